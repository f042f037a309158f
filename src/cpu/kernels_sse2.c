// The comparator kernels, sse2 build: compiled with this ISA's flags, chosen at run time.
#include "simd/wide_sse2.h"
#define BPX_BRUTE_ROWS bpx__brute_rows_sse2
#include "brute_kernel.h"
#define BPX_PRUNE_ROWS bpx__prune_rows_sse2
#include "prune_kernel.h"
#define BPX_SCAN_DIFFERS bpx__scan_differs_sse2
#include "scan_kernel.h"
