// The grid backend's state between cycles and what its passes share (grid.c runs the cycle;
// keys.c, scatter.c, sweep.c and emit.c are its passes).

#pragma once

#include <math.h>
#include <string.h>

#include "core/alloc.h"
#include "core/backend.h"
#include "cpu/backends.h"
#include "cpu/sort.h"
#include "grid.h"

enum {
    SAMPLE = 1023,            // boxes sampled for sizes (and first-cycle bounds)
    GRID_SWEEP_BOXES = 8,     // boxes one sweep should meet at the scene's density
    GRID_CELL_SIZES = 3,      // cell side / box size
    GRID_BOXES_PER_COLUMN = 16,
    CHUNKS_MAX = 64,          // box ranges of the key and scatter passes
    ITEM_ENTRIES = 4096,      // positions per test item (at least)
    ITEMS_MAX = 512,
    KEY_BLOCK = 1024,         // boxes keyed in vectors, then counted, while in cache
    BIG_SPAN = 1 << 14,       // ids per big-box work item (all big boxes against them)
    BIG_STEP = 2048,          // ids in cache at a time while every big box passes over them
    EMIT_SHIFT = 11,          // at most 2^11 ids per bucket of pairs, 11-bit sort digits
    EMIT_BUCKET_PAIRS = 8192, // pairs per bucket wanted (the in-cache sort)
    EMIT_GROUPS = 64,
    EMIT_ITEMS = 256,
    PAD = BPX_PAD_LANES,
    LEVELS = BPX_GRID_LEVELS,
    WORKERS_MAX = 256, // bpx_world_def.worker_count's range
};

// A box on its way to its column.
typedef struct bpx_grid_entry {
    float lo[3], hi[3];
    uint32_t id;
    uint32_t fx; // fine x cell of min x | flags << 24
} bpx_grid_entry;

typedef struct bpx_grid_params {
    float origin[3], inv[3];
    uint32_t top[3]; // largest cell coordinate per axis (on x, of the fine cells)
    int fine_bits;   // x is cut 2^fine_bits times finer than the cells, for the column sort
    uint32_t columns;
} bpx_grid_params;

// Sorted runs in SoA form, with the sort's scratch; `capacity` positions (padding included).
typedef struct bpx_grid_soa {
    float *lo[3], *hi[3];
    uint32_t *id, *cx, *keys, *ids, *scratch_keys, *scratch_ids;
    uint8_t *flags;
    size_t capacity;
} bpx_grid_soa;

typedef struct bpx_grid_chunk {
    uint32_t begin, end;
    uint32_t level_count[LEVELS];
    float lo_min[3], lo_max[3];
    float max_extent;
} bpx_grid_chunk;

typedef struct bpx_grid_state {
    // Last cycle's exact figures, for this cycle's parameters.
    bool have_stats;
    float bounds_lo[3], bounds_hi[3];
    float max_extent;

    bpx_grid_params params;
    bpx_grid_layout layout;
    bpx_grid_chunk chunks[CHUNKS_MAX];
    int chunk_count;

    uint32_t *key; // per box id (padded to a whole group for the big kernel)
    size_t key_capacity;
    uint32_t *hist; // chunk x column: counts, then write offsets
    size_t hist_capacity;
    uint32_t *column_start;
    size_t column_capacity;
    // Entries: positions below `split` in the memory the world lends for the cycle (its spare
    // boxes, dead until the next update: bpx_cycle.scratch), the rest in the grid's own array,
    // `skew` places on (entry_at). Dead after the tests: the emitter's scratch then.
    bpx_grid_entry *entries;
    size_t entry_capacity;
    uintptr_t lent_base, own_base;
    uint32_t split, skew;
    size_t lent_bytes;
    // Scatter's write-combining, per worker: a column's entry waiting for the other half of its
    // cache line, and the position it goes to.
    bpx_grid_entry *stash;
    size_t stash_capacity;
    uint32_t wcolumns; // columns of the windowed levels
    uint32_t *stash_at;
    size_t stash_at_capacity;
    // Positions of the coarser levels' runs (level 0's are sorted in the workers' scratch).
    bpx_grid_soa positions;
    bpx_grid_soa scratch[WORKERS_MAX];
    int scratch_count;
    uint32_t *big_ids;
    size_t big_capacity;
    uint32_t item_column[ITEMS_MAX + 1];
    int item_count, big_items;
    uint32_t big_parts; // work items of the big boxes, BIG_SPAN ids each

    // Emitter: its scratch when the dead entries cannot hold the pairs.
    bpx_pair_list a;
    uint32_t *emit_hist; // groups x buckets
    size_t emit_hist_capacity;
    uint32_t *bucket_start;
    size_t bucket_capacity;
    size_t *block_hits; // last cycle's hits per block
    size_t block_hits_capacity;

    // A profiled cycle (bpx_cycle.profile): per worker, the time its test tasks took and the
    // part of it spent sorting level 0's columns (a line each: the workers write their own).
    struct {
        uint64_t busy_ns, sort_ns;
        uint64_t unused[6];
    } worker_time[WORKERS_MAX];
} bpx_grid_state;

// Position `at`'s entry (bpx_grid_state.entries). The own array is shifted by `skew` so that a
// position keeps its parity in both: the scatter writes two entries of a 64-byte line together.
static inline bpx_grid_entry *entry_at(const bpx_grid_state *st, uint32_t at)
{
    uintptr_t base = at < st->split ? st->lent_base : st->own_base; // a select, not a branch
    return (bpx_grid_entry *)(base + (uintptr_t)at * sizeof(bpx_grid_entry));
}

typedef struct bpx_grid_job {
    const bpx_cycle *cycle;
    bpx_grid_state *st;
    bpx_soa soa;
    bpx_grid_column_fn *column;
    bpx_grid_big_fn *big;
    bpx_grid_keys_fn *keys;
    bool profile; // time the test tasks' sorts apart (worker_time)
} bpx_grid_job;

// Makes *array hold at least `need` elements of `size` bytes (contents not kept), with need /
// `slack` more, so that it settles after a few cycles; with `shrink`, also made again when it
// holds over half as much again as needed. Never zero-sized, so NULL means no memory.
static inline bool reserve_slack(void **array, size_t *capacity, size_t need, size_t size,
                                 size_t slack, bool shrink)
{
    if (need <= *capacity && *array && (!shrink || *capacity <= need + need / 2 + 64))
        return true;
    bpx__free(*array, *capacity * size);
    *capacity = need + need / slack + 64;
    *array = bpx__alloc(*capacity * size);
    if (!*array)
        *capacity = 0;
    return *array != NULL;
}

// Grows by half again: for the small arrays (per column, per chunk, per bucket).
static inline bool reserve_array(void **array, size_t *capacity, size_t need, size_t size)
{
    return reserve_slack(array, capacity, need, size, 2, false);
}

// A sixteenth more: for the arrays of an entry per position or a key per box, most of the
// grid's memory. Their need moves by a fraction of a percent between cycles of one scene, and
// half again was a third of the peak (10M boxes: 72 of 162 bytes a box). Shrunk when the need
// fell by a third (the own entries, once the world lends memory for half of them).
static inline bool reserve_tight(void **array, size_t *capacity, size_t need, size_t size)
{
    return reserve_slack(array, capacity, need, size, 16, true);
}

// Sentinels after a run: never in reach (min x +inf), never overlapping.
static inline void pad_soa(bpx_grid_soa *r, size_t at)
{
    for (size_t k = at; k < at + PAD; k++) {
        for (int a = 0; a < 3; a++) {
            r->lo[a][k] = INFINITY;
            r->hi[a][k] = -INFINITY;
        }
        r->id[k] = 0;
        r->cx[k] = UINT32_MAX;
        r->flags[k] = 0;
    }
}

// The cell of coordinate v on one axis: monotone in v (rounding is), clamped to [0, top].
static inline uint32_t cell_of(float v, float origin, float inv, uint32_t top)
{
    return bpx__grid_cell(v, origin, inv, (float)top); // exact: top < 2^24
}

// ---------------------------------------------------------------------------------------------
// Across the files of this folder

// keys.c: 1. parameters, 2. keys.
void bpx__grid_choose_params(const bpx_soa *s, bpx_grid_state *st, bpx_grid_params *p);
void bpx__grid_set_levels(bpx_grid_state *st);
void bpx__grid_key_task(int begin, int end, int worker, void *context);
// scatter.c: 4. scatter.
void bpx__grid_scatter_task(int begin, int end, int worker, void *context);
// sweep.c: 5. per-column sorts, 6. tests.
void bpx__grid_sort_task(int begin, int end, int worker, void *context);
void bpx__grid_test_task(int begin, int end, int worker, void *context);
// emit.c: 7. hits to (i, j) order.
bpx_status bpx__grid_emit_sorted(const bpx_cycle *cycle, bpx_grid_state *st, uint32_t n);
