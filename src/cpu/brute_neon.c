// Brute-force comparator, neon build (compiled with its own ISA flags; chosen at run time).
#include "simd/wide_neon.h"
#define BPX_BRUTE_ROWS bpx__brute_rows_neon
#include "brute_kernel.h"
