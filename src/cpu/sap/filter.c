// sap's passes over every box and every fat pair: the boxes checked against their fat boxes
// (bpx__sap_check_boxes), and the fat pairs filtered by the exact overlap
// (bpx__sap_filter_pairs); both in ranges on the workers, packed in order after.

#include <string.h>

#include "sap_internal.h"

// Boxes [i0, i1) into cur, and those that left their fat boxes into changed from i0 on;
// returns their count.
static uint32_t check_range(const bpx_cycle *cycle, bpx_sap_state *st, uint32_t i0, uint32_t i1)
{
    const bpx_soa *b = &cycle->boxes;
    const bpx_box *fat = st->a.fat;
    bpx_box *cur = st->a.cur;
    uint32_t *changed = st->a.changed + i0, count = 0;
    uint32_t i = i0;
#ifdef BPX_HAVE_TRANSPOSE4
    // Four boxes at a time: loaded as vectors, stored to cur by one transpose, checked against
    // their fat boxes transposed the other way.
    for (; i + 4 <= i1; i += 4) {
        __m128 v[6], f[6];
        for (int a = 0; a < 3; a++) {
            v[a] = _mm_loadu_ps(b->lo[a] + i);
            v[3 + a] = _mm_loadu_ps(b->hi[a] + i);
        }
        bpx__soa4_to_boxes(v, &cur[i]);
        bpx__boxes4_to_soa(&fat[i], f);
        __m128 inside = _mm_and_ps(_mm_cmpge_ps(v[0], f[0]), _mm_cmple_ps(v[3], f[3]));
        for (int a = 1; a < 3; a++)
            inside = _mm_and_ps(inside, _mm_and_ps(_mm_cmpge_ps(v[a], f[a]),
                                                   _mm_cmple_ps(v[3 + a], f[3 + a])));
        int left = ~_mm_movemask_ps(inside) & 0xf;
        for (uint32_t k = 0; k < 4; k++) {
            changed[count] = i + k;
            count += (uint32_t)(left >> k) & 1;
        }
    }
#endif
    for (; i < i1; i++) {
        bpx_box box = {{b->lo[0][i], b->lo[1][i], b->lo[2][i]},
                       {b->hi[0][i], b->hi[1][i], b->hi[2][i]}};
        cur[i] = box;
        bool inside = (box.min[0] >= fat[i].min[0]) & (box.min[1] >= fat[i].min[1]) &
                      (box.min[2] >= fat[i].min[2]) & (box.max[0] <= fat[i].max[0]) &
                      (box.max[1] <= fat[i].max[1]) & (box.max[2] <= fat[i].max[2]);
        changed[count] = i;
        count += !inside;
    }
    return count;
}

static void check_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    bpx_sap_job *job = context;
    for (int c = begin; c < end; c++)
        job->st->chunk_count[c] =
            check_range(job->cycle, job->st, chunk_begin(job->n, job->chunks, (uint32_t)c),
                        chunk_begin(job->n, job->chunks, (uint32_t)c + 1));
}

// How many ranges a pass over `count` items splits into (1: serial).
uint32_t bpx__sap_chunks_for(const bpx_cycle *cycle, size_t count)
{
    int workers = cycle->executor->worker_count;
    if (count < PARALLEL_MIN || workers < 2)
        return 1;
    return 4 * (uint32_t)workers < CHUNKS_MAX ? 4 * (uint32_t)workers : CHUNKS_MAX;
}

// This cycle's boxes into cur, and the boxes that left their fat boxes into changed, in id
// order (ranges on the workers, then packed); returns their count.
static uint32_t check_boxes(const bpx_cycle *cycle, bpx_sap_state *st)
{
    uint32_t chunks = bpx__sap_chunks_for(cycle, cycle->n);
    if (chunks == 1)
        return check_range(cycle, st, 0, cycle->n);
    bpx_sap_job job = {.st = st, .cycle = cycle, .n = cycle->n, .chunks = chunks};
    bpx__parallel_for(cycle->executor, check_task, (int)chunks, &job);
    uint32_t count = 0;
    for (uint32_t c = 0; c < chunks; c++) {
        uint32_t at = chunk_begin(cycle->n, chunks, c);
        if (at != count)
            memmove(st->a.changed + count, st->a.changed + at,
                    st->chunk_count[c] * sizeof(uint32_t));
        count += st->chunk_count[c];
    }
    return count;
}

uint32_t bpx__sap_check_boxes(const bpx_cycle *cycle, bpx_sap_state *st)
{
    uint64_t t = bpx__profile_clock(cycle->profile), n = cycle->n;
    uint32_t count = check_boxes(cycle, st);
    // Read: the SoA boxes and the fat boxes; written: the boxes (AoS) and the changed ids.
    bpx__profile_add(cycle->profile, "sap", "check", &t, BPX_ACCESS_SEQUENTIAL, 48 * n,
                     24 * n + 4 * (uint64_t)count, 0);
    return count;
}

// The fat pairs [k0, k1) whose boxes overlap, into out from k0 on; returns their count.
static size_t filter_range(const bpx_sap_state *st, bpx_pair *out, size_t k0, size_t k1)
{
    const bpx_box *cur = st->a.cur;
    const bpx_pair *fat = st->fat_pairs.pairs;
    size_t count = 0;
    out += k0;
    for (size_t k = k0; k < k1; k++) {
        if (k + PREFETCH < k1) { // j is anywhere: fetch it early (i comes in order), both
                                 // lines when its 24 bytes straddle two
            const bpx_box *next = &cur[fat[k + PREFETCH].j];
            PREFETCH_READ(next);
            PREFETCH_READ((const char *)next + sizeof *next - 1);
        }
        out[count] = fat[k];
        count += overlap(&cur[fat[k].i], &cur[fat[k].j]);
    }
    return count;
}

static void filter_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    bpx_sap_job *job = context;
    size_t total = job->st->fat_pairs.count;
    for (int c = begin; c < end; c++)
        job->st->chunk_count[c] = (uint32_t)filter_range(job->st, job->out, (size_t)((uint64_t)total * c / job->chunks),
                         (size_t)((uint64_t)total * (c + 1) / job->chunks));
}

// The exact pairs, fat pairs whose boxes overlap, into out (which holds fat_pairs.count), in
// the fat pairs' order (ranges on the workers, then packed).
static size_t filter_pairs(const bpx_cycle *cycle, bpx_sap_state *st, bpx_pair *out);

size_t bpx__sap_filter_pairs(const bpx_cycle *cycle, bpx_sap_state *st, bpx_pair *out)
{
    uint64_t t = bpx__profile_clock(cycle->profile), fat = st->fat_pairs.count;
    size_t count = filter_pairs(cycle, st, out);
    // Read: each fat pair, its first box in id order and its second anywhere (the gather);
    // written: the pairs that overlap.
    if (fat > 0)
        bpx__profile_add(cycle->profile, "sap", "filter", &t, BPX_ACCESS_GATHER,
                         8 * fat + 48 * fat, 8 * (uint64_t)count, fat);
    return count;
}

static size_t filter_pairs(const bpx_cycle *cycle, bpx_sap_state *st, bpx_pair *out)
{
    size_t total = st->fat_pairs.count;
    if (total == 0)
        return 0; // out may be NULL (an empty list owns no memory): no pointer arithmetic on it
    uint32_t chunks = total <= UINT32_MAX ? bpx__sap_chunks_for(cycle, total) : 1;
    if (chunks == 1)
        return filter_range(st, out, 0, total);
    bpx_sap_job job = {.st = st, .chunks = chunks, .out = out};
    bpx__parallel_for(cycle->executor, filter_task, (int)chunks, &job);
    size_t count = 0;
    for (uint32_t c = 0; c < chunks; c++) {
        size_t at = (size_t)((uint64_t)total * c / chunks);
        if (at != count)
            memmove(out + count, out + at, st->chunk_count[c] * sizeof(bpx_pair));
        count += st->chunk_count[c];
    }
    return count;
}
