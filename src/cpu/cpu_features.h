// What the running CPU (and OS) can execute, detected once, and the choice made from it: which
// instruction set's build of each comparator kernel runs (the kernels are compiled once per
// instruction set, kernels_<isa>.c). The public bpx_simd_* calls (bpx.h) answer from here too.
// Like zlib-ng's cpu_features.c + functable.c: the backends and the world ask; nothing here
// knows of them.
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "bpx/types.h"

/// Whether the CPU and OS support the instruction set (not whether the build has it).
bool bpx__cpu_supports(bpx_simd simd);
/// Whether this build has the kernels of the instruction set (AUTO: no).
bool bpx__simd_compiled(bpx_simd simd);

// The kernels read the cycle's box layouts and write the sink's blocks (core/backend.h). They are
// named by their tags here, so choosing a kernel needs nothing of the world.
struct bpx_soa;
struct bpx_sorted;
struct bpx_block;

/// Rows [row_begin, row_end) of the triangle i < j (brute_kernel.h), hits in (i, j) order.
typedef void bpx_brute_rows_fn(const struct bpx_soa *s, uint32_t row_begin, uint32_t row_end,
                               struct bpx_block *out);
/// Sorted positions [row_begin, row_end) swept forward (prune_kernel.h), hits unordered.
typedef void bpx_prune_rows_fn(const struct bpx_sorted *s, uint32_t row_begin, uint32_t row_end,
                               struct bpx_block *out);
/// Positions [k0, k1) of s whose box overlaps exactly one of boxes a and b (min then max per
/// slot, in s's slot order), ascending into out; returns the count (scan_kernel.h, sap's mend).
typedef uint32_t bpx_scan_differs_fn(const struct bpx_sorted *s, uint32_t k0, uint32_t k1,
                                     const float a[6], const float b[6], uint32_t *out);

/// The kernels for a supported width (AUTO: the widest); the scalar ones otherwise.
bpx_brute_rows_fn *bpx__brute_rows_for(bpx_simd simd);
bpx_prune_rows_fn *bpx__prune_rows_for(bpx_simd simd);
bpx_scan_differs_fn *bpx__scan_differs_for(bpx_simd simd);
