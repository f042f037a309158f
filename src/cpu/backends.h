// What the CPU backends lend one another: prune's sweep (sap's rebuild), the grid as a pair
// finder (sap's rebuild on dense scenes), the sweep's limit (auto, sap) and sap's counters
// (for the tests). The kernels themselves, and the choice of one per SIMD width, are in
// cpu_features.h.
#pragma once

#include "core/backend.h"

/// Boxes sorted by min x, in SoA form, with the original index of each; padded after n with
/// boxes whose min x is +inf, so a sweep stops there without a bounds check.
typedef struct bpx_sorted {
    const float *lo[3];
    const float *hi[3];
    const uint32_t *id;
    uint32_t n;
} bpx_sorted;

/// Sweeps the sink's first `blocks` blocks (their row ranges of `sorted`) on the cycle's workers
/// with the prune kernel of its SIMD width; hits land in each block (prune.c; sap's rebuild uses
/// it too).
void bpx__prune_sweep_blocks(const bpx_cycle *c, const bpx_sorted *sorted, int blocks);

/// A sweep along one axis tests about this many candidates per box at most before the grid's
/// cells are cheaper: the grid on 2 threads is ahead from n = 20k boxes at constant density,
/// where a sweep meets n^(2/3) / 2 = 368 boxes per box (`bpx bench --backend prune,grid --sizes
/// 10000,20000,50000 --scene uniform --threads 2`). auto and sap's rebuild use it.
#define BPX_SWEEP_MAX_CANDIDATES 350.0

/// The grid's pairs of `boxes` (boxes.n must be the cycle's n; any boxes of that count, e.g. sap's
/// fat ones, padded to a multiple of BPX_PAD_LANES with inert boxes) into block 0, in (i, j)
/// order, on the cycle's workers (grid/grid.c). *state is the grid's own, made on first use and
/// kept between calls, freed after a call that fails (OUT_OF_MEMORY, TOO_MANY_PAIRS);
/// bpx__grid_free releases it.
bpx_status bpx__grid_find(const bpx_cycle *c, void **state, bpx_soa boxes);
void bpx__grid_free(void **state);
/// Makes the grid's next call pick its cells from those boxes alone, not from its last call's
/// bounds (state may be NULL).
void bpx__grid_forget(void *state);

/// What sap's cycles did that their pairs do not show, since its state was made (zeros for a
/// world of another backend): endpoint lists sorted (see sap/lists.c), warm cycles that gave up
/// without trying to mend, and the fat margins of the last rebuild. For the tests.
typedef struct bpx_sap_counters {
    uint32_t lists_made, untried;
    float margin[3];
} bpx_sap_counters;
bpx_sap_counters bpx__sap_counters(const bpx_world *w);
