// The tree's keys on the world's workers: a copy of the boxes (one cache line each), the Morton
// keys of the live boxes' centres, and a stable radix sort of them. Every pass works on fixed
// chunks of items and joins them in chunk order, so the order is the same for any worker count.
#include <math.h>
#include <string.h>

#include "bvh.h"

#define CHUNK BPX_BVH_CHUNK
#define run bpx__bvh_run
#define chunks_of bpx__bvh_chunks

enum { RADIX_BITS = 11, BUCKETS = 1 << RADIX_BITS };

// 10 bits of v spread to every third bit.
static uint32_t spread(uint32_t v)
{
    v &= 0x3FF;
    v = (v | (v << 16)) & 0x030000FF;
    v = (v | (v << 8)) & 0x0300F00F;
    v = (v | (v << 4)) & 0x030C30C3;
    v = (v | (v << 2)) & 0x09249249;
    return v;
}

// ---------------------------------------------------------------------------------------------
// Keys: per chunk of ids, a copy of the boxes and the live ones' centre bounds, then their keys.
// Large boxes share the Morton order of the small ones: a subtree of their own (the binary
// tree's remedy) made every ray of the heavy-tailed scene walk it too, 20-30% more nodes.

typedef struct chunk_stats {
    double lo[3], hi[3];
    uint32_t live;
    uint32_t first; // where the chunk's keys start
} chunk_stats;

typedef struct key_job {
    bpx_bvh *t;
    const bpx_soa *s;
    chunk_stats *stats;
    double lo[3], scale[3];
} key_job;

static void stats_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    key_job *job = context;
    for (int c = begin; c < end; c++) {
        chunk_stats st = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}, 0, 0};
        bpx__bvh_copy_chunk(job->t, job->s, (uint32_t)c);
        uint32_t first = (uint32_t)c * CHUNK;
        uint32_t last = first + CHUNK < job->s->n ? first + CHUNK : job->s->n;
        for (uint32_t i = first; i < last; i++) {
            const bpx_bvh_box *b = &job->t->boxes[i];
            if (!(b->lo[0] <= b->hi[0]))
                continue;
            for (int a = 0; a < 3; a++) {
                double m = 0.5 * ((double)b->lo[a] + (double)b->hi[a]);
                st.lo[a] = m < st.lo[a] ? m : st.lo[a];
                st.hi[a] = m > st.hi[a] ? m : st.hi[a];
            }
            st.live++;
        }
        job->stats[c] = st;
    }
}

// The keys only order the boxes: any rounding here changes the tree's shape, never a result.
static void key_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    key_job *job = context;
    for (int c = begin; c < end; c++) {
        uint64_t *out = job->t->words + job->stats[c].first;
        uint32_t first = (uint32_t)c * CHUNK;
        uint32_t last = first + CHUNK < job->s->n ? first + CHUNK : job->s->n;
        for (uint32_t i = first; i < last; i++) {
            const bpx_bvh_box *b = &job->t->boxes[i];
            if (!(b->lo[0] <= b->hi[0]))
                continue;
            uint32_t key = 0;
            for (int a = 0; a < 3; a++) {
                double m = 0.5 * ((double)b->lo[a] + (double)b->hi[a]);
                key |= spread((uint32_t)((m - job->lo[a]) * job->scale[a])) << (2 - a);
            }
            *out++ = (uint64_t)key << 32 | i;
        }
    }
}

uint32_t bpx__bvh_keys(bpx_bvh *t, const bpx_soa *s, const bpx_executor *ex)
{
    uint32_t chunks = chunks_of(s->n);
    key_job job = {.t = t, .s = s, .stats = (chunk_stats *)(void *)t->counts};
    run(ex, stats_task, chunks, s->n, &job);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    uint32_t m = 0;
    for (uint32_t c = 0; c < chunks; c++) {
        chunk_stats *st = &job.stats[c];
        for (int a = 0; a < 3; a++) {
            lo[a] = st->lo[a] < lo[a] ? st->lo[a] : lo[a];
            hi[a] = st->hi[a] > hi[a] ? st->hi[a] : hi[a];
        }
        st->first = m;
        m += st->live;
    }
    for (int a = 0; a < 3; a++) {
        job.lo[a] = lo[a];
        job.scale[a] = hi[a] > lo[a] ? 1023.0 / (hi[a] - lo[a]) : 0.0;
    }
    run(ex, key_task, chunks, s->n, &job);
    return m;
}

// ---------------------------------------------------------------------------------------------
// Stable LSD radix sort of the words by key, 11 bits a pass: per chunk a histogram, then each
// chunk scatters to its own offsets (bucket by bucket, chunk by chunk: stable).

typedef struct sort_job {
    const uint64_t *src;
    uint64_t *dst;
    uint32_t *counts; // [chunk][bucket]
    uint32_t n;
    int shift;
} sort_job;

static void histogram_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    sort_job *job = context;
    for (int c = begin; c < end; c++) {
        uint32_t *count = job->counts + (size_t)c * BUCKETS;
        memset(count, 0, sizeof(uint32_t) * BUCKETS);
        uint32_t last = (uint32_t)c * CHUNK + CHUNK < job->n ? (uint32_t)c * CHUNK + CHUNK : job->n;
        for (uint32_t k = (uint32_t)c * CHUNK; k < last; k++)
            count[(job->src[k] >> job->shift) & (BUCKETS - 1)]++;
    }
}

static void scatter_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    sort_job *job = context;
    for (int c = begin; c < end; c++) {
        uint32_t *at = job->counts + (size_t)c * BUCKETS;
        uint32_t last = (uint32_t)c * CHUNK + CHUNK < job->n ? (uint32_t)c * CHUNK + CHUNK : job->n;
        for (uint32_t k = (uint32_t)c * CHUNK; k < last; k++) {
            uint64_t x = job->src[k];
            job->dst[at[(x >> job->shift) & (BUCKETS - 1)]++] = x;
        }
    }
}

void bpx__bvh_sort(bpx_bvh *t, uint32_t m, const bpx_executor *ex)
{
    uint32_t chunks = chunks_of(m);
    sort_job job = {t->words, t->words_scratch, t->counts, m, 0};
    for (int shift = 32; shift < 62; shift += RADIX_BITS) {
        job.shift = shift;
        run(ex, histogram_task, chunks, m, &job);
        // Bucket by bucket, chunk by chunk: the counts become each chunk's first slot.
        uint32_t sum = 0;
        bool single = false;
        for (uint32_t b = 0; b < BUCKETS && !single; b++) {
            uint32_t bucket = 0;
            for (uint32_t c = 0; c < chunks; c++) {
                uint32_t *count = &job.counts[(size_t)c * BUCKETS + b];
                uint32_t here = *count;
                *count = sum + bucket;
                bucket += here;
            }
            single = bucket == m; // every key has this digit: nothing to move
            sum += bucket;
        }
        if (single)
            continue;
        run(ex, scatter_task, chunks, m, &job);
        const uint64_t *done = job.dst;
        job.dst = (uint64_t *)job.src;
        job.src = done;
    }
    if (job.src != t->words) { // an odd number of passes moved: the result is in the scratch
        uint64_t *swap = t->words;
        t->words = t->words_scratch;
        t->words_scratch = swap;
    }
}

size_t bpx__bvh_count_words(uint32_t n)
{
    size_t stats = sizeof(chunk_stats) / sizeof(uint32_t) * chunks_of(n);
    size_t radix = (size_t)BUCKETS * chunks_of(n);
    return stats > radix ? stats : radix;
}
