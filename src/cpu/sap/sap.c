// The sap backend: sweep and prune with temporal coherence (the persistent sorted endpoint
// lists of SOLID and of Bullet's AxisSweep3, written here from the idea, not their code), over
// fat boxes. Paper modules: the comparator, past the paper (the pairs kept between cycles, as the
// paper's sweep-and-prune baseline of Table 2 does); its exact filter emits in (i, j) order.
//
// This file: the state's memory, and each cycle's choice between the warm cycle (mend.c) and a
// rebuild (rebuild.c); sap_internal.h describes the state and lists the other files.
//
// Threads: from PARALLEL_MIN boxes, the warm cycle's check of the boxes and its exact filter split
// into ranges on the world's workers (each range's output packed after, in order), and the
// one-pass mend and a full rebuild's sorts run the three lists at once (each list has its own sort
// memory: at a million boxes the three sorts in a row would be half of a rebuild, and a rebuild
// is what sets p99 there); the few-boxes mend is serial; the cold sweep (or grid) runs on the
// workers. The output is the same bytes either way. Memory: about 230 bytes per box (three
// endpoint lists, their indexes and their unsorted copies, three box copies, the cold sweep's
// arrays) plus a few pair lists, 24 KiB of sort memory (72 KiB when the lists sort at once, and
// 128 KiB more per list past 65,536 boxes), and the grid's own state once a rebuild has used it
// (kept for the next); grown with slack, so steady cycles allocate nothing.

#include <stdio.h>
#include <string.h>

#include "sap_internal.h"

// ---------------------------------------------------------------------------------------------
// Memory

// Every array of a with its size in bytes for `capacity` boxes; returns the count.
static int array_table(bpx_sap_arrays *a, size_t capacity, void ***ptrs, size_t *sizes)
{
    int k = 0;
    for (int axis = 0; axis < 3; axis++) {
        ptrs[k] = (void **)&a->ends[axis];
        sizes[k++] = 2 * capacity * sizeof(uint64_t);
        ptrs[k] = (void **)&a->where[axis];
        sizes[k++] = 2 * capacity * sizeof(uint32_t);
    }
    bpx_box **boxes[] = {&a->fat, &a->fat_prev, &a->cur};
    for (int b = 0; b < 3; b++) {
        ptrs[k] = (void **)boxes[b];
        sizes[k++] = capacity * sizeof(bpx_box);
    }
    ptrs[k] = (void **)&a->changed;
    sizes[k++] = capacity * sizeof(uint32_t);
    for (int axis = 0; axis < 3; axis++) {
        ptrs[k] = (void **)&a->words[axis];
        sizes[k++] = 2 * capacity * sizeof(uint64_t);
    }
    for (int axis = 0; axis < 3; axis++) {
        ptrs[k] = (void **)&a->lo[axis];
        sizes[k++] = (capacity + PAD) * sizeof(float);
        ptrs[k] = (void **)&a->hi[axis];
        sizes[k++] = (capacity + PAD) * sizeof(float);
    }
    ptrs[k] = (void **)&a->sorted_ids;
    sizes[k++] = (capacity + PAD) * sizeof(uint32_t);
    ptrs[k] = (void **)&a->counts;
    sizes[k++] = (capacity + 1) * sizeof(uint32_t);
    return k;
}

static void free_arrays(bpx_sap_arrays *a, uint32_t capacity)
{
    void **ptrs[ARRAY_COUNT];
    size_t sizes[ARRAY_COUNT];
    int count = array_table(a, capacity, ptrs, sizes);
    for (int k = 0; k < count; k++) {
        bpx__free(*ptrs[k], sizes[k]);
        *ptrs[k] = NULL;
    }
}

static void list_free(bpx_pair_list *list)
{
    bpx__free(list->pairs, list->capacity * sizeof(bpx_pair));
    *list = (bpx_pair_list){0};
}

static void sap_destroy(void *state)
{
    bpx_sap_state *st = state;
    free_arrays(&st->a, st->capacity);
    for (int k = 0; k < 3; k++)
        if (st->radix[k]) {
            bpx__free(st->radix[k]->lines, sizeof(bpx_radix_lines));
            bpx__free(st->radix[k], sizeof(bpx_radix_work));
        }
    bpx__grid_free(&st->grid);
    bpx_pair_list *lists[] = {&st->fat_pairs,      &st->merged,         &st->changes,
                              &st->spare,          &st->axis_changes[0], &st->axis_changes[1],
                              &st->axis_changes[2]};
    for (size_t k = 0; k < sizeof lists / sizeof lists[0]; k++)
        list_free(lists[k]);
    bpx__free(st, sizeof *st);
}

// Makes the arrays hold n boxes. With `keep`, the endpoint lists (2 * st->n each) and the fat
// boxes (st->n) survive a move to bigger arrays. All or nothing: on failure st is as it was.
static bool reserve_arrays(bpx_sap_state *st, uint32_t n, bool keep)
{
    if (n <= st->capacity && st->a.ends[0])
        return true;
    // Growth by add_boxes comes in small steps: leave room for more.
    uint64_t capacity = st->capacity ? (uint64_t)st->capacity + st->capacity / 2 : 0;
    if (capacity < n)
        capacity = n;
    if (capacity > BPX_MAX_BOXES)
        capacity = BPX_MAX_BOXES;
    if (capacity == 0)
        capacity = 1;
    bpx_sap_arrays grown = {0};
    void **ptrs[ARRAY_COUNT];
    size_t sizes[ARRAY_COUNT];
    int count = array_table(&grown, capacity, ptrs, sizes);
    for (int k = 0; k < count; k++)
        if (!(*ptrs[k] = bpx__alloc(sizes[k]))) {
            free_arrays(&grown, (uint32_t)capacity);
            return false;
        }
    if (keep && st->a.ends[0]) {
        for (int axis = 0; axis < 3; axis++) {
            memcpy(grown.ends[axis], st->a.ends[axis], 2 * (size_t)st->n * sizeof(uint64_t));
            memcpy(grown.where[axis], st->a.where[axis], 2 * (size_t)st->n * sizeof(uint32_t));
        }
        memcpy(grown.fat, st->a.fat, (size_t)st->n * sizeof(bpx_box));
        memcpy(grown.fat_prev, st->a.fat_prev, (size_t)st->n * sizeof(bpx_box));
        for (int s = 0; s < 3; s++) { // the scan list
            memcpy(grown.lo[s], st->a.lo[s], (size_t)st->n * sizeof(float));
            memcpy(grown.hi[s], st->a.hi[s], (size_t)st->n * sizeof(float));
        }
        memcpy(grown.sorted_ids, st->a.sorted_ids, (size_t)st->n * sizeof(uint32_t));
    }
    free_arrays(&st->a, st->capacity);
    st->a = grown;
    st->capacity = (uint32_t)capacity;
    return true;
}

// ---------------------------------------------------------------------------------------------
// The backend

static bpx_status sap_compare(void **state, bpx_cycle *cycle)
{
    bpx_sap_state *st = *state;
    if (!st) {
        if (!(st = bpx__alloc(sizeof *st)))
            return BPX_ERR_OUT_OF_MEMORY;
        *st = (bpx_sap_state){0};
        *state = st;
    }
    uint32_t n = cycle->n;
    // Two give-ups in a row mean the motion is not coherent: rebuild without trying, and try
    // mending again every RETRY_EVERY cycles (a single jump costs one wasted attempt, a run of
    // incoherent cycles one in RETRY_EVERY).
    bool warm = st->valid && n >= st->n && n - st->n <= st->n / 8 &&
                (st->give_ups < 2 || st->waited + 1 >= RETRY_EVERY);
    if (!reserve_arrays(st, n, warm)) {
        st->valid = false;
        return BPX_ERR_OUT_OF_MEMORY;
    }
    st->valid = false; // until this cycle completes
    st->checked = false;
    bpx_status status = BPX_OK;
    if (warm) {
        bpx_sap_mend_result r = bpx__sap_warm_cycle(cycle, st);
        if (r == MEND_NO_MEMORY)
            return BPX_ERR_OUT_OF_MEMORY;
        st->give_ups = r == MEND_DONE ? 0 : st->give_ups + 1;
        st->waited = 0;
        warm = r == MEND_DONE;
    } else {
        st->waited++;
    }
    bool lists = true; // the lists describe this cycle at its end
    if (warm) {
        // Block 0 gets the exact pairs; the other blocks, left by the last rebuild, are
        // dropped.
        status = bpx__emitter_own_blocks(cycle->sink, 1);
        if (status != BPX_OK)
            return status;
        bpx_block *out = &cycle->sink->blocks[0];
        out->hits.count = 0;
        if (!bpx__list_reserve(&out->hits, st->fat_pairs.count))
            return BPX_ERR_OUT_OF_MEMORY;
        out->hits.count = bpx__sap_filter_pairs(cycle, st, out->hits.pairs);
        out->tests = st->fat_pairs.count;
        out->status = BPX_OK;
    } else {
        // The lists are wanted only when the next cycle may mend: while coherent, or on the
        // cycle before a retry.
        lists = st->give_ups < 2 || st->waited + 1 >= RETRY_EVERY;
        status = lists ? bpx__sap_full_rebuild(cycle, st) : bpx__sap_rebuild_without_lists(cycle, st);
        if (status != BPX_OK)
            return status;
    }
    cycle->report.rebuilt = !warm;
    st->n = n;
    st->valid = lists;
    return BPX_OK;
}

bpx_sap_counters bpx__sap_counters(const bpx_world *w)
{
    const bpx_sap_state *st = bpx__world_backend_state(w, &bpx__sap_backend);
    bpx_sap_counters c = st ? st->counters : (bpx_sap_counters){0};
    for (int axis = 0; axis < 3 && st; axis++)
        c.margin[axis] = st->margin[axis];
    return c;
}

static bool sap_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    bpx_simd simd = def->simd == BPX_SIMD_AUTO ? bpx_simd_best() : def->simd;
    *reason = "";
    if (!bpx_simd_supported(simd)) {
        *reason = "SIMD width not supported here";
        return false;
    }
    snprintf(detail, size,
             "3-axis fat endpoint lists mended by insertion; rebuild sweep %s (grid when dense)",
             bpx_simd_name(simd));
    return true;
}

const bpx_backend_impl bpx__sap_backend = {
    .id = BPX_BACKEND_SAP,
    .name = "sap",
    .query = sap_query,
    .compare = sap_compare,
    .destroy = sap_destroy,
};
