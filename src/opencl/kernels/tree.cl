// bpx OpenCL kernels: a linear BVH (Karras 2012) built every cycle, for large n.
// SPDX-License-Identifier: MIT
//
// One cycle: bpx_tree_reset clears the scene bounds and the pair counter; bpx_tree_bounds
// reduces the live boxes' centres to the scene's bounds; bpx_tree_codes gives each box its Morton
// code (inert boxes the last code); the radix sort (sort.cl) orders (code, box) stably, so equal
// codes stay in box order; bpx_sweep_gather (sweep.cl) puts the boxes' keys in that order;
// bpx_tree_build makes the n - 1 internal nodes, one per item;
// bpx_tree_refit climbs from every leaf, the second child at each node carrying on;
// bpx_tree_walk walks once per box, from its leaf up (the build's parents), over the later Morton
// positions and appends each pair as a 64-bit key (min id << bits | max id) through one atomic
// counter; the 64-bit radix sort puts the keys in (i, j) order and bpx_tree_unpack makes them
// pairs. The per-item steps are lbvh.h's (the walk src/kernels/lbvh_walk.h's, which the cuda
// backend shares), which the host twin runs too. Keys are this program's
// box keys (twin.h), x, y, z, 0 per box.

// The cycle's small words: the scene's centre bounds (six order keys: min x, y, z, max x, y, z)
// at [0, 6), the walks' pair counter at 6 and its wrap flag at 7.
#define BPX_TREE_COUNTER 6

__kernel void bpx_tree_reset(__global uint *small)
{
    if (get_global_id(0) == 0) {
        for (int a = 0; a < 3; a++) {
            small[a] = 0xFFFFFFFFu;
            small[3 + a] = 0u;
        }
        small[BPX_TREE_COUNTER] = 0u;
        small[BPX_TREE_COUNTER + 1] = 0u;
    }
}

#define BPX_TREE_ITEMS 16

/// The scene's centre bounds as order keys (min x, y, z, max x, y, z): each item reduces
/// BPX_TREE_ITEMS boxes, each group in local memory, then one atomic per group and bound.
__kernel __attribute__((reqd_work_group_size(BPX_SCAN_WG, 1, 1)))
void bpx_tree_bounds(__global const uint *lo, __global const uint *hi, uint n,
                     __global uint *scene)
{
    __local uint part[6];
    uint l = get_local_id(0);
    if (l < 6)
        part[l] = l < 3 ? 0xFFFFFFFFu : 0u;
    barrier(CLK_LOCAL_MEM_FENCE);
    uint mine[6] = {0xFFFFFFFFu, 0xFFFFFFFFu, 0xFFFFFFFFu, 0u, 0u, 0u};
    ulong first = (ulong)get_group_id(0) * (BPX_SCAN_WG * BPX_TREE_ITEMS) + l;
    for (uint e = 0; e < BPX_TREE_ITEMS; e++) {
        ulong k = first + (ulong)e * BPX_SCAN_WG; // neighbouring items read neighbouring boxes
        if (k < n) {
            __global const uint *bl = lo + k * BPX_KEY_LANES, *bh = hi + k * BPX_KEY_LANES;
            if (bpx_lbvh_live(bl, bh)) {
                float c[3];
                bpx_lbvh_centre(bl, bh, c);
                for (int a = 0; a < 3; a++) {
                    uint key = bpx_key(as_uint(c[a]));
                    mine[a] = min(mine[a], key);
                    mine[3 + a] = max(mine[3 + a], key);
                }
            }
        }
    }
    for (int a = 0; a < 3; a++) {
        atomic_min(&part[a], mine[a]);
        atomic_max(&part[3 + a], mine[3 + a]);
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    if (l < 3)
        atomic_min(&scene[l], part[l]);
    else if (l < 6)
        atomic_max(&scene[l], part[l]);
}

__kernel void bpx_tree_codes(__global const uint *lo, __global const uint *hi, uint n,
                             __global const uint *scene, __global uint *codes,
                             __global uint *ids)
{
    uint k = get_global_id(0);
    if (k >= n)
        return;
    __global const uint *bl = lo + (ulong)k * BPX_KEY_LANES, *bh = hi + (ulong)k * BPX_KEY_LANES;
    uint code = BPX_LBVH_NO_CODE;
    if (bpx_lbvh_live(bl, bh)) {
        float c[3];
        bpx_lbvh_centre(bl, bh, c);
        code = bpx_lbvh_morton(c, scene);
    }
    codes[k] = code;
    ids[k] = k;
}

/// Internal node k of n - 1; its arrival flag is cleared for the refit that follows.
__kernel void bpx_tree_build(__global const uint *codes, uint n, __global uint *leaf_parent,
                             __global uint *node_parent, __global uint *flags)
{
    uint k = get_global_id(0);
    if (k + 1 >= n)
        return;
    bpx_lbvh_build_node(codes, (int)n, (int)k, leaf_parent, node_parent);
    flags[k] = 0u;
}

/// lo, hi: the boxes' keys in Morton order.
__kernel void bpx_tree_refit(__global const uint *lo, __global const uint *hi, uint n,
                             __global const uint *leaf_parent,
                             __global const uint *node_parent, __global uint *nodes,
                             __global uint *flags)
{
    uint k = get_global_id(0);
    if (k < n)
        bpx_lbvh_refit_leaf(k, lo, hi, leaf_parent, node_parent, nodes, flags);
}

/// One walk per Morton position but the last (which has no later position); lo, hi in Morton
/// order, ids the box at each position; each item's bounds tests go to tests[k] for the cycle's
/// statistics.
__kernel void bpx_tree_walk(__global const uint *lo, __global const uint *hi, uint n,
                            __global const uint *ids, __global const uint *leaf_parent,
                            __global const uint *node_parent, __global const uint *nodes,
                            uint bits, __global ulong *out, ulong capacity, __global uint *small,
                            __global uint *tests)
{
    uint k = get_global_id(0);
    if (k + 1 >= n)
        return;
    tests[k] = bpx_lbvh_walk(k, lo, hi, ids, leaf_parent, node_parent, nodes, bits, out,
                             capacity, small + BPX_TREE_COUNTER);
}

__kernel void bpx_tree_unpack(__global const ulong *keys, uint count, uint bits,
                              __global uint2 *pairs)
{
    uint k = get_global_id(0);
    if (k < count) {
        ulong key = keys[k];
        pairs[k] = (uint2)((uint)(key >> bits), (uint)(key & ((1ul << bits) - 1ul)));
    }
}

/// A device-resident cycle's count (bpx_opencl_collide_device): the walks' counter as the
/// caller's ulong, all ones when it wrapped (2^32 pairs or more).
__kernel void bpx_tree_count(__global const uint *small, __global ulong *count)
{
    if (get_global_id(0) == 0)
        *count = small[BPX_TREE_COUNTER + 1] ? ~0ul : (ulong)small[BPX_TREE_COUNTER];
}
