// The walks of the tree, once per instruction set: a file defines the three lane tests below
// and BPX_TRAVERSE (its entry's name), then includes this one (traverse_scalar.c,
// traverse_avx2.c, traverse_avx512.c). Every lane test computes a lane's answer with the very
// operations of the header's definitions (in double, in the same order), so every build and width
// gives the same bits; a node's lanes hold its children's bounds, and a leaf lane is a box, so the
// lane test of a leaf is the box's own test.
//
//   uint32_t lanes_box(node, p)     lanes whose box overlaps the region (closed intervals)
//   uint32_t lanes_sphere(node, p)  lanes within the sphere
//   uint32_t lanes_cast(node, p, limit, enter[W])
//                                   lanes the ray or sweep hits, at enter[k] = the fraction
//                                   (rounded to float), no later than limit
#pragma once

#include "query_prep.h"

enum { STACK = BPX_BVH_WIDTH * (BPX_BVH_MAX_DEPTH + 1) };

// -DBPX_COUNT_VISITS (a measuring build, never a release): nodes the closest casts enter, a
// noise-free measure of a tree's quality (bpx_querybench prints it per ray, one thread).
#ifdef BPX_COUNT_VISITS
extern uint64_t bpx__visits;
#define COUNT_VISIT() (bpx__visits++)
#else
#define COUNT_VISIT() ((void)0)
#endif

// A walk waits on memory (a node's lanes decide where it goes next): the nodes it will visit
// later start loading now, so their cache misses overlap.
static inline void prefetch_node(const bpx_bvh *t, uint32_t index)
{
    const char *node = (const char *)&t->nodes[index];
    for (size_t line = 0; line < sizeof(bpx_bvh_node); line += 64)
        __builtin_prefetch(node + line);
}

// A closest cast in a tree larger than the caches waits on each node it enters (the nearest
// child is entered at once, so its lines are not fetched ahead like the pushed ones'): on
// entering a node, every child node's lines start loading while its lanes are tested, so the
// next node is on its way before the test says which one it is. Measured on long_any at 100k
// boxes (27 nodes a ray), a quarter off a ray; in a tree that fits in the core's caches
// (1,000 nodes), the prefetches cost 8%, hence the size.
enum { SPECULATE_NODES = 4096 }; // 1 MiB of nodes
static inline void prefetch_children(const bpx_bvh *t, const bpx_bvh_node *node)
{
    uint32_t inner = ~node->leaves & ((1u << node->lanes) - 1u);
    for (; inner; inner &= inner - 1)
        prefetch_node(t, node->child[__builtin_ctz(inner)]);
}

// What a walk does with a hit it found (and may see): a callback's say, or the hit stored. A
// fixed list (the caller's memory) counts the hits past its end without storing them.
enum { GO_ON, STOP, FAIL };

static inline int take_hit(const bpx_query_view *v, const bpx_prepared *p, bpx_hit h,
                           float *limit, bpx_hit_list *out)
{
    if (p->visit) {
        float say = p->visit(&h, v->user_data ? v->user_data[h.id] : 0, p->visit_context);
        if (say == 0.0f)
            return STOP;
        if (say > 0.0f && say < *limit)
            *limit = say;
        return GO_ON;
    }
    if (out->count < out->capacity || bpx__hits_reserve(out, 1))
        out->hits[out->count] = h;
    else if (!out->fixed)
        return FAIL;
    out->count++;
    return p->any ? STOP : GO_ON;
}

// BOX and SPHERE: every box the region touches, by id.
static bool region(const bpx_query_view *v, const bpx_prepared *p, bpx_hit_list *out)
{
    const bpx_bvh *t = v->tree;
    size_t first = out->count;
    bool sphere = p->kind == BPX_QUERY_SPHERE;
    float limit = INFINITY; // a region has no end to clip
    uint32_t stack[STACK];
    int top = 0;
    if (t->node_count)
        stack[top++] = 0;
    while (top) {
        const bpx_bvh_node *node = &t->nodes[stack[--top]];
        uint32_t hit = sphere ? lanes_sphere(node, p) : lanes_box(node, p);
        for (uint32_t leaves = hit & node->leaves; leaves; leaves &= leaves - 1) {
            int k = __builtin_ctz(leaves);
            uint32_t id = node->child[k];
            if (!bpx__query_seen(v, p, id))
                continue;
            if (p->kind == BPX_QUERY_ORIENTED) { // a leaf lane is the box itself
                const float lo[3] = {node->lo[0][k], node->lo[1][k], node->lo[2][k]};
                const float hi[3] = {node->hi[0][k], node->hi[1][k], node->hi[2][k]};
                if (!bpx__oriented_hits(p, lo, hi))
                    continue;
            }
            int step = take_hit(v, p, (bpx_hit){id, 0.0f}, &limit, out);
            if (step == FAIL) {
                out->count = first;
                return false;
            }
            if (step == STOP)
                return true;
        }
        for (uint32_t inner = hit & ~node->leaves; inner; inner &= inner - 1) {
            prefetch_node(t, node->child[__builtin_ctz(inner)]);
            stack[top++] = node->child[__builtin_ctz(inner)];
        }
    }
    if (!p->visit)
        bpx__hits_sort(out, first, false);
    return true;
}

// RAY and SWEEP, every hit, by fraction then id (or each to the callback, which may clip the
// cast: nothing entering after `limit` is looked at again).
static bool cast_all(const bpx_query_view *v, const bpx_prepared *p, bpx_hit_list *out)
{
    const bpx_bvh *t = v->tree;
    size_t first = out->count;
    float limit = INFINITY;
    uint32_t stack[STACK];
    int top = 0;
    if (t->node_count)
        stack[top++] = 0;
    float enter[BPX_BVH_WIDTH];
    while (top) {
        const bpx_bvh_node *node = &t->nodes[stack[--top]];
        uint32_t hit = lanes_cast(node, p, limit, enter);
        for (uint32_t leaves = hit & node->leaves; leaves; leaves &= leaves - 1) {
            int k = __builtin_ctz(leaves);
            if (enter[k] > limit || !bpx__query_seen(v, p, node->child[k]))
                continue;
            int step = take_hit(v, p, (bpx_hit){node->child[k], enter[k]}, &limit, out);
            if (step == FAIL) {
                out->count = first;
                return false;
            }
            if (step == STOP)
                return true;
        }
        for (uint32_t inner = hit & ~node->leaves; inner; inner &= inner - 1) {
            int k = __builtin_ctz(inner);
            if (enter[k] > limit)
                continue;
            prefetch_node(t, node->child[k]);
            stack[top++] = node->child[k];
        }
    }
    if (!p->visit)
        bpx__hits_sort(out, first, true);
    return true;
}

// RAY and SWEEP, the closest hit: nearer children first, and nothing entered after the best so
// far. Fractions compare as the floats reported, so a tie at the reported fraction still looks
// for a lower id.
static bool cast_closest(const bpx_query_view *v, const bpx_prepared *p, bpx_hit_list *out)
{
    const bpx_bvh *t = v->tree;
    bpx_hit best = {UINT32_MAX, INFINITY};
    typedef struct entry {
        uint32_t node;
        float enter; // where the cast enters the node, as a reported fraction would round
    } entry;
    entry stack[STACK];
    int top = 0;
    if (t->node_count)
        stack[top++] = (entry){0, 0.0f};
    float enter[BPX_BVH_WIDTH];
    const bool speculate = t->node_count > SPECULATE_NODES;
    while (top) {
        top--;
        if (stack[top].enter > best.fraction)
            continue;
        uint32_t index = stack[top].node;
        for (;;) {
            const bpx_bvh_node *node = &t->nodes[index];
            COUNT_VISIT();
            if (speculate)
                prefetch_children(t, node);
            uint32_t hit = lanes_cast(node, p, best.fraction, enter);
            for (uint32_t leaves = hit & node->leaves; leaves; leaves &= leaves - 1) {
                int k = __builtin_ctz(leaves);
                bpx_hit h = {node->child[k], enter[k]};
                if ((h.fraction < best.fraction ||
                     (h.fraction == best.fraction && h.id < best.id)) &&
                    bpx__query_seen(v, p, h.id))
                    best = h;
            }
            // The children still in reach, farthest first; the nearest is entered next, right
            // away (as if pushed last and popped), the others pushed.
            entry near[BPX_BVH_WIDTH];
            int count = 0;
            for (uint32_t inner = hit & ~node->leaves; inner; inner &= inner - 1) {
                int k = __builtin_ctz(inner);
                if (enter[k] > best.fraction)
                    continue;
                entry e = {node->child[k], enter[k]};
                int at = count++;
                for (; at > 0 && near[at - 1].enter < e.enter; at--)
                    near[at] = near[at - 1];
                near[at] = e;
            }
            if (!count)
                break;
            for (int k = 0; k + 1 < count; k++) {
                prefetch_node(t, near[k].node);
                stack[top++] = near[k];
            }
            index = near[count - 1].node;
        }
    }
    if (best.id == UINT32_MAX)
        return true;
    float limit = INFINITY;
    return take_hit(v, p, best, &limit, out) != FAIL;
}


bool BPX_TRAVERSE(const bpx_query_view *view, const bpx_prepared *p, bpx_hit_list *out)
{
    switch (p->kind) {
    case BPX_QUERY_BOX:
    case BPX_QUERY_SPHERE:
    case BPX_QUERY_ORIENTED:
        return region(view, p, out);
    default:
#ifdef BPX_CAST_CLOSEST_FAST
        if (p->closest && !p->visit && p->all_moving)
            return BPX_CAST_CLOSEST_FAST(view, p, out);
#endif
        return p->closest && !p->visit ? cast_closest(view, p, out) : cast_all(view, p, out);
    }
}
