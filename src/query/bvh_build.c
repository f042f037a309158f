// The tree's build on the world's workers: Morton keys of the live boxes' centres, a stable
// radix sort, the top levels split on the calling thread, the subtrees below them as tasks.
// Every step works on fixed chunks of items or on subtrees fixed by the keys, never on one per
// worker, and joins them in a fixed order, so the tree is the same bytes for any worker count.
#include <math.h>
#include <string.h>

#include "bvh.h"
#include "core/alloc.h"

#define CHUNK BPX_BVH_CHUNK
/// Boxes in a subtree built by one task: enough to amortise handing it out, few enough that a
/// million boxes make hundreds of tasks to balance.
#define TASK_ITEMS 4096u

enum { RADIX_BITS = 11, BUCKETS = 1 << RADIX_BITS };

#define run bpx__bvh_run
#define chunks_of bpx__bvh_chunks
#define live bpx__bvh_live

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

// The live boxes' (key << 32 | id) words into t->words; returns how many.
static uint32_t make_keys(bpx_bvh *t, const bpx_soa *s, const bpx_executor *ex)
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

// Sorts t->words[0, m) (30-bit keys); the result ends in t->words.
static void sort_words(bpx_bvh *t, uint32_t m, const bpx_executor *ex)
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

// ---------------------------------------------------------------------------------------------
// Nodes. A node over sorted positions [begin, end) gets up to BPX_BVH_WIDTH children: its range
// is split at the highest bit in which its first and last keys differ (equal keys: in the
// middle), then the largest part again, until there are that many parts or only single boxes. A single box is a
// leaf lane; a larger part is a child node.

/// The most nodes a subtree over r >= 2 boxes can take: (W r / 2 - 1) / (W - 1) for width W.
/// A node over r <= W boxes is one node; over more it has W parts, j of them nodes over
/// S <= r - W + j boxes, so by induction 1 + (W S / 2 - j) / (W - 1) <= (W r / 2 - 1) / (W - 1).
static size_t most_nodes(uint32_t r)
{
    const size_t w = BPX_BVH_WIDTH;
    return r < 2 ? 1 : (w / 2 * (size_t)r - 1) / (w - 1);
}

static uint32_t key_at(const uint64_t *words, uint32_t k)
{
    return (uint32_t)(words[k] >> 32);
}

static uint32_t split_at(const uint64_t *words, uint32_t begin, uint32_t end)
{
    uint32_t diff = key_at(words, begin) ^ key_at(words, end - 1);
    if (!diff)
        return begin + (end - begin) / 2;
    uint32_t bit = 1u << (31 - __builtin_clz(diff));
    uint32_t lo = begin, hi = end - 1; // key lo lacks the bit, key hi has it
    while (hi - lo > 1) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (key_at(words, mid) & bit)
            hi = mid;
        else
            lo = mid;
    }
    return hi;
}

// The node's parts: bounds[0..parts] with part k = [bounds[k], bounds[k + 1]).
static int parts_of(const uint64_t *words, uint32_t begin, uint32_t end,
                    uint32_t bounds[BPX_BVH_WIDTH + 1])
{
    int parts = 1;
    bounds[0] = begin;
    bounds[1] = end;
    while (parts < BPX_BVH_WIDTH) {
        int largest = 0;
        for (int k = 1; k < parts; k++)
            if (bounds[k + 1] - bounds[k] > bounds[largest + 1] - bounds[largest])
                largest = k;
        if (bounds[largest + 1] - bounds[largest] < 2)
            break;
        uint32_t split = split_at(words, bounds[largest], bounds[largest + 1]);
        memmove(&bounds[largest + 2], &bounds[largest + 1],
                sizeof(uint32_t) * (size_t)(parts - largest));
        bounds[largest + 1] = split;
        parts++;
    }
    return parts;
}

static void clear_lanes(bpx_bvh_node *node)
{
    for (int a = 0; a < 3; a++)
        for (int k = 0; k < BPX_BVH_WIDTH; k++) {
            node->lo[a][k] = INFINITY;
            node->hi[a][k] = -INFINITY;
        }
    memset(node->child, 0, sizeof node->child);
    node->leaves = 0;
    node->lanes = 0;
}

static void set_lane(bpx_bvh_node *node, int k, const float lo[3], const float hi[3])
{
    for (int a = 0; a < 3; a++) {
        node->lo[a][k] = lo[a];
        node->hi[a][k] = hi[a];
    }
}

/// The union of a node's lanes.
void bpx__bvh_node_bounds(const bpx_bvh_node *node, float lo[3], float hi[3])
{
    for (int a = 0; a < 3; a++) {
        float l = node->lo[a][0], h = node->hi[a][0];
        for (uint32_t k = 1; k < node->lanes; k++) {
            l = node->lo[a][k] < l ? node->lo[a][k] : l;
            h = node->hi[a][k] > h ? node->hi[a][k] : h;
        }
        lo[a] = l;
        hi[a] = h;
    }
}

double bpx__bvh_area(const float lo[3], const float hi[3])
{
    double e[3];
    for (int a = 0; a < 3; a++)
        e[a] = (double)hi[a] - (double)lo[a];
    return e[0] * e[1] + e[1] * e[2] + e[2] * e[0];
}

/// How many sorted positions ahead a leaf lane fetches its box: ids in Morton order lie all
/// over the world's arrays, so each read would miss the caches; fetched early, they overlap.
#define PREFETCH 16

// Lane k of node: the box at sorted position at.
static void leaf_lane(const bpx_bvh *t, bpx_bvh_node *node, int k, uint32_t at)
{
    if (at + PREFETCH < t->item_count)
        __builtin_prefetch(&t->boxes[(uint32_t)t->words[at + PREFETCH]]);
    uint32_t id = (uint32_t)t->words[at];
    const bpx_bvh_box *b = &t->boxes[id];
    for (int a = 0; a < 3; a++) {
        node->lo[a][k] = b->lo[a];
        node->hi[a][k] = b->hi[a];
    }
    node->child[k] = id;
    node->leaves |= 1u << k;
}

typedef struct subtree {
    bpx_bvh *t;
    uint32_t next; // the next free node
    double area;   // of the nodes built
} subtree;

// Builds the node over [begin, end) at st->next and its children after it, depth first.
static uint32_t build_node(subtree *st, uint32_t begin, uint32_t end)
{
    bpx_bvh *t = st->t;
    uint32_t index = st->next++;
    uint32_t bounds[BPX_BVH_WIDTH + 1];
    int parts = parts_of(t->words, begin, end, bounds);
    bpx_bvh_node *node = &t->nodes[index];
    clear_lanes(node);
    node->lanes = (uint32_t)parts;
    for (int k = 0; k < parts; k++) {
        if (bounds[k + 1] - bounds[k] == 1) {
            leaf_lane(t, node, k, bounds[k]);
            continue;
        }
        uint32_t child = build_node(st, bounds[k], bounds[k + 1]);
        float lo[3], hi[3];
        bpx__bvh_node_bounds(&t->nodes[child], lo, hi);
        set_lane(node, k, lo, hi);
        t->nodes[index].child[k] = child;
    }
    float lo[3], hi[3];
    bpx__bvh_node_bounds(node, lo, hi);
    st->area += bpx__bvh_area(lo, hi);
    return index;
}

static void subtree_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    bpx_bvh *t = context;
    for (int b = begin; b < end; b++) {
        bpx_bvh_block *block = &t->blocks[b + 1]; // block 0 holds the top levels
        subtree st = {t, block->first, 0.0};
        build_node(&st, block->begin, block->end);
        block->count = st.next - block->first;
        block->area = st.area;
    }
}

static bool grow_blocks(bpx_bvh *t)
{
    uint32_t cap = 2 * t->block_capacity + 16;
    void *memory = t->blocks;
    if (!bpx__grow(&memory, sizeof(bpx_bvh_block) * t->block_capacity, sizeof(bpx_bvh_block) * cap))
        return false;
    t->blocks = memory;
    t->block_capacity = cap;
    return true;
}

// The top levels: the root and the nodes over more than TASK_ITEMS boxes, built here, in depth
// first order from node 0; their node lanes' bounds are left for later. The parts of at most
// TASK_ITEMS boxes (more than one) become blocks.
static bool build_top(bpx_bvh *t, uint32_t begin, uint32_t end, uint32_t parent, uint32_t lane)
{
    if (parent != UINT32_MAX && end - begin <= TASK_ITEMS) {
        if (t->block_count == t->block_capacity && !grow_blocks(t))
            return false;
        t->blocks[t->block_count++] = (bpx_bvh_block){0, 0, begin, end, parent, lane, 0.0};
        return true;
    }
    uint32_t index = t->blocks[0].count++;
    if (parent != UINT32_MAX)
        t->nodes[parent].child[lane] = index;
    uint32_t bounds[BPX_BVH_WIDTH + 1];
    int parts = parts_of(t->words, begin, end, bounds);
    clear_lanes(&t->nodes[index]);
    t->nodes[index].lanes = (uint32_t)parts;
    for (int k = 0; k < parts; k++) {
        if (bounds[k + 1] - bounds[k] == 1)
            leaf_lane(t, &t->nodes[index], k, bounds[k]);
        else if (!build_top(t, bounds[k], bounds[k + 1], index, (uint32_t)k))
            return false;
    }
    return true;
}

size_t bpx__bvh_most_nodes(uint32_t m)
{
    return most_nodes(m);
}

size_t bpx__bvh_count_words(uint32_t n)
{
    size_t stats = sizeof(chunk_stats) / sizeof(uint32_t) * chunks_of(n);
    size_t radix = (size_t)BUCKETS * chunks_of(n);
    return stats > radix ? stats : radix;
}

// ---------------------------------------------------------------------------------------------

bool bpx__bvh_rebuild(bpx_bvh *t, const bpx_soa *s, const bpx_executor *ex)
{
    uint32_t m = make_keys(t, s, ex);
    sort_words(t, m, ex);
    t->item_count = m;
    t->node_count = 0;
    t->block_count = 0;
    if (!m)
        return true;
    if (!t->block_capacity && !grow_blocks(t))
        return false;
    t->blocks[0] = (bpx_bvh_block){0, 0, 0, m, UINT32_MAX, 0, 0.0};
    t->block_count = 1;
    if (!build_top(t, 0, m, UINT32_MAX, 0))
        return false;
    // The blocks after the top nodes, each with room for its worst case: their places depend
    // on the keys alone.
    size_t at = t->blocks[0].count;
    for (uint32_t b = 1; b < t->block_count; b++) {
        bpx_bvh_block *block = &t->blocks[b];
        block->first = (uint32_t)at;
        t->nodes[block->parent].child[block->lane] = block->first;
        at += most_nodes(block->end - block->begin);
    }
    run(ex, subtree_task, t->block_count - 1, m, t);
    bpx__bvh_top_refit(t);
    t->node_count = 0;
    for (uint32_t b = 0; b < t->block_count; b++)
        t->node_count += t->blocks[b].count;
    return true;
}
