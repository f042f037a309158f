// The comparator kernels, avx2 build: compiled with this ISA's flags, chosen at run time.
#include "simd/wide_avx2.h"
#define BPX_BRUTE_ROWS bpx__brute_rows_avx2
#include "brute_kernel.h"
#define BPX_PRUNE_ROWS bpx__prune_rows_avx2
#include "prune_kernel.h"
#define BPX_SCAN_DIFFERS bpx__scan_differs_avx2
#include "scan_kernel.h"
