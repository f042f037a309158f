// The tree's keys on the world's workers: a copy of the boxes (one cache line each), the
// Morton-like keys of the live boxes' centres, and a stable radix sort of them. Every pass
// works on fixed chunks of items and joins them in chunk order, so the order is the same for
// any worker count.
#include <math.h>
#include <string.h>

#include "bvh.h"

#define CHUNK BPX_BVH_CHUNK
#define run bpx__bvh_run
#define chunks_of bpx__bvh_chunks

enum { RADIX_BITS = 11, BUCKETS = 1 << RADIX_BITS };

// ---------------------------------------------------------------------------------------------
// Keys: per chunk of ids, a copy of the boxes, the live ones' centre bounds, and per shape class
// the count and extents; then their keys. Large boxes share the Morton order of the small ones:
// a subtree of their own (the binary tree's remedy) made every ray of the heavy-tailed scene
// walk it too, 20-30% more nodes.
//
// Long boxes change two things. The key's bits interleave the axes in the order that shrinks
// the nodes' area most (a node's bounds are its cell grown by its boxes): where boxes are 50
// times longer on x, cells take their y and z bits first and end up long on x like their boxes
// (cubic cells made every node as long as a box, around a cell a fiftieth of that). And boxes
// long on different axes (their longest side over 4 times the next), each class at least an
// eighth of them, go to subtrees of their own (two key bits, below the top bits), each with
// its own order: mixed, every node was long on every axis. Cube-like boxes keep the plain
// x, y, z order.

enum { CLASSES = 4, LONG_RATIO = 4 };

typedef struct chunk_stats {
    double lo[3], hi[3];
    double extent[CLASSES][3]; // sums of the live boxes' sides, by class
    uint32_t count[CLASSES];
    uint32_t live;
    uint32_t first; // where the chunk's keys start
} chunk_stats;

typedef struct key_job {
    bpx_bvh *t;
    const bpx_soa *s;
    chunk_stats *stats;
    double lo[3], scale[3];
    int class_shift;           // where the subtree's two bits go
    uint8_t class_of[CLASSES]; // a shape class's subtree (0 when not split off)
    // Per subtree and axis, the key bits of a 10-bit coordinate's low and high five bits.
    uint32_t bits[CLASSES][3][2][32];
} key_job;

// 0 for a cube-like box, 1 + a for one long on axis a. Without branches: which side is the
// longest is random in most scenes (a branch on it cost the build 10% at 1M boxes).
static int shape_class(const bpx_bvh_box *b)
{
    float e[3];
    for (int a = 0; a < 3; a++)
        e[a] = b->hi[a] - b->lo[a];
    int k = 0;
    for (int a = 0; a < 3; a++)
        k += (a + 1) * ((e[a] > LONG_RATIO * e[(a + 1) % 3]) & (e[a] > LONG_RATIO * e[(a + 2) % 3]));
    return k;
}

static void stats_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    key_job *job = context;
    for (int c = begin; c < end; c++) {
        chunk_stats st;
        memset(&st, 0, sizeof st);
        // In locals (registers): the long classes' sums, indexed by class, are rare.
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        double sum[3] = {0, 0, 0};
        uint32_t live = 0;
        const bpx_soa *s = job->s;
        uint32_t first = (uint32_t)c * CHUNK;
        uint32_t last = first + CHUNK < s->n ? first + CHUNK : s->n;
        for (uint32_t i = first; i < last; i++) {
            // bpx__bvh_copy_chunk's copy, with the box's shape class for key_task in one pass.
            bpx_bvh_box box;
            for (int a = 0; a < 3; a++) {
                box.lo[a] = s->lo[a][i];
                box.hi[a] = s->hi[a][i];
            }
            const bpx_bvh_box *b = &box;
            uint32_t k = box.lo[0] <= box.hi[0] ? (uint32_t)shape_class(b) : 0;
            memcpy(&box.pad[0], &k, sizeof k);
            box.pad[1] = 0.0f;
            job->t->boxes[i] = box;
            if (!(b->lo[0] <= b->hi[0]))
                continue;
            for (int a = 0; a < 3; a++) {
                double m = 0.5 * ((double)b->lo[a] + (double)b->hi[a]);
                lo[a] = m < lo[a] ? m : lo[a];
                hi[a] = m > hi[a] ? m : hi[a];
                sum[a] += (double)b->hi[a] - (double)b->lo[a];
            }
            if (k) {
                for (int a = 0; a < 3; a++)
                    st.extent[k][a] += (double)b->hi[a] - (double)b->lo[a];
                st.count[k]++;
            }
            live++;
        }
        // Class 0: what the long classes leave.
        st.count[0] = live - st.count[1] - st.count[2] - st.count[3];
        for (int a = 0; a < 3; a++) {
            st.lo[a] = lo[a];
            st.hi[a] = hi[a];
            st.extent[0][a] = sum[a] - st.extent[1][a] - st.extent[2][a] - st.extent[3][a];
        }
        st.live = live;
        job->stats[c] = st;
    }
}

// The order of the key's bits, highest first: each bit halves the cell on the axis whose
// halving takes the most area off the cell grown by the mean box (cell c, grown d = c + e:
// halving c_a takes c_a / 2 * (d_b + d_c)); 10 bits an axis, 30 in all. The extents weigh
// EXTENT_WEIGHT times: cells then come out as long as their boxes sooner (long boxes: 20% fewer
// nodes a ray than at weight 1, the same from 8 to 64; cube-like boxes: the same order).
enum { EXTENT_WEIGHT = 16 };
typedef struct bit_order {
    double c[3];      // the cell's sides so far
    int taken[3];     // bits of each axis placed
    int place[3][10]; // key bit of each axis's bit (9: the highest)
} bit_order;

static void order_bits(bit_order *o, const double extent[3], int bit, int count)
{
    for (; count > 0; count--, bit--) {
        int best = -1;
        double most = -1.0;
        for (int a = 0; a < 3; a++) {
            double gain = o->c[a] * (o->c[(a + 1) % 3] + o->c[(a + 2) % 3] +
                                     EXTENT_WEIGHT * (extent[(a + 1) % 3] + extent[(a + 2) % 3]));
            if (o->taken[a] < 10 && gain > most)
                best = a, most = gain;
        }
        o->place[best][9 - o->taken[best]++] = bit;
        o->c[best] *= 0.5;
    }
}

static void order_tables(const bit_order *o, uint32_t bits[3][2][32])
{
    for (int a = 0; a < 3; a++)
        for (int half = 0; half < 2; half++)
            for (uint32_t v = 0; v < 32; v++) {
                uint32_t key = 0;
                for (int j = 0; j < 5; j++)
                    key |= ((v >> j) & 1u) << o->place[a][5 * half + j];
                bits[a][half][v] = key;
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
            uint32_t k;
            memcpy(&k, &b->pad[0], sizeof k); // stats_task's shape_class
            uint32_t sub = job->class_of[k];
            uint32_t key = sub << job->class_shift;
            for (int a = 0; a < 3; a++) {
                double m = 0.5 * ((double)b->lo[a] + (double)b->hi[a]);
                uint32_t q = (uint32_t)((m - job->lo[a]) * job->scale[a]) & 1023;
                key |= job->bits[sub][a][0][q & 31] | job->bits[sub][a][1][q >> 5];
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
    double extent[CLASSES][3] = {{0}};
    uint32_t count[CLASSES] = {0};
    uint32_t m = 0;
    for (uint32_t c = 0; c < chunks; c++) {
        chunk_stats *st = &job.stats[c];
        for (int a = 0; a < 3; a++) {
            lo[a] = st->lo[a] < lo[a] ? st->lo[a] : lo[a];
            hi[a] = st->hi[a] > hi[a] ? st->hi[a] : hi[a];
        }
        for (int k = 0; k < CLASSES; k++) {
            count[k] += st->count[k];
            for (int a = 0; a < 3; a++)
                extent[k][a] += st->extent[k][a];
        }
        st->first = m;
        m += st->live;
    }
    if (!m)
        return 0;
    // A class too small for a subtree of its own joins the cube-like boxes (subtree 0). With
    // one subtree in all, the key's top bits are the same for every box: no split.
    for (int k = 1; k < CLASSES; k++)
        if (count[k] < m / 8) {
            count[0] += count[k];
            count[k] = 0;
            for (int a = 0; a < 3; a++)
                extent[0][a] += extent[k][a];
        }
    // The subtrees split off below the top bits (every shape in the same order), once the
    // cells are about twice as long as the long boxes: a ray then walks each shape's subtree
    // only near its path (split at the root, rays walked three trees over the whole world:
    // 35% more nodes at 1M boxes).
    bit_order top;
    memset(&top, 0, sizeof top);
    double all[3] = {0, 0, 0}, longest = 0.0;
    int subtrees = 0;
    for (int k = 0; k < CLASSES; k++) {
        subtrees += count[k] > 0;
        for (int a = 0; a < 3; a++)
            all[a] += extent[k][a] / m;
        if (k && count[k])
            longest = extent[k][k - 1] / count[k] > longest ? extent[k][k - 1] / count[k] : longest;
    }
    for (int a = 0; a < 3; a++) {
        job.lo[a] = lo[a];
        top.c[a] = hi[a] > lo[a] ? hi[a] - lo[a] : 0.0;
        job.scale[a] = top.c[a] > 0.0 ? 1023.0 / top.c[a] : 0.0;
    }
    int top_bits = 0;
    while (subtrees > 1 && top_bits < 30 &&
           fmax(top.c[0], fmax(top.c[1], top.c[2])) > 2.0 * longest)
        order_bits(&top, all, 31 - top_bits++, 1);
    job.class_shift = 30 - top_bits;
    for (int k = 0; k < CLASSES; k++) {
        job.class_of[k] = count[k] ? (uint8_t)k : 0;
        if (!count[k])
            continue;
        double mean[3];
        for (int a = 0; a < 3; a++)
            mean[a] = extent[k][a] / count[k];
        bit_order own = top;
        order_bits(&own, mean, 29 - top_bits, 30 - top_bits);
        order_tables(&own, job.bits[k]);
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
