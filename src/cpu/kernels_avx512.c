// The comparator kernels, avx512 build: compiled with this ISA's flags, chosen at run time.
#include "simd/wide_avx512.h"
#define BPX_BRUTE_ROWS bpx__brute_rows_avx512
#include "brute_kernel.h"
#define BPX_PRUNE_ROWS bpx__prune_rows_avx512
#include "prune_kernel.h"
#define BPX_SCAN_DIFFERS bpx__scan_differs_avx512
#include "scan_kernel.h"
