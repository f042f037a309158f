// The comparator kernels, scalar build: compiled with this ISA's flags, chosen at run time.
#include "simd/wide_scalar.h"
#define BPX_BRUTE_ROWS bpx__brute_rows_scalar
#include "brute_kernel.h"
#define BPX_PRUNE_ROWS bpx__prune_rows_scalar
#include "prune_kernel.h"
#define BPX_SCAN_DIFFERS bpx__scan_differs_scalar
#include "scan_kernel.h"
