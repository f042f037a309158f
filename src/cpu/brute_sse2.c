// Brute-force comparator, sse2 build (compiled with its own ISA flags; chosen at run time).
#include "simd/wide_sse2.h"
#define BPX_BRUTE_ROWS bpx__brute_rows_sse2
#include "brute_kernel.h"
