// The grid backend's kernels, avx512 build: compiled with this ISA's flags, chosen at run time.
#include "simd/wide_avx512.h"
#define BPX_GRID_COLUMN bpx__grid_column_avx512
#define BPX_GRID_BIG bpx__grid_big_avx512
#define BPX_GRID_KEYS bpx__grid_keys_avx512
#include "grid_kernel.h"
