// The grid backend's kernels, neon build: compiled with this ISA's flags, chosen at run time.
#include "simd/wide_neon.h"
#define BPX_GRID_COLUMN bpx__grid_column_neon
#define BPX_GRID_BIG bpx__grid_big_neon
#define BPX_GRID_KEYS bpx__grid_keys_neon
#include "grid_kernel.h"
