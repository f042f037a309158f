// The grid backend: a hierarchical grid of columns in (y, z), each a run sorted along x, for
// millions of boxes; the few biggest boxes apart. Linear in n at constant density. Paper
// modules: the comparator, past the paper; the emitter's ordering (emit.c).
//
// Why: at constant density the candidates of one sweep over the whole scene grow like n^(5/3)
// (a box meets the whole slab of boxes whose x intervals meet its own). Columns no wider than a
// box leave each box a handful of short, sorted, contiguous runs to test (SIMD, no hashing).
//
// Each cycle, every pass but the small serial ones split over the workers:
//  1. Parameters (serial, from a sample and last cycle's exact bounds): the level-0 cell side s
//     is the largest box size that keeps about GRID_WINDOW_BOXES boxes per window at the scene's
//     density (all boxes when sizes are even; the bulk when they are heavy-tailed), and no more
//     columns than about one per GRID_BOXES_PER_COLUMN boxes.
//  2. Keys: each box's cells (q = floor((v - origin) / s), clamped: monotone in v, which is all
//     the tests' reasoning needs, so any float input is safe), its level (the first at which it
//     spans at most 2 cells per axis; level l has cells 4^l s), the 1 to 4 columns ((y, z)
//     cells at that level) it covers, 16 boxes at a time in vectors (grid_kernel.h); per-chunk
//     histograms of columns.
//  3. Levels: the top levels holding few boxes become "big" boxes, tested against all (the
//     rest never look for them); the others get columns: a prefix of the histograms.
//  4. Scatter: each box (coordinates, id, x cell, flags) to its columns, 32 bytes an entry;
//     two entries of a column that share a cache line go out together as one streamed line
//     (the second waits in a small per-worker stash), so no line is read before it is written.
//     The first columns' entries go to the world's spare boxes, lent for the cycle
//     (bpx_cycle.scratch: 24 bytes a box, half the entries), the rest to the grid's own array.
//  5. Per column: a counting sort on the x cell, mended by insertion sort on min x (radix when
//     that gives up), written out as SoA runs.
//  6. Tests (grid_kernel.h): each box against the rest of its run, and from its home column
//     against windows of the columns it covers at each coarser level; big boxes against all.
//     A pair met in several columns is kept in one (a rule on the flags), so no dedupe pass.
//  7. Hits to (i, j) order: a scatter by i / 2048 into buckets (in the entries, dead by then),
//     then in cache each bucket by i (a counting pass) and each i's few pairs by j, straight
//     into block 0's list. Every test is the exact float comparison of overlap.h; the grid only
//     decides which pairs are tested, and the order is a full sort, so the bytes are the same
//     for any worker count or schedule.

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cpu/cpu_features.h"
#include "grid_internal.h"

// ---------------------------------------------------------------------------------------------
// Memory

static void free_soa(bpx_grid_soa *r)
{
    size_t cap = r->capacity;
    for (int a = 0; a < 3; a++) {
        bpx__free(r->lo[a], cap * sizeof(float));
        bpx__free(r->hi[a], cap * sizeof(float));
    }
    uint32_t *u32s[] = {r->id, r->cx, r->keys, r->ids, r->scratch_keys, r->scratch_ids};
    for (size_t k = 0; k < sizeof u32s / sizeof u32s[0]; k++)
        bpx__free(u32s[k], cap * sizeof(uint32_t));
    bpx__free(r->flags, cap);
    *r = (bpx_grid_soa){0};
}

static bool reserve_soa(bpx_grid_soa *r, size_t need)
{
    if (need <= r->capacity && r->id)
        return true;
    free_soa(r);
    size_t cap = need + need / 2 + 64;
    bool ok = true;
    for (int a = 0; a < 3; a++) {
        ok &= (r->lo[a] = bpx__alloc(cap * sizeof(float))) != NULL;
        ok &= (r->hi[a] = bpx__alloc(cap * sizeof(float))) != NULL;
    }
    uint32_t **u32s[] = {&r->id, &r->cx, &r->keys, &r->ids, &r->scratch_keys, &r->scratch_ids};
    for (size_t k = 0; k < sizeof u32s / sizeof u32s[0]; k++)
        ok &= (*u32s[k] = bpx__alloc(cap * sizeof(uint32_t))) != NULL;
    ok &= (r->flags = bpx__alloc(cap)) != NULL;
    r->capacity = cap;
    if (!ok)
        free_soa(r);
    return ok;
}

void bpx__grid_free(void **state)
{
    bpx_grid_state *st = *state;
    if (!st)
        return;
    free_soa(&st->positions);
    for (int k = 0; k < WORKERS_MAX; k++)
        free_soa(&st->scratch[k]);
    bpx__free(st->key, st->key_capacity * sizeof(uint32_t));
    bpx__free(st->hist, st->hist_capacity * sizeof(uint32_t));
    bpx__free(st->column_start, st->column_capacity * sizeof(uint32_t));
    bpx__free(st->entries, st->entry_capacity * sizeof(bpx_grid_entry));
    bpx__free(st->stash, st->stash_capacity * sizeof(bpx_grid_entry));
    bpx__free(st->stash_at, st->stash_at_capacity * sizeof(uint32_t));
    bpx__free(st->big_ids, st->big_capacity * sizeof(uint32_t));
    bpx__free(st->a.pairs, st->a.capacity * sizeof(bpx_pair));
    bpx__free(st->emit_hist, st->emit_hist_capacity * sizeof(uint32_t));
    bpx__free(st->bucket_start, st->bucket_capacity * sizeof(uint32_t));
    bpx__free(st->block_hits, st->block_hits_capacity * sizeof(size_t));
    bpx__free(st, sizeof *st);
    *state = NULL;
}

void bpx__grid_forget(void *state)
{
    if (state)
        ((bpx_grid_state *)state)->have_stats = false;
}

static void grid_destroy(void *state)
{
    bpx__grid_free(&state);
}

// ---------------------------------------------------------------------------------------------
// Kernels per instruction set (grid_<isa>.c), chosen at run time like brute's.

#define GRID_DECLARE(isa)                                                                          \
    bpx_grid_column_fn bpx__grid_column_##isa;                                                     \
    bpx_grid_big_fn bpx__grid_big_##isa;                                                           \
    bpx_grid_keys_fn bpx__grid_keys_##isa;
GRID_DECLARE(scalar)
#if BPX_HAVE_SSE2
GRID_DECLARE(sse2)
#endif
#if BPX_HAVE_AVX2
GRID_DECLARE(avx2)
#endif
#if BPX_HAVE_AVX512
GRID_DECLARE(avx512)
#endif
#if BPX_HAVE_NEON
GRID_DECLARE(neon)
#endif

typedef struct grid_kernels {
    bpx_grid_column_fn *column;
    bpx_grid_big_fn *big;
    bpx_grid_keys_fn *keys;
} grid_kernels;

static grid_kernels kernels_for(bpx_simd simd)
{
    if (simd == BPX_SIMD_AUTO)
        simd = bpx_simd_best();
    if (!bpx_simd_supported(simd))
        simd = BPX_SIMD_SCALAR;
    switch (simd) {
#if BPX_HAVE_SSE2
    case BPX_SIMD_SSE2:
        return (grid_kernels){bpx__grid_column_sse2, bpx__grid_big_sse2, bpx__grid_keys_sse2};
#endif
#if BPX_HAVE_AVX2
    case BPX_SIMD_AVX2:
        return (grid_kernels){bpx__grid_column_avx2, bpx__grid_big_avx2, bpx__grid_keys_avx2};
#endif
#if BPX_HAVE_AVX512
    case BPX_SIMD_AVX512:
        return (grid_kernels){bpx__grid_column_avx512, bpx__grid_big_avx512, bpx__grid_keys_avx512};
#endif
#if BPX_HAVE_NEON
    case BPX_SIMD_NEON:
        return (grid_kernels){bpx__grid_column_neon, bpx__grid_big_neon, bpx__grid_keys_neon};
#endif
    default:
        return (grid_kernels){bpx__grid_column_scalar, bpx__grid_big_scalar, bpx__grid_keys_scalar};
    }
}

// ---------------------------------------------------------------------------------------------
// The cycle

// Work items: column ranges of about equal positions (empty columns count a little).
static void plan_items(bpx_grid_state *st, uint32_t columns, uint32_t positions)
{
    uint64_t cost_total = (uint64_t)positions + columns / 8;
    uint64_t target = cost_total / ITEMS_MAX + 1;
    if (target < ITEM_ENTRIES)
        target = ITEM_ENTRIES;
    int items = 0;
    uint64_t cost = 0;
    st->item_column[0] = 0;
    for (uint32_t c = 0; c < columns; c++) {
        cost += (st->column_start[c + 1] - st->column_start[c]) + ((c & 7) == 0);
        if (cost >= target && items + 1 < ITEMS_MAX) {
            st->item_column[++items] = c + 1;
            cost = 0;
        }
    }
    if (st->item_column[items] != columns || items == 0)
        st->item_column[++items] = columns;
    st->item_count = items;
}

static bpx_status find(const bpx_cycle *cycle, void **state, bpx_soa boxes)
{
    bpx_grid_state *st = *state;
    if (!st) {
        if (!(st = bpx__alloc(sizeof *st)))
            return BPX_ERR_OUT_OF_MEMORY;
        *st = (bpx_grid_state){0};
        *state = st;
    }
    uint32_t n = boxes.n;
    grid_kernels kernels = kernels_for(cycle->simd);
    bpx_profile *prof = cycle->profile;
    bpx_grid_job job = {cycle, st, boxes, kernels.column, kernels.big, kernels.keys, prof != NULL};
    uint64_t t = bpx__profile_clock(prof);

    // 1. Parameters, levels, chunks.
    bpx__grid_choose_params(&job.soa, st, &st->params);
    bpx__grid_set_levels(st);
    uint32_t columns = st->params.columns;
    int workers = cycle->executor->worker_count > 1 ? cycle->executor->worker_count : 1;
    int chunks = 2 * workers;
    chunks = chunks < CHUNKS_MAX ? chunks : CHUNKS_MAX;
    if ((uint32_t)chunks > n / 4096 + 1)
        chunks = (int)(n / 4096 + 1);
    st->chunk_count = chunks;
    for (int c = 0; c < chunks; c++) {
        st->chunks[c].begin = (uint32_t)((uint64_t)n * c / chunks);
        st->chunks[c].end = (uint32_t)((uint64_t)n * (c + 1) / chunks);
    }
    size_t padded = ((size_t)n + PAD - 1) / PAD * PAD + PAD;
    if (!reserve_tight((void **)&st->key, &st->key_capacity, padded, sizeof(uint32_t)) ||
        !reserve_array((void **)&st->hist, &st->hist_capacity, (size_t)chunks * columns,
                       sizeof(uint32_t)))
        return BPX_ERR_OUT_OF_MEMORY;

    uint64_t n64 = n, sampled = n < SAMPLE ? n : SAMPLE;
    bpx__profile_add(prof, "grid", "params", &t, BPX_ACCESS_SEQUENTIAL, 24 * sampled, 0, 0);

    // 2. Keys.
    bpx__parallel_for(cycle->executor, bpx__grid_key_task, chunks, &job);
    // Read: the six coordinate arrays; written: a key per box, the chunks' histograms.
    bpx__profile_add(prof, "grid", "keys", &t, BPX_ACCESS_SEQUENTIAL, 24 * n64,
                     4 * n64 + 4 * (uint64_t)chunks * columns, 0);

    // 3. Levels: big from the top while few boxes; the rest in columns.
    uint32_t level_count[LEVELS] = {0};
    float lo_min[3] = {INFINITY, INFINITY, INFINITY}, lo_max[3] = {-INFINITY, -INFINITY, -INFINITY};
    float largest = 0.0f;
    for (int c = 0; c < chunks; c++) {
        const bpx_grid_chunk *ch = &st->chunks[c];
        for (int l = 0; l < LEVELS; l++)
            level_count[l] += ch->level_count[l];
        for (int a = 0; a < 3; a++) {
            lo_min[a] = fminf(lo_min[a], ch->lo_min[a]);
            lo_max[a] = fmaxf(lo_max[a], ch->lo_max[a]);
        }
        largest = fmaxf(largest, ch->max_extent);
    }
    st->have_stats = lo_min[0] <= lo_max[0];
    for (int a = 0; a < 3; a++) {
        st->bounds_lo[a] = lo_min[a];
        st->bounds_hi[a] = lo_max[a];
    }
    st->max_extent = largest;
    uint32_t big_limit = n / 16384 > 16 ? n / 16384 : 16, big = 0;
    int windowed = LEVELS;
    while (windowed > 0 && big + level_count[windowed - 1] <= big_limit)
        big += level_count[--windowed];
    bpx_grid_layout *g = &st->layout;
    g->windowed = windowed;
    for (int l = 0; l < LEVELS; l++)
        g->level[l].count = level_count[l];
    uint32_t wcolumns = windowed < LEVELS ? g->level[windowed].first_column : columns;
    if (!reserve_array((void **)&st->column_start, &st->column_capacity, (size_t)wcolumns + 1,
                       sizeof(uint32_t)) ||
        !reserve_array((void **)&st->big_ids, &st->big_capacity, big, sizeof(uint32_t)))
        return BPX_ERR_OUT_OF_MEMORY;
    size_t at = 0;
    uint32_t level1 = windowed > 1 ? g->level[1].first_column : wcolumns, longest = 0;
    for (uint32_t c = 0; c < wcolumns; c++) {
        st->column_start[c] = (uint32_t)at;
        for (int ch = 0; ch < chunks; ch++) {
            uint32_t *slot = &st->hist[(size_t)ch * columns + c];
            uint32_t count = *slot;
            *slot = (uint32_t)at;
            at += count;
        }
        if (at > UINT32_MAX - 2 * PAD)
            return BPX_ERR_OUT_OF_MEMORY; // positions are 32-bit
        if (c < level1 && at - st->column_start[c] > longest)
            longest = (uint32_t)(at - st->column_start[c]);
    }
    st->column_start[wcolumns] = (uint32_t)at;
    uint32_t positions = (uint32_t)at;
    // Entries: the first columns in the memory the world lends (as many whole columns as fit),
    // the rest in the grid's own array.
    size_t lent = cycle->scratch ? cycle->scratch_bytes / sizeof(bpx_grid_entry) : 0;
    uint32_t split = 0;
    if (lent >= positions) {
        split = positions;
    } else if (lent) { // the last column start that fits
        uint32_t lo = 0, hi = wcolumns;
        while (lo < hi) {
            uint32_t mid = lo + (hi - lo + 1) / 2;
            if (st->column_start[mid] <= lent)
                lo = mid;
            else
                hi = mid - 1;
        }
        split = st->column_start[lo];
    }
    st->split = split;
    st->skew = split & 1;
    st->lent_bytes = split ? cycle->scratch_bytes : 0;
    // Coarser runs in shared positions (indexed like the entries; level 0's part untouched),
    // level 0's in each worker's scratch, one column at a time.
    bool coarse = positions > st->column_start[level1];
    if (!reserve_tight((void **)&st->entries, &st->entry_capacity,
                       (size_t)(positions - split) + st->skew, sizeof(bpx_grid_entry)) ||
        (coarse && !reserve_soa(&st->positions, (size_t)positions + PAD)))
        return BPX_ERR_OUT_OF_MEMORY;
    st->lent_base = split ? (uintptr_t)cycle->scratch : 0;
    // Wraps below the array for positions under split, which never take this base.
    st->own_base = (uintptr_t)st->entries - (uintptr_t)(split - st->skew) * sizeof(bpx_grid_entry);
    for (int k = 0; k < workers && k < WORKERS_MAX; k++)
        if (!reserve_soa(&st->scratch[k], (size_t)longest + PAD))
            return BPX_ERR_OUT_OF_MEMORY;
    st->wcolumns = wcolumns;
    if (!reserve_array((void **)&st->stash, &st->stash_capacity, (size_t)workers * wcolumns,
                       sizeof(bpx_grid_entry)) ||
        !reserve_array((void **)&st->stash_at, &st->stash_at_capacity, (size_t)workers * wcolumns,
                       sizeof(uint32_t)))
        return BPX_ERR_OUT_OF_MEMORY;
    if (big) {
        uint32_t k = 0;
        for (uint32_t i = 0; i < n; i++) {
            uint32_t key = st->key[i];
            if (key != BPX_GRID_INERT && bpx__grid_key_level(key) >= (uint32_t)windowed)
                st->big_ids[k++] = i;
        }
    }
    for (size_t k = n; k < padded; k++)
        st->key[k] = BPX_GRID_INERT;

    // Read and written: the histograms (a prefix over them), the column starts; the keys once
    // more when some boxes are big.
    bpx__profile_add(prof, "grid", "levels", &t, BPX_ACCESS_SEQUENTIAL,
                     4 * (uint64_t)chunks * columns + (big ? 4 * n64 : 0),
                     4 * (uint64_t)chunks * wcolumns + 4 * (uint64_t)wcolumns + 4 * (uint64_t)big,
                     0);

    // 4. Scatter; 5. sort the columns.
    bpx__parallel_for(cycle->executor, bpx__grid_scatter_task, chunks, &job);
    // Read in id order: keys and coordinates; written: a 32-byte entry per position, each to
    // its column's next place (the random access of the cycle).
    bpx__profile_add(prof, "grid", "scatter", &t, BPX_ACCESS_SCATTER, 28 * n64,
                     sizeof(bpx_grid_entry) * (uint64_t)positions, positions);
    plan_items(st, wcolumns, positions);
    if (coarse) {
        pad_soa(&st->positions, positions);
        bpx__parallel_for(cycle->executor, bpx__grid_sort_task, st->item_count, &job);
    }
    uint64_t coarse_ns = 0;
    if (prof) {
        uint64_t now = bpx__profile_now();
        coarse_ns = now - t;
        t = now;
        for (int k = 0; k < workers && k < WORKERS_MAX; k++)
            st->worker_time[k].busy_ns = st->worker_time[k].sort_ns = 0;
    }

    // 6. Tests (level 0's columns sorted on the way).
    const bpx_grid_soa *r = &st->positions;
    for (int a = 0; a < 3; a++) {
        g->lo[a] = r->lo[a];
        g->hi[a] = r->hi[a];
    }
    g->id = r->id;
    g->cx = r->cx;
    g->flags = r->flags;
    g->column_start = st->column_start;
    g->boxes = job.soa;
    g->big_ids = st->big_ids;
    g->big_count = big;
    g->key = st->key;
    st->big_parts = (uint32_t)((((size_t)n + PAD - 1) / PAD * PAD + BIG_SPAN - 1) / BIG_SPAN);
    st->big_items = big ? (int)st->big_parts : 0;
    int blocks = st->item_count + st->big_items;
    bpx_status status = bpx__emitter_own_blocks(cycle->sink, blocks);
    if (status != BPX_OK)
        return status;
    // Room for about last cycle's hits per block, so coherent cycles do not grow lists.
    if ((size_t)blocks > st->block_hits_capacity) {
        size_t old = st->block_hits_capacity, cap = (size_t)blocks + (size_t)blocks / 2;
        if (!bpx__grow((void **)&st->block_hits, old * sizeof(size_t), cap * sizeof(size_t)))
            return BPX_ERR_OUT_OF_MEMORY;
        memset(st->block_hits + old, 0, (cap - old) * sizeof(size_t));
        st->block_hits_capacity = cap;
    }
    for (int b = 0; b < blocks; b++) {
        size_t want = st->block_hits[b];
        if (!bpx__list_reserve(&cycle->sink->blocks[b].hits, want + want / 4 + 64))
            return BPX_ERR_OUT_OF_MEMORY;
    }
    bpx__parallel_for(cycle->executor, bpx__grid_test_task, blocks, &job);
    for (int b = 0; b < blocks; b++)
        st->block_hits[b] = cycle->sink->blocks[b].hits.count;
    if (prof) {
        // Level 0's columns are sorted inside the tests: the pass's time is split by the share
        // of the workers' time their sorts took. Sort: each entry read (32 bytes) and written
        // as a run (six floats, id, x cell, flags: 33 bytes). Tests: every run read once (more
        // for the windows of coarser levels, not counted), a pair written per hit; with big
        // boxes, the boxes read once more in id order.
        uint64_t now = bpx__profile_now(), pass = now - t, busy = 0, sorting = 0, hits = 0;
        t = now;
        for (int k = 0; k < workers && k < WORKERS_MAX; k++) {
            busy += st->worker_time[k].busy_ns;
            sorting += st->worker_time[k].sort_ns;
        }
        for (int b = 0; b < blocks; b++)
            hits += cycle->sink->blocks[b].hits.count;
        uint64_t sort_ns = busy ? (uint64_t)((double)pass * ((double)sorting / (double)busy)) : 0;
        sort_ns = sort_ns < pass ? sort_ns : pass;
        bpx__profile_add_ns(prof, "grid", "sort", coarse_ns + sort_ns, BPX_ACCESS_SEQUENTIAL,
                            32 * (uint64_t)positions, 33 * (uint64_t)positions, 0);
        bpx__profile_add_ns(prof, "grid", "tests", pass - sort_ns, BPX_ACCESS_SEQUENTIAL,
                            33 * (uint64_t)positions + (big ? 24 * n64 : 0), 8 * hits, 0);
    }

    // 7. Hits to (i, j) order.
    return bpx__grid_emit_sorted(cycle, st, n);
}

bpx_status bpx__grid_find(const bpx_cycle *cycle, void **state, bpx_soa boxes)
{
    bpx_status status = find(cycle, state, boxes);
    // The state is memory only (every cycle starts from the boxes): a cycle too big for memory,
    // or for 32-bit pair offsets, gives it all back, and the next one grows it again.
    if (status == BPX_ERR_OUT_OF_MEMORY || status == BPX_ERR_TOO_MANY_PAIRS)
        bpx__grid_free(state);
    return status;
}

static bpx_status grid_compare(void **state, bpx_cycle *cycle)
{
    return bpx__grid_find(cycle, state, cycle->boxes);
}

static bool grid_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    bpx_simd simd = def->simd == BPX_SIMD_AUTO ? bpx_simd_best() : def->simd;
    *reason = "";
    if (!bpx_simd_supported(simd)) {
        *reason = "SIMD width not supported here";
        return false;
    }
    snprintf(detail, size,
             "hierarchical columns in y, z swept along x, big boxes apart, %s, "
             "threads",
             bpx_simd_name(simd));
    return true;
}

const bpx_backend_impl bpx__grid_backend = {
    .id = BPX_BACKEND_GRID,
    .name = "grid",
    .query = grid_query,
    .compare = grid_compare,
    .destroy = grid_destroy,
};
