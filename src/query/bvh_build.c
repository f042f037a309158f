// The tree's nodes on the world's workers: the top levels split on the calling thread, the
// subtrees below them as tasks, each planned first so that it gets exactly its room. Subtrees
// are fixed by the keys, never by the workers, so the tree is the same bytes for any count.
#include <math.h>
#include <string.h>

#include "bvh.h"
#include "core/alloc.h"

/// Boxes in a subtree built by one task: enough to amortise handing it out, few enough that a
/// million boxes make hundreds of tasks to balance.
#define TASK_ITEMS 4096u

#define run bpx__bvh_run

// ---------------------------------------------------------------------------------------------
// Nodes. A node over sorted positions [begin, end) has up to BPX_BVH_WIDTH (W) parts: its range
// is split at the highest bit in which its first and last keys differ (equal keys: in the
// middle), then the largest part again, while there are fewer than W parts and one holds more
// than W boxes. A part of one box is a leaf lane; a larger one a child node, unless the node
// has lanes to spare for all its boxes (then they are leaf lanes here: a node over at most W
// boxes holds them all, and nodes are fuller, a third fewer than from splitting to the end).

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
        if (bounds[largest + 1] - bounds[largest] <= BPX_BVH_WIDTH)
            break;
        uint32_t split = split_at(words, bounds[largest], bounds[largest + 1]);
        memmove(&bounds[largest + 2], &bounds[largest + 1],
                sizeof(uint32_t) * (size_t)(parts - largest));
        bounds[largest + 1] = split;
        parts++;
    }
    // Spare lanes take the boxes of the smallest part that fits in them, one box a lane.
    for (;;) {
        int smallest = -1;
        for (int k = 0; k < parts; k++) {
            uint32_t r = bounds[k + 1] - bounds[k];
            if (r >= 2 && r - 1 <= (uint32_t)(BPX_BVH_WIDTH - parts) &&
                (smallest < 0 || r < bounds[smallest + 1] - bounds[smallest]))
                smallest = k;
        }
        if (smallest < 0)
            return parts;
        uint32_t first = bounds[smallest], r = bounds[smallest + 1] - first;
        memmove(&bounds[smallest + r], &bounds[smallest + 1],
                sizeof(uint32_t) * (size_t)(parts - smallest));
        for (uint32_t j = 1; j < r; j++)
            bounds[smallest + j] = first + j;
        parts += (int)(r - 1);
    }
}

// Plans the subtree over [begin, end): per node, depth first, its number of parts and the
// bounds between them, at *plan; returns its nodes. The parts' sum over nodes is the nodes
// plus the boxes less one, so a subtree's plan fits in two words a box (its boxes' slots of
// the sort's spare array).
static uint32_t plan_nodes(const uint64_t *words, uint32_t begin, uint32_t end, uint32_t **plan)
{
    uint32_t bounds[BPX_BVH_WIDTH + 1], count = 1;
    int parts = parts_of(words, begin, end, bounds);
    uint32_t *at = *plan;
    at[0] = (uint32_t)parts;
    memcpy(at + 1, bounds + 1, sizeof(uint32_t) * (size_t)(parts - 1));
    *plan = at + parts;
    for (int k = 0; k < parts; k++)
        if (bounds[k + 1] - bounds[k] > 1)
            count += plan_nodes(words, bounds[k], bounds[k + 1], plan);
    return count;
}

static uint32_t *plan_of(const bpx_bvh *t, const bpx_bvh_block *block)
{
    return (uint32_t *)(void *)(t->words_scratch + block->begin);
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
    const uint32_t *plan; // the next node's plan
    uint32_t next;        // the next free node
    double area;          // of the nodes built
} subtree;

// Builds the node over [begin, end) at st->next and its children after it, depth first, as
// planned.
static uint32_t build_node(subtree *st, uint32_t begin, uint32_t end)
{
    bpx_bvh *t = st->t;
    uint32_t index = st->next++;
    uint32_t bounds[BPX_BVH_WIDTH + 1];
    int parts = (int)*st->plan;
    bounds[0] = begin;
    memcpy(bounds + 1, st->plan + 1, sizeof(uint32_t) * (size_t)(parts - 1));
    bounds[parts] = end;
    st->plan += parts;
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

static void plan_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    bpx_bvh *t = context;
    for (int b = begin; b < end; b++) {
        bpx_bvh_block *block = &t->blocks[b + 1]; // block 0 holds the top levels
        uint32_t *plan = plan_of(t, block);
        block->count = plan_nodes(t->words, block->begin, block->end, &plan);
    }
}

static void subtree_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    bpx_bvh *t = context;
    for (int b = begin; b < end; b++) {
        bpx_bvh_block *block = &t->blocks[b + 1];
        subtree st = {t, plan_of(t, block), block->first, 0.0};
        build_node(&st, block->begin, block->end);
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

bool bpx__bvh_rebuild(bpx_bvh *t, const bpx_soa *s, const bpx_executor *ex)
{
    uint32_t m = bpx__bvh_keys(t, s, ex);
    bpx__bvh_sort(t, m, ex);
    t->item_count = m;
    t->node_count = 0;
    t->block_count = 0;
    if (!m)
        return true;
    // Top nodes each cover more than TASK_ITEMS boxes, disjoint at each of at most 64 levels.
    if (!t->block_capacity && !grow_blocks(t))
        return false;
    if (!bpx__bvh_reserve_nodes(t, m / (TASK_ITEMS / BPX_BVH_MAX_DEPTH) + 2, 0))
        return false;
    t->blocks[0] = (bpx_bvh_block){0, 0, 0, m, UINT32_MAX, 0, 0.0};
    t->block_count = 1;
    if (!build_top(t, 0, m, UINT32_MAX, 0))
        return false;
    // The blocks after the top nodes, in order, each where the ones before it end: their
    // places depend on the keys alone.
    run(ex, plan_task, t->block_count - 1, m, t);
    size_t at = t->blocks[0].count;
    for (uint32_t b = 1; b < t->block_count; b++) {
        t->blocks[b].first = (uint32_t)at;
        at += t->blocks[b].count;
    }
    if (!bpx__bvh_reserve_nodes(t, at, t->blocks[0].count))
        return false;
    for (uint32_t b = 1; b < t->block_count; b++)
        t->nodes[t->blocks[b].parent].child[t->blocks[b].lane] = t->blocks[b].first;
    run(ex, subtree_task, t->block_count - 1, m, t);
    bpx__bvh_top_refit(t);
    t->node_count = (uint32_t)at;
    return true;
}
