// Brute-force comparator, avx2 build (compiled with its own ISA flags; chosen at run time).
#include "simd/wide_avx2.h"
#define BPX_BRUTE_ROWS bpx__brute_rows_avx2
#include "brute_kernel.h"
