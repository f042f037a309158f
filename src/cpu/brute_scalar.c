// Brute-force comparator, scalar build (compiled with its own ISA flags; chosen at run time).
#include "simd/wide_scalar.h"
#define BPX_BRUTE_ROWS bpx__brute_rows_scalar
#include "brute_kernel.h"
