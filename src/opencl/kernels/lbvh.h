// bpx OpenCL kernels: the linear BVH's per-item steps on box keys (Karras 2012), shared word for
// word by the device program (tree.cl) and its plain-C twin (src/opencl/twin.c).
// SPDX-License-Identifier: MIT
//
// Valid OpenCL C 1.2 and C11; it comes after twin.h (keys, bpx_u32, BPX_G) and
// src/kernels/lbvh_build.h (Morton codes and the node build, which the cuda backend shares), and
// before src/kernels/lbvh_walk.h (the walk, which the cuda backend shares too: this file says
// how the walk reads the tree's keys and emits its hits). Each step is one item's work: the
// centre of one box, the refit from one leaf, the walk of one box. The device runs the items in
// parallel, the twin in loops, so the twin's pairs are the device's pairs and a test proves the
// algorithm on the host. The cuda backend (src/cuda/tree.cuh) refits the same way on float
// bounds.
//
// Exactness: every decision about a pair compares the caller's own coordinates as order keys
// (twin.h), and a node's bounds are minima and maxima of those keys, so culling never rounds.
// Float arithmetic (the centres behind the Morton codes) only orders the leaves, and the pairs
// are sorted into (i, j) order afterwards, so the tree's shape never shows in the result.
#ifndef BPX_OPENCL_LBVH_H
#define BPX_OPENCL_LBVH_H

#ifndef __OPENCL_VERSION__
// The device program has these two just before this file.
#include "../../kernels/lbvh_build.h"
#include "twin.h"
#endif

#ifdef __OPENCL_VERSION__
#pragma OPENCL FP_CONTRACT OFF
// The refit's hand-over between two children: the first to arrive leaves, the second sees the
// first's slot. The fences order a slot's stores before the count that publishes them, and the
// sibling's slot's loads after it.
inline uint bpx_lbvh_arrive_(__global uint *flags, uint p)
{
    mem_fence(CLK_GLOBAL_MEM_FENCE);
    uint old = atomic_inc((volatile __global uint *)&flags[p]);
    mem_fence(CLK_GLOBAL_MEM_FENCE);
    return old;
}
#define BPX_LBVH_ARRIVE(flags, p) bpx_lbvh_arrive_((flags), (p))
#define BPX_LBVH_RESERVE(counter, k) atomic_add((volatile __global uint *)(counter), (k))
#define BPX_LBVH_OVERFLOW(counter) atomic_or((volatile __global uint *)(counter) + 1, 1u)
#define BPX_LBVH_SLOTS volatile __global
#else
// The twin runs the items one after another: plain counters stand in for the atomics.
static inline bpx_u32 bpx_lbvh_post_inc_(bpx_u32 *p, bpx_u32 k)
{
    bpx_u32 old = *p;
    *p += k;
    return old;
}
#define BPX_LBVH_ARRIVE(flags, p) bpx_lbvh_post_inc_(&(flags)[p], 1u)
#define BPX_LBVH_RESERVE(counter, k) bpx_lbvh_post_inc_((counter), (k))
#define BPX_LBVH_OVERFLOW(counter) ((counter)[1] |= 1u)
#define BPX_LBVH_SLOTS
#endif

/// The Morton code of a box with no centre (inert: removed ids, min > max): after every other.
#define BPX_LBVH_NO_CODE 0xFFFFFFFFu
/// Hits one walk keeps before reserving their places with one atomic.
#define BPX_LBVH_BATCH 8

/// A box with keys lo, hi (x, y, z lanes) has a centre: min x <= max x. Inert boxes (min +inf,
/// max -inf) and padding boxes have none.
BPX_FN int bpx_lbvh_live(const BPX_G bpx_u32 *lo, const BPX_G bpx_u32 *hi)
{
    return lo[0] <= hi[0];
}

/// The centre of a live box, in floats (halves first: lo + hi can overflow). Only orders.
BPX_FN void bpx_lbvh_centre(const BPX_G bpx_u32 *lo, const BPX_G bpx_u32 *hi, float c[3])
{
    for (int a = 0; a < 3; a++)
        c[a] = 0.5f * bpx_lbvh_key_value(lo[a]) + 0.5f * bpx_lbvh_key_value(hi[a]);
}

/// Keys per child slot: min x, y, z, the child's code (BPX_LBVH_LEAF | position, or a node),
/// max x, y, z, 0. Node p's two children are slots 2p and 2p + 1: one 64-byte record, so that a
/// walk's visit to a node reads one cache line.
#define BPX_LBVH_SLOT 8

/// The refit from the leaf at position t: its box's keys are at lo / hi position t (the boxes are
/// gathered into Morton order first, so that neighbouring items read neighbouring boxes rather
/// than chase box numbers across memory). It writes its box into its parent's slot; the second
/// child to arrive at a node writes the node's union into the node's parent, and so on to the root.
/// flags[] (one per node, zero before) count the arrivals. Unions are minima and maxima of keys:
/// exact. Inert boxes' empty bounds (min key > max key) never widen a union, so a node holding only
/// inert boxes stays empty.
BPX_FN void bpx_lbvh_refit_leaf(bpx_u32 t, const BPX_G bpx_u32 *lo, const BPX_G bpx_u32 *hi,
                                const BPX_G bpx_u32 *leaf_parent, const BPX_G bpx_u32 *node_parent,
                                BPX_LBVH_SLOTS bpx_u32 *nodes, BPX_G bpx_u32 *flags)
{
    bpx_u64 box = (bpx_u64)t * BPX_KEY_LANES;
    bpx_u32 l[3], h[3];
    for (int a = 0; a < 3; a++) {
        l[a] = lo[box + (bpx_u32)a];
        h[a] = hi[box + (bpx_u32)a];
    }
    bpx_u32 code = t | BPX_LBVH_LEAF;
    bpx_u32 up = leaf_parent[t];
    for (;;) {
        bpx_u32 p = up >> 1;
        bpx_u64 slot = (bpx_u64)up * BPX_LBVH_SLOT; // up = 2p + side
        for (int a = 0; a < 3; a++) {
            nodes[slot + (bpx_u32)a] = l[a];
            nodes[slot + 4 + (bpx_u32)a] = h[a];
        }
        nodes[slot + 3] = code;
        nodes[slot + 7] = 0u;
        if (BPX_LBVH_ARRIVE(flags, p) == 0 || p == 0)
            return; // the sibling is not there yet (its item carries on), or this was the root
        bpx_u64 other = (bpx_u64)(up ^ 1u) * BPX_LBVH_SLOT;
        for (int a = 0; a < 3; a++) {
            bpx_u32 ol = nodes[other + (bpx_u32)a], oh = nodes[other + 4 + (bpx_u32)a];
            l[a] = ol < l[a] ? ol : l[a];
            h[a] = oh > h[a] ? oh : h[a];
        }
        code = p;
        up = node_parent[p];
    }
}

/// Algorithm 1 on keys: box a (private) against the bounds of a child slot.
BPX_FN int bpx_lbvh_overlap(const bpx_u32 *alo, const bpx_u32 *ahi, const BPX_G bpx_u32 *slot)
{
    const BPX_G bpx_u32 *blo = slot, *bhi = slot + 4;
    return (alo[0] <= bhi[0]) & (blo[0] <= ahi[0]) & (alo[1] <= bhi[1]) & (blo[1] <= ahi[1]) &
           (alo[2] <= bhi[2]) & (blo[2] <= ahi[2]);
}

/// Writes a walk's batch of hit keys at places reserved with one atomic; places at or beyond
/// `capacity` are dropped (the counter still counts them: the host grows the buffer and walks
/// again). A counter that wraps past 2^32 sets counter[1].
BPX_FN void bpx_lbvh_flush(const bpx_u64 *batch, bpx_u32 count, BPX_G bpx_u64 *out,
                           bpx_u64 capacity, BPX_G bpx_u32 *counter)
{
    bpx_u32 at = BPX_LBVH_RESERVE(counter, count);
    if (at > 0xFFFFFFFFu - count)
        BPX_LBVH_OVERFLOW(counter);
    for (bpx_u32 k = 0; k < count; k++)
        if ((bpx_u64)at + k < capacity)
            out[(bpx_u64)at + k] = batch[k];
}

/// Appends the pair of boxes `me` and `other` to a walk's batch as the key (min id << bits) | max
/// id, flushing a full batch.
BPX_FN void bpx_lbvh_hit(bpx_u32 me, bpx_u32 other, bpx_u32 bits, bpx_u64 *batch,
                         bpx_u32 *batched, BPX_G bpx_u64 *out, bpx_u64 capacity,
                         BPX_G bpx_u32 *counter)
{
    bpx_u64 i = me < other ? me : other, j = me < other ? other : me;
    batch[(*batched)++] = (i << bits) | j;
    if (*batched == BPX_LBVH_BATCH) {
        bpx_lbvh_flush(batch, *batched, out, capacity, counter);
        *batched = 0u;
    }
}

/// The walk of the box at Morton position t (t + 1 < n) over the positions after t only, from its
/// leaf up (src/kernels/lbvh_walk.h), on keys: leaf_parent and node_parent are the build's
/// (lbvh_build.h: 2p + side), boxes in Morton order (lo / hi position t), ids[t] the box number
/// at position t; hits leave through bpx_lbvh_hit's batches. Returns the bounds tests made.
/// bpx_u32 bpx_lbvh_walk(bpx_u32 t, lo, hi, ids, leaf_parent, node_parent, nodes, bits, out,
///                       capacity, counter)
typedef struct {
    bpx_u32 lo[3], hi[3];
} bpx_lbvh_box;
#define BPX_WALK_PREFIX BPX_FN
#define BPX_WALK_NAME bpx_lbvh_walk
#define BPX_WALK_PARAMS                                                                            \
    const BPX_G bpx_u32 *lo, const BPX_G bpx_u32 *hi, const BPX_G bpx_u32 *ids,                    \
        const BPX_G bpx_u32 *leaf_parent, const BPX_G bpx_u32 *node_parent,                        \
        const BPX_G bpx_u32 *nodes, bpx_u32 bits, BPX_G bpx_u64 *out, bpx_u64 capacity,            \
        BPX_G bpx_u32 *counter
#define BPX_WALK_BOX bpx_lbvh_box
#define BPX_WALK_SLOT const BPX_G bpx_u32 *
#define BPX_WALK_LOAD(box, t)                                                                      \
    for (int a = 0; a < 3; a++) {                                                                  \
        (box).lo[a] = lo[(bpx_u64)(t) * BPX_KEY_LANES + (bpx_u32)a];                               \
        (box).hi[a] = hi[(bpx_u64)(t) * BPX_KEY_LANES + (bpx_u32)a];                               \
    }
#define BPX_WALK_LIVE(box) ((box).lo[0] <= (box).hi[0])
#define BPX_WALK_ID(box, t) ids[(t)]
#define BPX_WALK_READ(p, side) (nodes + ((bpx_u64)(p) * 2u + (side)) * BPX_LBVH_SLOT)
#define BPX_WALK_OVERLAP(box, s) bpx_lbvh_overlap((box).lo, (box).hi, (s))
#define BPX_WALK_CODE(s) (s)[3]
#define BPX_WALK_BEGIN                                                                             \
    bpx_u64 batch[BPX_LBVH_BATCH];                                                                 \
    bpx_u32 batched = 0u;
#define BPX_WALK_HIT(me, at)                                                                       \
    bpx_lbvh_hit((me), ids[(at)], bits, batch, &batched, out, capacity, counter)
#define BPX_WALK_END                                                                               \
    if (batched)                                                                                   \
        bpx_lbvh_flush(batch, batched, out, capacity, counter);
#ifndef __OPENCL_VERSION__
#include "../../kernels/lbvh_walk.h" // the program has it just after this file
#endif

#endif
