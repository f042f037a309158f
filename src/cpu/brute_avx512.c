// Brute-force comparator, avx512 build (compiled with its own ISA flags; chosen at run time).
#include "simd/wide_avx512.h"
#define BPX_BRUTE_ROWS bpx__brute_rows_avx512
#include "brute_kernel.h"
