#include "bvh.h"

#include <math.h>
#include <string.h>

#include "core/alloc.h"
#include "core/clock.h"
#include "cpu/sort.h"

/// A refitted tree is rebuilt once its inner nodes' area, relative to the root's, grows past
/// this factor of what the last build gave: a looser tree costs every query more.
#define BPX_BVH_REBUILD_LOOSENESS 1.3

static bool live(const bpx_soa *s, uint32_t i)
{
    return s->lo[0][i] <= s->hi[0][i]; // removed ids hold inert boxes: +inf .. -inf
}

// Room for a tree over `items` boxes. A rebuild rewrites everything, so the arrays are
// replaced, not grown: all new or, when memory runs out, all old.
static bool reserve(bpx_bvh *t, uint32_t items)
{
    if (items <= t->item_capacity)
        return true;
    uint32_t cap = items + items / 4 + 16;
    bpx_bvh fresh = *t;
    fresh.nodes = bpx__alloc(sizeof(bpx_bvh_node) * 2 * (size_t)cap);
    fresh.items = bpx__alloc(sizeof(bpx_box) * (size_t)cap);
    fresh.ids = bpx__alloc(sizeof(uint32_t) * (size_t)cap);
    fresh.keys = bpx__alloc(sizeof(uint32_t) * (size_t)cap);
    fresh.scratch = bpx__alloc(sizeof(uint32_t) * 2 * (size_t)cap);
    fresh.node_capacity = 2 * cap;
    fresh.item_capacity = fresh.scratch_capacity = cap;
    bool ok = fresh.nodes && fresh.items && fresh.ids && fresh.keys && fresh.scratch;
    bpx_bvh *drop = ok ? t : &fresh;
    bpx__free(drop->nodes, sizeof(bpx_bvh_node) * drop->node_capacity);
    bpx__free(drop->items, sizeof(bpx_box) * drop->item_capacity);
    bpx__free(drop->ids, sizeof(uint32_t) * drop->item_capacity);
    bpx__free(drop->keys, sizeof(uint32_t) * drop->scratch_capacity);
    bpx__free(drop->scratch, sizeof(uint32_t) * 2 * (size_t)drop->scratch_capacity);
    if (ok)
        *t = fresh;
    t->valid = false;
    return ok;
}

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

/// Boxes whose largest side passes this many times the mean one go to a subtree of their own
/// (bit 30 of their key): among small boxes a large one would inflate every node above it, the
/// heavy-tailed case (the grid backend keeps its biggest boxes apart for the same reason).
#define BPX_BVH_LARGE_FACTOR 4.0

static double largest_side(const bpx_soa *s, uint32_t i)
{
    double side = 0.0;
    for (int a = 0; a < 3; a++) {
        double e = (double)s->hi[a][i] - (double)s->lo[a][i];
        side = e > side ? e : side;
    }
    return side;
}

// Morton keys of the live boxes' centres in t->keys, their ids in t->ids; returns how many.
// The keys only order the boxes: any rounding here changes the tree's shape, never a result.
static uint32_t morton_keys(bpx_bvh *t, const bpx_soa *s)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double side_sum = 0.0;
    uint32_t live_count = 0;
    for (uint32_t i = 0; i < s->n; i++) {
        if (!live(s, i))
            continue;
        for (int a = 0; a < 3; a++) {
            double c = 0.5 * ((double)s->lo[a][i] + (double)s->hi[a][i]);
            lo[a] = c < lo[a] ? c : lo[a];
            hi[a] = c > hi[a] ? c : hi[a];
        }
        side_sum += largest_side(s, i);
        live_count++;
    }
    double large = live_count ? BPX_BVH_LARGE_FACTOR * side_sum / live_count : INFINITY;
    double scale[3];
    for (int a = 0; a < 3; a++)
        scale[a] = hi[a] > lo[a] ? 1023.0 / (hi[a] - lo[a]) : 0.0;
    uint32_t m = 0;
    for (uint32_t i = 0; i < s->n; i++) {
        if (!live(s, i))
            continue;
        uint32_t key = largest_side(s, i) > large ? 1u << 30 : 0u;
        for (int a = 0; a < 3; a++) {
            double c = 0.5 * ((double)s->lo[a][i] + (double)s->hi[a][i]);
            key |= spread((uint32_t)((c - lo[a]) * scale[a])) << (2 - a);
        }
        t->keys[m] = key;
        t->ids[m] = i;
        m++;
    }
    return m;
}

static void box_union(float lo[3], float hi[3], const float blo[3], const float bhi[3])
{
    for (int a = 0; a < 3; a++) {
        lo[a] = blo[a] < lo[a] ? blo[a] : lo[a];
        hi[a] = bhi[a] > hi[a] ? bhi[a] : hi[a];
    }
}

static void leaf_bounds(bpx_bvh *t, bpx_bvh_node *node)
{
    const bpx_box *b = t->items + node->second;
    memcpy(node->lo, b->min, sizeof node->lo);
    memcpy(node->hi, b->max, sizeof node->hi);
    for (uint32_t k = 1; k < node->count; k++)
        box_union(node->lo, node->hi, b[k].min, b[k].max);
}

static void inner_bounds(bpx_bvh *t, uint32_t index)
{
    bpx_bvh_node *node = &t->nodes[index];
    const bpx_bvh_node *a = &t->nodes[index + 1], *b = &t->nodes[node->second];
    memcpy(node->lo, a->lo, sizeof node->lo);
    memcpy(node->hi, a->hi, sizeof node->hi);
    box_union(node->lo, node->hi, b->lo, b->hi);
}

// Where [begin, end) of the sorted keys splits: at the highest bit in which its first and last
// keys differ, or in the middle when all keys are equal.
static uint32_t split_at(const uint32_t *keys, uint32_t begin, uint32_t end)
{
    uint32_t diff = keys[begin] ^ keys[end - 1];
    if (!diff)
        return begin + (end - begin) / 2;
    uint32_t bit = 1u << (31 - __builtin_clz(diff));
    uint32_t lo = begin, hi = end - 1; // keys[lo] lacks the bit, keys[hi] has it
    while (hi - lo > 1) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (keys[mid] & bit)
            hi = mid;
        else
            lo = mid;
    }
    return hi;
}

static uint32_t build(bpx_bvh *t, uint32_t begin, uint32_t end)
{
    uint32_t index = t->node_count++;
    bpx_bvh_node *node = &t->nodes[index];
    if (end - begin <= BPX_BVH_LEAF) {
        node->second = begin;
        node->count = end - begin;
        leaf_bounds(t, node);
        return index;
    }
    uint32_t split = split_at(t->keys, begin, end);
    build(t, begin, split);
    uint32_t second = build(t, split, end);
    t->nodes[index].second = second;
    t->nodes[index].count = 0;
    inner_bounds(t, index);
    return index;
}

static double area(const float lo[3], const float hi[3])
{
    double e[3];
    for (int a = 0; a < 3; a++)
        e[a] = (double)hi[a] - (double)lo[a];
    return e[0] * e[1] + e[1] * e[2] + e[2] * e[0];
}

// The expected number of inner nodes a ray through the root visits, by the surface area rule.
static double looseness(const bpx_bvh *t)
{
    if (!t->node_count)
        return 0.0;
    double root = area(t->nodes[0].lo, t->nodes[0].hi), sum = 0.0;
    if (!(root > 0.0))
        return 1.0;
    for (uint32_t k = 0; k < t->node_count; k++)
        if (!t->nodes[k].count)
            sum += area(t->nodes[k].lo, t->nodes[k].hi);
    return sum / root;
}

static void gather(bpx_bvh *t, const bpx_soa *s, uint32_t k)
{
    uint32_t i = t->ids[k];
    bpx_box *b = &t->items[k];
    for (int a = 0; a < 3; a++) {
        b->min[a] = s->lo[a][i];
        b->max[a] = s->hi[a][i];
    }
}

static bpx_status rebuild(bpx_bvh *t, const bpx_soa *s)
{
    if (!reserve(t, s->n))
        return BPX_ERR_OUT_OF_MEMORY;
    uint32_t m = morton_keys(t, s);
    // Stable: equal keys keep id order, so the tree depends on the boxes alone.
    bpx__radix_sort(t->keys, t->ids, t->scratch, t->scratch + t->scratch_capacity, m);
    for (uint32_t k = 0; k < m; k++)
        gather(t, s, k);
    t->item_count = m;
    t->node_count = 0;
    if (m)
        build(t, 0, m);
    t->looseness = looseness(t);
    t->builds++;
    return BPX_OK;
}

// The same live ids, moved: new item boxes, then every node's bounds from its children's.
// False when the live ids differ from the tree's (then it must be rebuilt).
static bool refit(bpx_bvh *t, const bpx_soa *s)
{
    if (s->n != t->world_n)
        return false;
    uint32_t live_count = 0;
    for (uint32_t i = 0; i < s->n; i++)
        live_count += live(s, i);
    if (live_count != t->item_count)
        return false;
    for (uint32_t k = 0; k < t->item_count; k++) {
        if (!live(s, t->ids[k]))
            return false; // as many live, but not the same ones
        gather(t, s, k);
    }
    for (uint32_t k = t->node_count; k-- > 0;) {
        if (t->nodes[k].count)
            leaf_bounds(t, &t->nodes[k]);
        else
            inner_bounds(t, k);
    }
    t->refits++;
    return true;
}

bpx_status bpx__bvh_update(bpx_bvh *t, const bpx_world *w)
{
    if (t->valid && t->version == w->boxes_version)
        return BPX_OK;
    uint64_t start = bpx__now_ns();
    bpx_soa s = bpx__world_soa(w);
    bool refitted = t->valid && refit(t, &s);
    if (refitted && looseness(t) > BPX_BVH_REBUILD_LOOSENESS * t->looseness)
        refitted = false;
    t->valid = false;
    if (!refitted) {
        bpx_status status = rebuild(t, &s);
        if (status != BPX_OK)
            return status;
    }
    t->valid = true;
    t->version = w->boxes_version;
    t->world_n = s.n;
    t->last_update_ns = bpx__now_ns() - start;
    return BPX_OK;
}

void bpx__bvh_free(bpx_bvh *t)
{
    bpx__free(t->nodes, sizeof(bpx_bvh_node) * t->node_capacity);
    bpx__free(t->items, sizeof(bpx_box) * t->item_capacity);
    bpx__free(t->ids, sizeof(uint32_t) * t->item_capacity);
    bpx__free(t->keys, sizeof(uint32_t) * t->scratch_capacity);
    bpx__free(t->scratch, sizeof(uint32_t) * 2 * (size_t)t->scratch_capacity);
    memset(t, 0, sizeof *t);
}
