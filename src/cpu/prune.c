// The prune backend: single-axis sort and sweep ("box pruning", Terdiman), SIMD and threads.
// Paper modules: the comparator, past the paper (a sort instead of every pair); the emitter's
// ordering of out-of-order hits (bpx__emitter_sort_blocks).
//
// Each cycle: (1) order the boxes by min x — the order of the last cycle, mended by insertion
// sort, when the scene is coherent; a radix sort when it is not (first cycle, new n, or too many
// swaps); (2) gather the boxes into sorted SoA arrays; (3) sweep sorted positions in blocks on
// the workers (prune_kernel.h); (4) put the hits in (i, j) order with two stable counting sorts
// (by j, then by i) — O(n + pairs), the same bytes whatever the thread count.
#include <stdio.h>
#include <string.h>

#include "backends.h"
#include "core/alloc.h"
#include "core/backend.h"
#include "core/clock.h"
#include "cpu_features.h"
#include "sort.h"

enum {
    ROWS_PER_BLOCK = 1024, // sweep rows cost about the same; claims even out the rest
    PAD = BPX_PAD_LANES,   // sentinel boxes after n in the sorted arrays
};

typedef struct prune_state {
    uint32_t capacity; // boxes the arrays below hold (plus PAD)
    uint32_t *order;   // box ids by min x (persistent between cycles)
    uint32_t *keys;    // sortable min x of order[k]
    uint32_t *scratch_keys;
    uint32_t *scratch_ids;
    float *lo[3], *hi[3]; // sorted SoA
    uint32_t *ids;        // == order, padded
    uint32_t *counts;     // n + 1, for the counting sorts of pairs
    uint32_t ordered_n;   // n that `order` is valid for (UINT32_MAX: none)
    uint32_t padded_n;    // n whose sentinels the sorted arrays hold (UINT32_MAX: none)
    bpx_pair_list sorted; // the cycle's pairs, (i, j) order
    bpx_pair_list spare;  // counting-sort scratch
} prune_state;

static void free_arrays(prune_state *st)
{
    size_t words = (size_t)st->capacity + PAD;
    uint32_t **u32s[] = {&st->order, &st->keys, &st->scratch_keys, &st->scratch_ids, &st->ids,
                         &st->counts};
    for (size_t k = 0; k < sizeof u32s / sizeof u32s[0]; k++) {
        bpx__free(*u32s[k], words * sizeof(uint32_t));
        *u32s[k] = NULL;
    }
    for (int a = 0; a < 3; a++) {
        bpx__free(st->lo[a], words * sizeof(float));
        bpx__free(st->hi[a], words * sizeof(float));
        st->lo[a] = st->hi[a] = NULL;
    }
    st->capacity = 0;
}

static void prune_destroy(void *state)
{
    prune_state *st = state;
    free_arrays(st);
    bpx__free(st->sorted.pairs, st->sorted.capacity * sizeof(bpx_pair));
    bpx__free(st->spare.pairs, st->spare.capacity * sizeof(bpx_pair));
    bpx__free(st, sizeof *st);
}

static bool reserve_state(void **state, uint32_t n)
{
    prune_state *st = *state;
    if (!st) {
        if (!(st = bpx__alloc(sizeof *st)))
            return false;
        *st = (prune_state){.ordered_n = UINT32_MAX, .padded_n = UINT32_MAX};
        *state = st;
    }
    if (n <= st->capacity && st->order)
        return true;
    free_arrays(st);
    st->ordered_n = UINT32_MAX;
    st->padded_n = UINT32_MAX;
    size_t words = (size_t)n + PAD;
    st->capacity = n;
    uint32_t **u32s[] = {&st->order, &st->keys, &st->scratch_keys, &st->scratch_ids, &st->ids,
                         &st->counts};
    bool ok = true;
    for (size_t k = 0; k < sizeof u32s / sizeof u32s[0]; k++)
        ok &= (*u32s[k] = bpx__alloc(words * sizeof(uint32_t))) != NULL;
    for (int a = 0; a < 3; a++) {
        ok &= (st->lo[a] = bpx__alloc(words * sizeof(float))) != NULL;
        ok &= (st->hi[a] = bpx__alloc(words * sizeof(float))) != NULL;
    }
    if (!ok)
        free_arrays(st);
    return ok;
}

// Orders st->order by min x: mend last cycle's order when possible, else radix sort.
static void sort_by_min_x(const bpx_cycle *cycle, prune_state *st)
{
    uint32_t n = cycle->n;
    const float *lx = cycle->boxes.lo[0];
    bool coherent = st->ordered_n == n;
    if (!coherent)
        for (uint32_t k = 0; k < n; k++)
            st->order[k] = k;
    for (uint32_t k = 0; k < n; k++)
        st->keys[k] = bpx__float_key(lx[st->order[k]]);
    // Coherent motion moves few boxes past few others; give up when it gets expensive (keys
    // and ids move together, so a given-up pass still leaves valid input for the radix sort).
    if (coherent && bpx__insertion_sort(st->keys, st->order, n, 4 * (uint64_t)n + 1024))
        return;
    bpx__radix_sort(st->keys, st->order, st->scratch_keys, st->scratch_ids, n);
    st->ordered_n = n;
}

static void gather(const bpx_cycle *cycle, prune_state *st)
{
    uint32_t n = cycle->n;
    for (int a = 0; a < 3; a++) {
        const float *lo = cycle->boxes.lo[a], *hi = cycle->boxes.hi[a];
        float *slo = st->lo[a], *shi = st->hi[a];
        for (uint32_t k = 0; k < n; k++) {
            slo[k] = lo[st->order[k]];
            shi[k] = hi[st->order[k]];
        }
    }
    memcpy(st->ids, st->order, sizeof(uint32_t) * n);
    // The sentinels after n: nothing else writes there, so only when n changed (PAD of them in
    // six arrays, one at a time, every cycle: part of the 18% that prune_compare itself took at
    // n = 200 on Table 2's scenario, 10% after).
    if (st->padded_n != n) {
        for (int a = 0; a < 3; a++)
            for (uint32_t k = n; k < n + PAD; k++) {
                st->lo[a][k] = 1.0f / 0.0f;
                st->hi[a][k] = -1.0f / 0.0f;
            }
        memset(st->ids + n, 0, sizeof(uint32_t) * PAD);
        st->padded_n = n;
    }
}

typedef struct prune_job {
    const bpx_cycle *cycle;
    bpx_sorted sorted;
    bpx_prune_rows_fn *rows;
} prune_job;

static void prune_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    prune_job *job = context;
    for (int b = begin; b < end; b++) {
        bpx_block *block = &job->cycle->sink->blocks[b];
        block->hits.count = 0;
        block->tests = 0;
        block->status = BPX_OK;
        job->rows(&job->sorted, block->row_begin, block->row_end, block);
    }
}

void bpx__prune_sweep_blocks(const bpx_cycle *cycle, const bpx_sorted *sorted, int blocks)
{
    prune_job job = {cycle, *sorted, bpx__prune_rows_for(cycle->simd)};
    bpx__parallel_for(cycle->executor, prune_task, blocks, &job);
}

static bpx_status prune_compare(void **state, bpx_cycle *cycle)
{
    uint32_t n = cycle->n;
    if (!reserve_state(state, n))
        return BPX_ERR_OUT_OF_MEMORY;
    prune_state *st = *state;
    if (cycle->sink->planned_n != n) {
        bpx_status status = bpx__emitter_plan_rows(cycle->sink, n, ROWS_PER_BLOCK);
        if (status != BPX_OK)
            return status;
    }
    bpx_profile *prof = cycle->profile;
    uint64_t t = bpx__profile_clock(prof), n64 = n;
    sort_by_min_x(cycle, st);
    // The min x of every box read in last cycle's order (a gather), keys and ids read and
    // written by the mend (or the radix sort's passes: counted as one).
    bpx__profile_add(prof, "prune", "sort", &t, BPX_ACCESS_SEQUENTIAL, 4 * n64 + 8 * n64,
                     8 * n64, 0);
    gather(cycle, st);
    // Every box fetched by id in sorted order into the SoA arrays.
    bpx__profile_add(prof, "prune", "gather", &t, BPX_ACCESS_GATHER, 4 * n64 + 24 * n64,
                     24 * n64, n64);

    bpx_sorted sorted = {{st->lo[0], st->lo[1], st->lo[2]}, {st->hi[0], st->hi[1], st->hi[2]},
                         st->ids, n};
    bpx__prune_sweep_blocks(cycle, &sorted, cycle->sink->block_count);
    uint64_t hits = 0;
    for (int k = 0; prof && k < cycle->sink->block_count; k++)
        hits += cycle->sink->blocks[k].hits.count;
    // The sorted boxes read once (more where a box meets many), a pair written per hit.
    bpx__profile_add(prof, "prune", "sweep", &t, BPX_ACCESS_SEQUENTIAL, 28 * n64, 8 * hits, 0);

    bpx_status status =
        bpx__emitter_sort_blocks(cycle->sink, n, &st->sorted, &st->spare, st->counts);
    // As sap's order (rebuild.c): gathered, scattered by i (a record at random each), runs by j.
    if (hits > 0)
        bpx__profile_add(prof, "prune", "order", &t, BPX_ACCESS_SCATTER, 4 * 8 * hits + 8 * n64,
                         3 * 8 * hits + 4 * n64, hits);
    return status;
}

static bool prune_query(const bpx_world_def *def, const char **reason, char *detail,
                        size_t size)
{
    bpx_simd simd = def->simd == BPX_SIMD_AUTO ? bpx_simd_best() : def->simd;
    *reason = "";
    if (!bpx_simd_supported(simd)) {
        *reason = "SIMD width not supported here";
        return false;
    }
    snprintf(detail, size, "sort on x + sweep, %s, %d lanes, threads", bpx_simd_name(simd),
             bpx_simd_lanes(simd));
    return true;
}

const bpx_backend_impl bpx__prune_backend = {
    .id = BPX_BACKEND_PRUNE,
    .name = "prune",
    .query = prune_query,
    .compare = prune_compare,
    .destroy = prune_destroy,
};
