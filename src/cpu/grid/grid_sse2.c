// The grid backend's kernels, sse2 build: compiled with this ISA's flags, chosen at run time.
#include "simd/wide_sse2.h"
#define BPX_GRID_COLUMN bpx__grid_column_sse2
#define BPX_GRID_BIG bpx__grid_big_sse2
#define BPX_GRID_KEYS bpx__grid_keys_sse2
#include "grid_kernel.h"
