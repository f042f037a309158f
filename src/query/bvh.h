// The queries' tree: an 8-wide bounding volume hierarchy over the world's live boxes, built in
// Morton order (a linear BVH) on the world's workers, and refitted while the same objects only
// move.
#pragma once

#include "core/world.h"

/// Children per node. A child lane is either another node or one box (a leaf lane): a box's
/// bounds sit in its parent, so testing a node's lanes tests its boxes, exactly. 8 lanes: a
/// third fewer nodes per ray than 4 (the walk waits on each node's memory), one AVX-512 vector
/// of doubles or two AVX2 ones.
#ifndef BPX_BVH_WIDTH
#define BPX_BVH_WIDTH 8
#endif
/// Deepest tree: 32 key bits split by bit, then equal keys halved (32 times at most); every
/// level of nodes takes at least one of those binary splits.
#define BPX_BVH_MAX_DEPTH 64

/// A node, 256 bytes (four cache lines), its children's bounds by axis and lane so that one
/// vector holds an axis of all of them. Unused lanes hold +inf .. -inf, which every test
/// rejects.
typedef struct bpx_bvh_node {
    _Alignas(64) float lo[3][BPX_BVH_WIDTH];
    float hi[3][BPX_BVH_WIDTH];
    uint32_t child[BPX_BVH_WIDTH]; ///< a node's index, or for a leaf lane the box's id
    uint32_t leaves;               ///< bit k: lane k is a box
    uint32_t lanes;                ///< lanes in use: the first `lanes`
} bpx_bvh_node;

/// A box in one 32-byte record: a read at a random id costs one cache line, not six.
typedef struct bpx_bvh_box {
    float lo[3], hi[3];
    float pad[2]; ///< pad[0]: the build's shape class of the box (bvh_keys.c)
} bpx_bvh_box;

/// A run of nodes built by one task: a subtree below the top levels, or the top levels. The
/// blocks lie one after another in block order, each in depth-first order.
typedef struct bpx_bvh_block {
    uint32_t first; ///< its first node (the subtree's root)
    uint32_t count; ///< nodes it holds
    uint32_t begin; ///< its boxes: positions [begin, end) of the sorted order
    uint32_t end;
    uint32_t parent; ///< the top node whose lane points at the root (UINT32_MAX: none)
    uint32_t lane;
    double area; ///< its nodes' total surface area (looseness)
} bpx_bvh_block;

typedef struct bpx_bvh {
    bpx_bvh_node *nodes; ///< the blocks' nodes
    size_t node_capacity;
    uint32_t item_count; ///< live boxes in the tree

    // Subtrees: block 0 holds the top levels (node 0 the root), the others one subtree each.
    bpx_bvh_block *blocks;
    uint32_t block_count;
    uint32_t block_capacity;

    // Build scratch: (key << 32 | id) words, twice for the radix sort; the world's boxes
    // by id, one cache line each, for the leaf lanes' reads in Morton order (scattered ids).
    uint64_t *words;
    uint64_t *words_scratch;
    bpx_bvh_box *boxes;
    uint32_t item_capacity;
    uint32_t *counts; ///< radix counts, one row of buckets per chunk; chunk sums
    size_t count_capacity;

    bool valid;       // matches the world's boxes of `version`
    uint64_t version; // the world's boxes_version it was made from
    uint32_t world_n; // the world's n then
    double looseness; // nodes' area over the root's, at the last build
    uint64_t builds, refits, last_update_ns;
    uint32_t node_count; ///< nodes in use, over all blocks
} bpx_bvh;

/// Brings the tree up to date with the world's current boxes: a refit when the same ids are
/// live and the tree stays tight, else a rebuild, on the world's workers. The tree is the same
/// for every worker count. Returns OUT_OF_MEMORY and leaves the tree invalid (never wrong) when
/// memory runs out.
bpx_status bpx__bvh_update(bpx_bvh *tree, const bpx_world *world);

void bpx__bvh_free(bpx_bvh *tree);

// Between bvh.c, bvh_keys.c and bvh_build.c.

/// Items per chunk of the parallel passes (copies, keys, sort, live counts).
#define BPX_BVH_CHUNK (1u << 15)
/// Below this many items of work the passes run on the calling thread (same result).
#define BPX_BVH_PARALLEL_ITEMS (2u * BPX_BVH_CHUNK)

/// Runs task over [0, items) on the workers, or here when `work` (items of data) is small.
static inline void bpx__bvh_run(const bpx_executor *ex, bpx_task_fn *task, uint32_t items,
                                uint32_t work, void *context)
{
    if (work >= BPX_BVH_PARALLEL_ITEMS && items > 1)
        bpx__parallel_for(ex, task, (int)items, context);
    else if (items)
        task(0, (int)items, 0, context);
}

static inline uint32_t bpx__bvh_chunks(uint32_t n)
{
    return (n + BPX_BVH_CHUNK - 1) / BPX_BVH_CHUNK;
}

static inline bool bpx__bvh_live(const bpx_soa *s, uint32_t i)
{
    return s->lo[0][i] <= s->hi[0][i]; // removed ids hold inert boxes: +inf .. -inf
}

/// Copies chunk c of the world's boxes into t->boxes; returns how many of them are live.
static inline uint32_t bpx__bvh_copy_chunk(bpx_bvh *t, const bpx_soa *s, uint32_t c)
{
    uint32_t first = c * BPX_BVH_CHUNK, count = 0;
    uint32_t last = first + BPX_BVH_CHUNK < s->n ? first + BPX_BVH_CHUNK : s->n;
    for (uint32_t i = first; i < last; i++) {
        bpx_bvh_box *b = &t->boxes[i];
        for (int a = 0; a < 3; a++) {
            b->lo[a] = s->lo[a][i];
            b->hi[a] = s->hi[a][i];
        }
        count += b->lo[0] <= b->hi[0];
    }
    return count;
}

/// Rebuilds the tree over the live boxes of s: false when memory ran out.
bool bpx__bvh_rebuild(bpx_bvh *t, const bpx_soa *s, const bpx_executor *executor);
/// The top block's node lanes from their children, in reverse (children after parents).
void bpx__bvh_top_refit(bpx_bvh *t);
/// Room for count nodes, keeping the first `keep`: false when memory ran out.
bool bpx__bvh_reserve_nodes(bpx_bvh *t, size_t count, size_t keep);
/// The live boxes' (key << 32 | id) words into t->words, and the boxes into t->boxes;
/// returns how many are live.
uint32_t bpx__bvh_keys(bpx_bvh *t, const bpx_soa *s, const bpx_executor *ex);
/// Sorts t->words[0, m) by key, stably; the result ends in t->words.
void bpx__bvh_sort(bpx_bvh *t, uint32_t m, const bpx_executor *ex);
/// The words of radix counts and chunk sums a build over n ids needs.
size_t bpx__bvh_count_words(uint32_t n);
/// The union of a node's lanes, and a box's surface area (half of it).
void bpx__bvh_node_bounds(const bpx_bvh_node *node, float lo[3], float hi[3]);
double bpx__bvh_area(const float lo[3], const float hi[3]);
