// The grid backend's kernels, avx2 build: compiled with this ISA's flags, chosen at run time.
#include "simd/wide_avx2.h"
#define BPX_GRID_COLUMN bpx__grid_column_avx2
#define BPX_GRID_BIG bpx__grid_big_avx2
#define BPX_GRID_KEYS bpx__grid_keys_avx2
#include "grid_kernel.h"
