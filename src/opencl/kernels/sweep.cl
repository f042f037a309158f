// bpx OpenCL kernels: sort and sweep on x for large n (the paper's future work, §7).
// SPDX-License-Identifier: MIT
//
// bpx_sweep_keys makes (min-x key, box number) for the radix sort; bpx_sweep_gather puts the
// keys in sorted order; bpx_sweep_count / bpx_sweep_write sweep every sorted position (tiled,
// below); the pairs are then radix-sorted by j and then, stably, by i (same sort kernels), and
// bpx_sweep_interleave packs them as (i, j) for the read-back. The file comes after brute.cl in
// the program and uses its tile.

__kernel void bpx_sweep_keys(__global const uint4 *lo, uint n, __global uint *keys,
                             __global uint *index)
{
    uint k = get_global_id(0);
    if (k < n) {
        keys[k] = lo[k].x;
        index[k] = k;
    }
}

/// Keys in sorted order, padded to whole tiles with padding boxes.
__kernel void bpx_sweep_gather(__global const uint4 *lo, __global const uint4 *hi,
                               __global const uint *index, uint n, uint padded,
                               __global uint4 *sorted_lo, __global uint4 *sorted_hi)
{
    uint p = get_global_id(0);
    if (p < n) {
        sorted_lo[p] = lo[index[p]];
        sorted_hi[p] = hi[index[p]];
    } else if (p < padded) {
        sorted_lo[p] = (uint4)(BPX_KEY_PAD_LO, BPX_KEY_PAD_LO, BPX_KEY_PAD_LO, 0u);
        sorted_hi[p] = (uint4)(BPX_KEY_PAD_HI, BPX_KEY_PAD_HI, BPX_KEY_PAD_HI, 0u);
    }
}

// The sweep, tiled: a work-group holds BPX_TILE consecutive sorted positions (one per
// work-item) and walks tiles of later positions through local memory, from its own tile on,
// until a tile starts beyond the largest max x among its rows. Each row tests whole tiles with
// the brute-force comparator's branch-free loop (brute.cl's tile and BPX_HIT, with "column after
// row" in sorted order), so the sweep is vectorised the same way. The result is that of
// bpx_sweep_position (twin.h) for every position: the same pairs, counted or written in the same
// order.
inline uint sweep_reach(uint my_reach, __local uint *reach)
{
    if (get_local_id(0) == 0)
        *reach = 0;
    barrier(CLK_LOCAL_MEM_FENCE);
    atomic_max(reach, my_reach);
    barrier(CLK_LOCAL_MEM_FENCE);
    return *reach;
}

__kernel __attribute__((reqd_work_group_size(BPX_TILE, 1, 1)))
void bpx_sweep_count(__global const uint4 *sorted_lo, __global const uint4 *sorted_hi,
                     uint padded, __global uint *counts)
{
    __local tile_planes tile;
    __local uint reach_local;
    uint p = get_global_id(0);
    uint4 my_lo = sorted_lo[p];
    uint4 my_hi = sorted_hi[p];
    uint i = p; // BPX_HIT's "column after row", in sorted positions
    // Padding rows (max x key 0) do not widen the reach.
    uint reach = sweep_reach(my_hi.x, &reach_local);
    uint count = 0;
    for (uint c0 = get_group_id(0) * BPX_TILE; c0 < padded; c0 += BPX_TILE) {
        load_tile(&tile, sorted_lo, sorted_hi, c0);
        barrier(CLK_LOCAL_MEM_FENCE);
        bool past = tile.lx[0] > reach; // sorted: every later column starts beyond too
        uint hits = 0;
        for (uint k = 0; k < BPX_TILE; k++)
            hits += BPX_HIT(&tile, k, c0 + k);
        count += past ? 0u : hits;
        barrier(CLK_LOCAL_MEM_FENCE);
        if (past)
            break;
    }
    counts[p] = count;
}

/// Writes position p's pairs (smaller box number first) from offsets[p]; those at or beyond
/// `capacity` are dropped (the host sized the buffer from the count register).
__kernel __attribute__((reqd_work_group_size(BPX_TILE, 1, 1)))
void bpx_sweep_write(__global const uint4 *sorted_lo, __global const uint4 *sorted_hi,
                     __global const uint *index, uint n, uint padded,
                     __global const ulong *offsets, __global uint *out_i, __global uint *out_j,
                     ulong capacity)
{
    __local tile_planes tile;
    __local uint reach_local;
    uint p = get_global_id(0);
    uint4 my_lo = sorted_lo[p];
    uint4 my_hi = sorted_hi[p];
    uint i = p;
    uint reach = sweep_reach(my_hi.x, &reach_local);
    uint me = p < n ? index[p] : 0u;
    ulong place = p < n ? offsets[p] : 0ul;
    for (uint c0 = get_group_id(0) * BPX_TILE; c0 < padded; c0 += BPX_TILE) {
        load_tile(&tile, sorted_lo, sorted_hi, c0);
        barrier(CLK_LOCAL_MEM_FENCE);
        bool past = tile.lx[0] > reach;
        ulong mask = 0;
        for (uint k = 0; k < BPX_TILE; k++)
            mask |= (ulong)BPX_HIT(&tile, k, c0 + k) << k;
        for (; mask && !past; mask &= mask - 1, place++) {
            uint k = 63u - (uint)clz(mask & (~mask + 1ul));
            uint other = index[c0 + k];
            if (place < capacity) {
                out_i[place] = me < other ? me : other;
                out_j[place] = me < other ? other : me;
            }
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        if (past)
            break;
    }
}

__kernel void bpx_sweep_interleave(__global const uint *i, __global const uint *j, ulong count,
                                   __global uint2 *pairs)
{
    ulong k = get_global_id(0);
    if (k < count)
        pairs[k] = (uint2)(i[k], j[k]);
}
