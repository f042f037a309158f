// The comparator kernels, neon build: compiled with this ISA's flags, chosen at run time.
#include "simd/wide_neon.h"
#define BPX_BRUTE_ROWS bpx__brute_rows_neon
#include "brute_kernel.h"
#define BPX_PRUNE_ROWS bpx__prune_rows_neon
#include "prune_kernel.h"
#define BPX_SCAN_DIFFERS bpx__scan_differs_neon
#include "scan_kernel.h"
