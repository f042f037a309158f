// The tree comparator's per-item steps, for one box, one node or one walk: __host__ __device__,
// so the kernels (kernels.cu), the fake device's (test/fake_cuda/kernels.cu) and the host twin
// in test/test_cuda_twin.cu run the same code; the twin proves the algorithm on machines without
// a GPU. The Morton code and the node build are src/kernels/lbvh_build.h's, the walk
// src/kernels/lbvh_walk.h's, which the opencl backend's program and its twin run too; here the
// refit and the walk work on float bounds, the opencl backend's (src/opencl/kernels/lbvh.h) on
// the boxes' integer keys, with the same rules.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <cstring>

#include "../kernels/lbvh_build.h"
#include "kernels.cuh"

#define BPX_HD __host__ __device__ inline

namespace bpx_tree {

BPX_HD uint32_t bits_of(float f)
{
#ifdef __CUDA_ARCH__
    return __float_as_uint(f);
#else
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
#endif
}

BPX_HD float float_of(uint32_t u)
{
    return BPX_LB_FLOAT(u); // the shared build's bit cast (src/kernels/lbvh_build.h)
}

/// Floats as unsigned keys of the same order, for atomicMin/atomicMax.
BPX_HD uint32_t order_key(float f)
{
    uint32_t u = bits_of(f);
    return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

BPX_HD float order_value(uint32_t k)
{
    return float_of((k & 0x80000000u) ? (k & 0x7fffffffu) : ~k);
}

/// Closed intervals on every axis (Algorithm 1): touching boxes overlap, -0.0 equals 0.0.
BPX_HD bool overlap(float4 alo, float4 ahi, float4 blo, float4 bhi)
{
    return alo.x <= bhi.x && blo.x <= ahi.x && alo.y <= bhi.y && blo.y <= ahi.y &&
           alo.z <= bhi.z && blo.z <= ahi.z;
}

/// Inert boxes (removed ids: min +inf, max -inf) have no centre: they stay out of the scene's
/// bounds, sort last, and their empty bounds never widen a node.
BPX_HD bool live(float lo_x, float hi_x)
{
    return lo_x <= hi_x;
}

BPX_HD void centre(const float lo[3], const float hi[3], float c[3])
{
    for (int a = 0; a < 3; a++)
        c[a] = 0.5f * lo[a] + 0.5f * hi[a]; // halves first: lo + hi can overflow
}

/// The 30-bit Morton code of a centre in the scene's centre bounds (6 order keys): the opencl
/// backend's, from the shared header.
BPX_HD uint32_t morton(const float c[3], const uint32_t scene[6])
{
    return bpx_lbvh_morton(c, scene);
}

/// Karras (2012), "Maximizing parallelism in the construction of BVHs, octrees, and k-d trees":
/// internal node i (of n - 1, root 0) finds its range's other end and its split, independently
/// of every other node, and tells its two children that it is their parent: (i << 1) | side.
/// Equal codes are split by position. The opencl backend's, from the shared header.
BPX_HD void build_node(const uint32_t *keys, int n, int i, uint32_t *leaf_parent,
                       uint32_t *node_parent)
{
    bpx_lbvh_build_node(keys, n, i, leaf_parent, node_parent);
}

/// Bottom-up from leaf t: it writes its box into its parent's slot; the second child to arrive
/// at a node writes the node's union into the node's parent, and so on to the root. `arrive`
/// returns how many children had arrived before (an atomic increment on the device).
// The host twin passes host-only functors: the check belongs to each instantiation's caller.
#pragma nv_exec_check_disable
template <class Arrive>
BPX_HD void refit_leaf(uint32_t t, const float4 *leaf_lo, const float4 *leaf_hi,
                       const uint32_t *leaf_parent, const uint32_t *node_parent,
                       bpx_cuda_node *nodes, Arrive arrive)
{
    float4 lo = leaf_lo[t], hi = leaf_hi[t];
    uint32_t code = t | BPX_CUDA_LEAF;
    uint32_t up = leaf_parent[t];
    for (;;) {
        uint32_t p = up >> 1, side = up & 1;
        nodes[p].lo[side] = make_float4(lo.x, lo.y, lo.z, float_of(code));
        nodes[p].hi[side] = make_float4(hi.x, hi.y, hi.z, 0.0f);
        if (arrive(p) == 0 || p == 0)
            return; // the sibling is not there yet (it carries on), or this was the root
#ifdef __CUDA_ARCH__
        float4 l0 = __ldcg(&nodes[p].lo[0]), l1 = __ldcg(&nodes[p].lo[1]);
        float4 h0 = __ldcg(&nodes[p].hi[0]), h1 = __ldcg(&nodes[p].hi[1]);
#else
        float4 l0 = nodes[p].lo[0], l1 = nodes[p].lo[1], h0 = nodes[p].hi[0], h1 = nodes[p].hi[1];
#endif
        lo = make_float4(fminf(l0.x, l1.x), fminf(l0.y, l1.y), fminf(l0.z, l1.z), 0.0f);
        hi = make_float4(fmaxf(h0.x, h1.x), fmaxf(h0.y, h1.y), fmaxf(h0.z, h1.z), 0.0f);
        code = p;
        up = node_parent[p];
    }
}

static_assert(BPX_CUDA_LEAF == BPX_LBVH_LEAF, "one child-code flag for the refit and the walk");

/// A walk's hit: box `me` and the box at Morton position `at`, emitted as (i, j), i < j.
#pragma nv_exec_check_disable
template <class Emit>
BPX_HD void emit_hit(uint32_t me, uint32_t at, const float4 *leaf_lo, Emit &emit)
{
    uint32_t other = bits_of(leaf_lo[at].w);
    emit(me < other ? me : other, me < other ? other : me);
}

/// A child slot as the walk reads it: node p's bounds of child `side`, its code in lo.w.
struct slot {
    float4 lo, hi;
};

BPX_HD slot read_slot(const bpx_cuda_node *nodes, uint32_t p, uint32_t side)
{
#ifdef __CUDA_ARCH__
    return slot{__ldg(&nodes[p].lo[side]), __ldg(&nodes[p].hi[side])};
#else
    return slot{nodes[p].lo[side], nodes[p].hi[side]};
#endif
}

struct walk_box {
    float4 lo, hi;
};

/// The walk of the box at Morton position t (t + 1 < n) over the positions after t only, from its
/// leaf up: src/kernels/lbvh_walk.h's, the opencl backend's walk, here on float bounds. Every
/// pair is emitted by exactly one walk, the one from its lower Morton position, at the two
/// leaves' lowest common ancestor. emit(i, j), i < j, for each overlapping pair. Returns the
/// bounds tests made.
/// template <class Emit> uint32_t walk(uint32_t t, nodes, leaf_lo, leaf_hi, leaf_parent,
///                                     node_parent, Emit emit)
// The host twin passes host-only functors: the check belongs to each instantiation's caller.
#define BPX_WALK_PREFIX _Pragma("nv_exec_check_disable") template <class Emit> BPX_HD
#define BPX_WALK_NAME walk
#define BPX_WALK_PARAMS                                                                            \
    const bpx_cuda_node *nodes, const float4 *leaf_lo, const float4 *leaf_hi,                      \
        const uint32_t *leaf_parent, const uint32_t *node_parent, Emit emit
#define BPX_WALK_BOX walk_box
#define BPX_WALK_SLOT slot
#define BPX_WALK_LOAD(box, t) ((box) = walk_box{leaf_lo[(t)], leaf_hi[(t)]})
#define BPX_WALK_LIVE(box) live((box).lo.x, (box).hi.x)
#define BPX_WALK_ID(box, t) bits_of((box).lo.w)
#define BPX_WALK_READ(p, side) read_slot(nodes, (p), (side))
#define BPX_WALK_OVERLAP(box, s) overlap((box).lo, (box).hi, (s).lo, (s).hi)
#define BPX_WALK_CODE(s) bits_of((s).lo.w)
#define BPX_WALK_BEGIN
#define BPX_WALK_HIT(me, at) emit_hit((me), (at), leaf_lo, emit)
#define BPX_WALK_END
#include "../kernels/lbvh_walk.h"

/// Bits of a pair key's j: the fewest (at least 1) that hold every id below n.
BPX_HD int key_bits(uint32_t n)
{
    int bits = 1;
    while (bits < 32 && (1ull << bits) < n)
        bits++;
    return bits;
}

/// A pair (i < j) as one key, (i << bits) | j: ordered by their low 2 * bits bits (the radix
/// sort's range), keys are in (i, j) order, and all ones (the device path's padding) is last.
BPX_HD unsigned long long pair_key(uint32_t i, uint32_t j, int bits)
{
    return ((unsigned long long)i << bits) | j;
}

BPX_HD bpx_pair key_pair(unsigned long long key, int bits)
{
    return bpx_pair{(uint32_t)(key >> bits), (uint32_t)(key & ((1ull << bits) - 1))};
}

} // namespace bpx_tree
