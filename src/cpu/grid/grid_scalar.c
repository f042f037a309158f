// The grid backend's kernels, scalar build: compiled with this ISA's flags, chosen at run time.
#include "simd/wide_scalar.h"
#define BPX_GRID_COLUMN bpx__grid_column_scalar
#define BPX_GRID_BIG bpx__grid_big_scalar
#define BPX_GRID_KEYS bpx__grid_keys_scalar
#include "grid_kernel.h"
