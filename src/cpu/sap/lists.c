// sap's endpoint lists: made by a rebuild's radix sorts (bpx__sap_make_lists), grown by add_boxes
// (bpx__sap_append_boxes), and indexed for the few-boxes mend (bpx__sap_index_lists).

#include <string.h>

#include "sap_internal.h"

// where[axis] for a whole list (after a sort or a shift of every word).
static void index_list(bpx_sap_arrays *a, int axis, uint32_t count)
{
    const uint64_t *ends = a->ends[axis];
    uint32_t *where = a->where[axis];
    for (uint32_t k = 0; k < count; k++)
        where[end_slot(ends[k])] = k;
}

static void index_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    bpx_sap_job *job = context;
    for (int axis = begin; axis < end; axis++)
        index_list(&job->st->a, axis, 2 * job->n);
}

// where for the three lists at once (on the workers from PARALLEL_MIN boxes).
void bpx__sap_index_lists(const bpx_cycle *cycle, bpx_sap_state *st, uint32_t n)
{
    bpx_sap_job job = {.st = st, .n = n};
    if (n >= PARALLEL_MIN && cycle->executor->worker_count > 1)
        bpx__parallel_for(cycle->executor, index_task, 3, &job);
    else
        index_task(0, 3, 0, &job);
}

// Puts new boxes n_old .. n-1 into the lists as if they had been inert last cycle (maxima at
// the front, minima at the back; the next full pass puts them in order).
void bpx__sap_append_boxes(bpx_sap_state *st, uint32_t n_old, uint32_t n)
{
    uint32_t added = n - n_old;
    const float inf = 1.0f / 0.0f;
    const bpx_box inert = {{inf, inf, inf}, {-inf, -inf, -inf}};
    for (int axis = 0; axis < 3; axis++) {
        uint64_t *ends = st->a.ends[axis];
        memmove(ends + added, ends, 2 * (size_t)n_old * sizeof(uint64_t));
        for (uint32_t k = 0; k < added; k++) {
            ends[k] = fat_word(&inert, axis, true, n_old + k);
            ends[added + 2 * (size_t)n_old + k] = fat_word(&inert, axis, false, n_old + k);
        }
        index_list(&st->a, axis, 2 * n);
    }
    for (uint32_t i = n_old; i < n; i++)
        st->a.fat[i] = st->a.fat_prev[i] = inert;
}

// One axis's list for a full rebuild: the 2n fat endpoint words sorted into ends[axis] (minima
// listed before maxima, and the sort is stable, so ties come out in word order); and the count
// of pairs whose intervals overlap on the axis (inert boxes, the only ones with infinite keys,
// left out). where[axis] waits for the first few-boxes mend (the one-pass mend does without):
// a million boxes at rest may need none before their next rebuild, and its 2n scattered stores
// would take a third of the list's time.
static void rebuild_list(bpx_sap_state *st, uint32_t n, int axis, bpx_radix_work *work,
                         uint64_t *overlaps, uint32_t *live)
{
    bpx_sap_arrays *a = &st->a;
    uint64_t *words = a->words[axis], *ends = a->ends[axis];
    for (uint32_t i = 0; i < n; i++) {
        words[i] = end_word(coord_key(a->fat[i].min[axis]), i);
        words[n + i] = end_word(coord_key(a->fat[i].max[axis]), MAX_BIT | i);
    }
    bpx__radix_sort_words(words, ends, 2 * n, work);
    const uint32_t inf_key = coord_key(1.0f / 0.0f), minus_inf_key = coord_key(-1.0f / 0.0f);
    uint64_t sum = 0, open = 0, minima = 0;
    for (uint32_t k = 0; k < 2 * n; k++) {
        uint64_t e = ends[k];
        uint32_t key = (uint32_t)(e >> 32);
        if (key == inf_key || key == minus_inf_key)
            continue;
        if (e & MAX_BIT) {
            open--;
        } else {
            sum += open;
            open++;
            minima++;
        }
    }
    *overlaps = sum;
    *live = (uint32_t)minima;
}

static void list_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    bpx_sap_job *job = context;
    for (int axis = begin; axis < end; axis++)
        rebuild_list(job->st, job->n, axis, job->st->radix[job->chunks > 1 ? axis : 0],
                     &job->overlaps[axis], &job->live[axis]);
}

// The cold sorts' work memory for `sorts` lists at once, of `words` words each: made by the
// first rebuild that needs it (the lines only for lists long enough to stream), then kept.
bool bpx__sap_reserve_radix(bpx_sap_state *st, int sorts, size_t words)
{
    for (int k = 0; k < sorts; k++) {
        if (!st->radix[k]) {
            if (!(st->radix[k] = bpx__alloc(sizeof(bpx_radix_work))))
                return false;
            st->radix[k]->lines = NULL;
        }
        if (words >= BPX_RADIX_STREAM_WORDS && !st->radix[k]->lines &&
            !(st->radix[k]->lines = bpx__alloc(sizeof(bpx_radix_lines))))
            return false;
    }
    return true;
}

// The endpoint lists of the fat boxes by radix sort, and from the count of pairs overlapping on
// each axis the rebuild's choice: sweep along the axis with the fewest, unless even that one
// meets too many boxes per box: then the grid. *live: the boxes that are not inert. False when
// memory ran out.
//
// Where the grid is chosen (hundreds of thousands of boxes, dense), the next rebuilds keep the
// choice and leave the lists unmade while the n it was made at is within an eighth of theirs:
// there the lists cost more than the grid (1M boxes, 2 threads: 80-100 ms against 66-82,
// `bpx bench --backend sap --scene resting --sizes 1000000 --threads 2`), and
// a million boxes at rest may need no mend before the next rebuild (all fat boxes are made
// together, so the fastest boxes leave together: too many to mend). The first warm cycle that
// must mend (or grow) makes them, so such a cycle is warm but may cost a sort of three lists;
// the choice is counted again each time they are made.
bool bpx__sap_make_lists(const bpx_cycle *cycle, bpx_sap_state *st, uint32_t n, uint32_t *live)
{
    bool parallel = n >= PARALLEL_MIN && cycle->executor->worker_count > 1;
    if (!bpx__sap_reserve_radix(st, parallel ? 3 : 1, 2 * (size_t)n))
        return false;
    bpx_sap_job job = {.st = st, .n = n, .chunks = parallel ? 3 : 1}; // chunks: the sorts' memory
    uint64_t t = bpx__profile_clock(cycle->profile), words = 2 * (uint64_t)n;
    if (parallel)
        bpx__parallel_for(cycle->executor, list_task, 3, &job);
    else
        list_task(0, 3, 0, &job);
    // Per axis: the fat boxes' coordinates read into 2n words, three radix passes over them
    // (read and written), and one count of the overlaps over the sorted list.
    bpx__profile_add(cycle->profile, "sap", "lists", &t, BPX_ACCESS_SEQUENTIAL,
                     3 * (8 * (uint64_t)n + 3 * 8 * words + 8 * words),
                     3 * (8 * words + 3 * 8 * words), 0);
    const uint64_t *overlaps = job.overlaps;
    int axis = 0;
    for (int k = 1; k < 3; k++)
        if (overlaps[k] < overlaps[axis])
            axis = k;
    st->sweep_axis = axis;
    *live = job.live[axis]; // inert boxes are +inf..-inf on every axis
    st->use_grid = (double)overlaps[axis] > BPX_SWEEP_MAX_CANDIDATES * *live;
    st->counted_n = n;
    st->listed = true;
    st->indexed = false;
    st->counters.lists_made++;
    return true;
}
