// The grid's hits to (i, j) order (7.): bucketed by i on the workers, each bucket sorted in
// cache, the result in block 0.

#include <string.h>

#include "grid_internal.h"

// ---------------------------------------------------------------------------------------------
// 7. Hits to (i, j) order

typedef struct emit_job {
    const bpx_cycle *cycle;
    bpx_grid_state *st;
    int groups, buckets, items, j_passes, shift;
    bpx_pair *to;    // the bucketed pairs (scratch)
    bpx_pair *other; // the result: block 0's list
} emit_job;

static void emit_range(const emit_job *job, int g, int *b0, int *b1)
{
    int blocks = job->cycle->sink->block_count;
    *b0 = (int)((int64_t)blocks * g / job->groups);
    *b1 = (int)((int64_t)blocks * (g + 1) / job->groups);
}

static void emit_count_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    const emit_job *job = context;
    for (int g = begin; g < end; g++) {
        uint32_t *hist = job->st->emit_hist + (size_t)g * job->buckets;
        memset(hist, 0, sizeof(uint32_t) * (size_t)job->buckets);
        int b0, b1;
        emit_range(job, g, &b0, &b1);
        for (int b = b0; b < b1; b++) {
            const bpx_pair_list *hits = &job->cycle->sink->blocks[b].hits;
            for (size_t k = 0; k < hits->count; k++)
                hist[hits->pairs[k].i >> job->shift]++;
        }
    }
}

static void emit_scatter_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    const emit_job *job = context;
    for (int g = begin; g < end; g++) {
        uint32_t *offset = job->st->emit_hist + (size_t)g * job->buckets;
        int b0, b1;
        emit_range(job, g, &b0, &b1);
        for (int b = b0; b < b1; b++) {
            const bpx_pair_list *hits = &job->cycle->sink->blocks[b].hits;
            for (size_t k = 0; k < hits->count; k++)
                job->to[offset[hits->pairs[k].i >> job->shift]++] = hits->pairs[k];
        }
    }
}

// Pairs of one i sorted by j, in place: insertion for the usual few, LSD counting passes
// (through scratch) for a box that meets many.
static void sort_run(bpx_pair *run, bpx_pair *scratch, uint32_t count, int j_passes)
{
    if (count <= 32) {
        for (uint32_t k = 1; k < count; k++) {
            bpx_pair x = run[k];
            uint32_t at = k;
            for (; at > 0 && x.j < run[at - 1].j; at--)
                run[at] = run[at - 1];
            run[at] = x;
        }
        return;
    }
    enum { DIGITS = 1 << EMIT_SHIFT };
    uint32_t counts[DIGITS + 1];
    bpx_pair *src = run, *dst = scratch;
    for (int pass = 0; pass < j_passes; pass++) {
        int at = pass * EMIT_SHIFT;
        memset(counts, 0, sizeof counts);
        for (uint32_t k = 0; k < count; k++)
            counts[((src[k].j >> at) & (DIGITS - 1)) + 1]++;
        for (uint32_t d = 0; d < DIGITS; d++)
            counts[d + 1] += counts[d];
        for (uint32_t k = 0; k < count; k++)
            dst[counts[(src[k].j >> at) & (DIGITS - 1)]++] = src[k];
        bpx_pair *t = src;
        src = dst;
        dst = t;
    }
    if (src != run)
        memcpy(run, src, sizeof(bpx_pair) * count);
}

// Sorts one bucket of src (2^shift ids) by (i, j) into dst: a counting pass on i's low bits,
// then each i's pairs by j (src is the scratch). The runs of one i are found by a pass over the
// pairs, not over the 2^shift ids: at about one overlap per box a bucket holds half as many
// pairs as ids, and that pass (with a copy of the counts for it) went (`bpx bench --profile
// --backend grid`, 1M boxes, one thread: this stage 6-26% faster, before and after alternating).
static void sort_bucket(bpx_pair *src, bpx_pair *dst, uint32_t count, int j_passes, int shift)
{
    enum { IDS = 1 << EMIT_SHIFT };
    uint32_t counts[IDS + 1];
    uint32_t mask = (1u << shift) - 1;
    memset(counts, 0, sizeof(uint32_t) * (mask + 2));
    for (uint32_t k = 0; k < count; k++)
        counts[(src[k].i & mask) + 1]++;
    for (uint32_t d = 0; d <= mask; d++)
        counts[d + 1] += counts[d];
    for (uint32_t k = 0; k < count; k++)
        dst[counts[src[k].i & mask]++] = src[k];
    for (uint32_t k = 0; k < count;) {
        uint32_t end = k + 1;
        while (end < count && dst[end].i == dst[k].i)
            end++;
        if (end - k > 1)
            sort_run(dst + k, src + k, end - k, j_passes);
        k = end;
    }
}

static void emit_sort_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    const emit_job *job = context;
    const uint32_t *start = job->st->bucket_start;
    for (int item = begin; item < end; item++) {
        int b0 = (int)((int64_t)job->buckets * item / job->items);
        int b1 = (int)((int64_t)job->buckets * (item + 1) / job->items);
        for (int b = b0; b < b1; b++)
            sort_bucket(job->to + start[b], job->other + start[b], start[b + 1] - start[b],
                        job->j_passes, job->shift);
    }
}

bpx_status bpx__grid_emit_sorted(const bpx_cycle *cycle, bpx_grid_state *st, uint32_t n)
{
    size_t total = 0;
    bpx_status status = bpx__emitter_total(cycle->sink, &total);
    if (status != BPX_OK)
        return status;
    uint64_t tests = 0;
    for (int k = 0; k < cycle->sink->block_count; k++)
        tests += cycle->sink->blocks[k].tests;
    if (total > UINT32_MAX)
        return BPX_ERR_TOO_MANY_PAIRS; // bucket offsets are 32-bit
    // Buckets of 2^shift ids holding about EMIT_BUCKET_PAIRS pairs (dense pair sets: fewer ids).
    int shift = EMIT_SHIFT;
    while (shift > 0 && (double)total * (double)(1u << shift) > (double)EMIT_BUCKET_PAIRS * n)
        shift--;
    int buckets = n ? (int)(((n - 1) >> shift) + 1) : 1;
    int groups = cycle->sink->block_count < EMIT_GROUPS ? cycle->sink->block_count : EMIT_GROUPS;
    int j_passes = 1; // 11-bit digits of the largest j
    for (uint32_t top = n ? n - 1 : 0;
         EMIT_SHIFT * j_passes < 32 && top >> (EMIT_SHIFT * j_passes);)
        j_passes++;
    // The result goes to block 0's list, whose hits are read (into the buckets) before it is
    // written: grown to hold them all, its hits kept, a sixteenth over (it is most of the pairs'
    // memory, and coherent cycles' totals move little).
    bpx_pair_list *result = &cycle->sink->blocks[0].hits;
    if (result->capacity < total) {
        size_t capacity = total + total / 16 + 64;
        if (!bpx__grow((void **)&result->pairs, result->capacity * sizeof(bpx_pair),
                       capacity * sizeof(bpx_pair)))
            return BPX_ERR_OUT_OF_MEMORY;
        result->capacity = capacity;
    }
    // The buckets: in the entries, dead since the tests, when they hold the pairs (about one a
    // box against 1.5 entries of 32 bytes at the grid's density); else the grid's own list.
    bpx_pair *to = NULL;
    size_t need = total * sizeof(bpx_pair);
    if (st->entry_capacity * sizeof(bpx_grid_entry) >= need)
        to = (bpx_pair *)(void *)st->entries;
    else if (st->lent_bytes >= need)
        to = (bpx_pair *)st->lent_base;
    else if (bpx__list_reserve(&st->a, total + total / 4))
        to = st->a.pairs;
    if (!to ||
        !reserve_array((void **)&st->emit_hist, &st->emit_hist_capacity,
                       (size_t)groups * (size_t)buckets, sizeof(uint32_t)) ||
        !reserve_array((void **)&st->bucket_start, &st->bucket_capacity, (size_t)buckets + 1,
                       sizeof(uint32_t)))
        return BPX_ERR_OUT_OF_MEMORY;
    emit_job job = {cycle,    st,    groups, buckets, buckets < EMIT_ITEMS ? buckets : EMIT_ITEMS,
                    j_passes, shift, to,     result->pairs};
    bpx_profile *prof = cycle->profile;
    uint64_t t = bpx__profile_clock(prof), bytes = 8 * (uint64_t)total;
    if (total) {
        bpx__parallel_for(cycle->executor, emit_count_task, groups, &job);
        bpx__profile_add(prof, "grid", "order: count", &t, BPX_ACCESS_SEQUENTIAL, bytes,
                         4 * (uint64_t)groups * buckets, 0);
        uint32_t at = 0;
        for (int b = 0; b < buckets; b++) {
            st->bucket_start[b] = at;
            for (int g = 0; g < groups; g++) {
                uint32_t *slot = &st->emit_hist[(size_t)g * buckets + b];
                uint32_t c = *slot;
                *slot = at;
                at += c;
            }
        }
        st->bucket_start[buckets] = at;
        bpx__parallel_for(cycle->executor, emit_scatter_task, groups, &job);
        // Each pair to its bucket: a few hundred write streams, not single records at random.
        bpx__profile_add(prof, "grid", "order: buckets", &t, BPX_ACCESS_SEQUENTIAL, bytes, bytes,
                         0);
        bpx__parallel_for(cycle->executor, emit_sort_task, job.items, &job);
        // Each bucket in cache: read, counted by i, written in (i, j) order.
        bpx__profile_add(prof, "grid", "order: sort", &t, BPX_ACCESS_SEQUENTIAL, bytes, bytes, 0);
    }
    // Block 0 holds the ordered list.
    for (int k = 0; k < cycle->sink->block_count; k++) {
        cycle->sink->blocks[k].hits.count = 0;
        cycle->sink->blocks[k].tests = 0;
    }
    result->count = total;
    cycle->sink->blocks[0].tests = tests;
    return BPX_OK;
}
