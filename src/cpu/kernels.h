// The comparator kernels, compiled once per instruction set (kernels_<isa>.c) and picked at run
// time by SIMD width (brute.c holds the table).
#pragma once

#include "core/world.h"

/// Rows [row_begin, row_end) of the triangle i < j (brute_kernel.h), hits in (i, j) order.
typedef void bpx_brute_rows_fn(const bpx_soa *s, uint32_t row_begin, uint32_t row_end,
                               bpx_block *out);
/// Sorted positions [row_begin, row_end) swept forward (prune_kernel.h), hits unordered.
typedef void bpx_prune_rows_fn(const bpx_sorted *s, uint32_t row_begin, uint32_t row_end,
                               bpx_block *out);

/// Positions [k0, k1) of s whose box overlaps exactly one of boxes a and b (min then max per
/// slot, in s's slot order), ascending into out; returns the count (scan_kernel.h, sap's mend).
typedef uint32_t bpx_scan_differs_fn(const bpx_sorted *s, uint32_t k0, uint32_t k1,
                                     const float a[6], const float b[6], uint32_t *out);

/// The kernels for a supported width (AUTO: the widest); the scalar ones otherwise.
bpx_brute_rows_fn *bpx__brute_rows_for(bpx_simd simd);
bpx_prune_rows_fn *bpx__prune_rows_for(bpx_simd simd);
bpx_scan_differs_fn *bpx__scan_differs_for(bpx_simd simd);

/// Sweeps the world's first `blocks` blocks (their row ranges of `sorted`) on its workers with the
/// prune kernel of its SIMD width; hits land in each block (prune.c; sap's rebuild uses it too).
void bpx__prune_sweep_blocks(bpx_world *w, const bpx_sorted *sorted, int blocks);

/// A sweep along one axis tests about this many candidates per box at most before the grid's
/// cells are cheaper: the grid on 2 threads is ahead from n = 20k boxes at constant density,
/// where a sweep meets n^(2/3) / 2 = 368 boxes per box (`bpx bench --backend prune,grid --sizes
/// 10000,20000,50000 --scene uniform --threads 2`). auto and sap's rebuild use it.
#define BPX_SWEEP_MAX_CANDIDATES 350.0

/// The grid's pairs of `boxes` (boxes.n must be the world's n; any boxes of that count, e.g. sap's
/// fat ones, padded to a multiple of BPX_PAD_LANES with inert boxes) into block 0, in (i, j)
/// order, on the world's workers (grid/grid.c). *state is the grid's own, made on first use and
/// kept between calls, freed after a call that fails (OUT_OF_MEMORY, TOO_MANY_PAIRS);
/// bpx__grid_free releases it.
bpx_status bpx__grid_find(bpx_world *w, void **state, bpx_soa boxes);
void bpx__grid_free(void **state);
/// Makes the grid's next call pick its cells from those boxes alone, not from its last call's
/// bounds (state may be NULL).
void bpx__grid_forget(void *state);

/// What sap's cycles did that their pairs do not show, since its state was made (zeros for a
/// world of another backend): endpoint lists sorted (see sap/lists.c), and warm cycles
/// that gave up without trying to mend. For the tests.
typedef struct bpx_sap_counters {
    uint32_t lists_made, untried;
} bpx_sap_counters;
bpx_sap_counters bpx__sap_counters(const bpx_world *w);
