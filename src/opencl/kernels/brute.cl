// bpx OpenCL kernels: the brute-force comparator and the collision emitter.
// SPDX-License-Identifier: MIT
//
// One work-item per row (box i), one work-group per BPX_TILE consecutive rows. Columns come
// through local memory BPX_TILE boxes at a time (the tile: the paper's 2m - 1 comparison units
// fed from one memory), stored as six planes, so a row's test against the whole tile is one
// branch-free loop of the six comparisons that the compiler vectorises across the columns (a
// CPU's SIMD lanes under PoCL) while the GPU runs the rows side by side. The count pass sums the
// hits (and notes the first few); the emit pass, for groups with longer rows, makes a bit mask
// of the tile's hits and steps through its set bits.
//
// Rows come from one key set (a, global numbers ia + r) and columns from another (b, global
// numbers jb + c): the same set when everything fits, two blocks when boxes are streamed.
// A pair (i, j) counts when j > i. Both sets are padded to whole tiles with padding boxes.
//
// The emitter is deterministic: bpx_brute_count keeps, per row, its hit count and its first
// BPX_STASH hits, and per group the sum and whether some row had more; a scan of the group sums
// gives each group its offset; bpx_brute_emit gives each row its offset (a scan inside the group)
// and writes its hits in j order, from the stash or, for groups with a longer row, by comparing
// again. The pairs therefore come out sorted by (i, j) whatever the schedule.
#ifndef BPX_STASH
#define BPX_STASH 4
#endif

// The tile: six planes of BPX_TILE keys in local memory.
typedef struct tile_planes {
    uint lx[BPX_TILE], ly[BPX_TILE], lz[BPX_TILE];
    uint hx[BPX_TILE], hy[BPX_TILE], hz[BPX_TILE];
} tile_planes;

// Algorithm 1 for row (my_lo, my_hi) = box i against column k of the tile = box j.
#define BPX_HIT(t, k, j)                                                                           \
    ((my_lo.x <= (t)->hx[k]) & ((t)->lx[k] <= my_hi.x) & (my_lo.y <= (t)->hy[k]) &               \
     ((t)->ly[k] <= my_hi.y) & (my_lo.z <= (t)->hz[k]) & ((t)->lz[k] <= my_hi.z) & ((j) > i))

// First column tile a group must look at: the one holding column (first row's number + 1).
inline uint first_tile(uint ia, uint jb)
{
    ulong first = (ulong)ia + get_group_id(0) * BPX_TILE + 1u;
    return first <= jb ? 0u : (uint)((first - jb) / BPX_TILE * BPX_TILE);
}

inline void load_tile(__local tile_planes *t, __global const uint4 *lo, __global const uint4 *hi,
                      uint c0)
{
    uint l = get_local_id(0);
    uint4 a = lo[c0 + l];
    uint4 b = hi[c0 + l];
    t->lx[l] = a.x;
    t->ly[l] = a.y;
    t->lz[l] = a.z;
    t->hx[l] = b.x;
    t->hy[l] = b.y;
    t->hz[l] = b.z;
}

// Exclusive scan of one value per work-item over a work-group of `width` items (every item
// calls it); returns this item's prefix and leaves the group's sum in *total. scratch holds
// `width` ulongs. The tiled kernels, the small-set kernel and scan.cl all scan with it.
inline ulong bpx_local_scan(ulong value, __local ulong *scratch, uint width, ulong *total)
{
    uint l = get_local_id(0);
    scratch[l] = value;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint step = 1; step < width; step <<= 1) {
        ulong add = l >= step ? scratch[l - step] : 0ul;
        barrier(CLK_LOCAL_MEM_FENCE);
        scratch[l] += add;
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    *total = scratch[width - 1];
    ulong inclusive = scratch[l];
    barrier(CLK_LOCAL_MEM_FENCE);
    return inclusive - value;
}

__kernel __attribute__((reqd_work_group_size(BPX_TILE, 1, 1)))
void bpx_brute_count(__global const uint4 *lo_a, __global const uint4 *hi_a, uint ia,
                     __global const uint4 *lo_b, __global const uint4 *hi_b, uint nb, uint jb,
                     __global uint *row_count, __global uint *stash, __global ulong *group_sum,
                     __global uint *group_long)
{
    __local tile_planes tile;
    __local ulong scratch[BPX_TILE];
    __local uint any_long;
    uint r = get_global_id(0);
    uint l = get_local_id(0);
    uint i = ia + r;
    uint4 my_lo = lo_a[r];
    uint4 my_hi = hi_a[r];
    uint count = 0;
    for (uint c0 = first_tile(ia, jb); c0 < nb; c0 += BPX_TILE) {
        load_tile(&tile, lo_b, hi_b, c0);
        barrier(CLK_LOCAL_MEM_FENCE);
        uint j0 = jb + c0;
        uint hits = 0;
        for (uint k = 0; k < BPX_TILE; k++)
            hits += BPX_HIT(&tile, k, j0 + k);
        if (hits && count < BPX_STASH) {
            uint c = count;
            for (uint k = 0; k < BPX_TILE && c < BPX_STASH; k++)
                if (BPX_HIT(&tile, k, j0 + k))
                    stash[r * BPX_STASH + c++] = j0 + k;
        }
        count += hits;
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    row_count[r] = count;
    ulong total;
    bpx_local_scan(count, scratch, BPX_TILE, &total);
    // Whether some row of the group has more hits than its stash holds.
    if (l == 0)
        any_long = 0;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (count > BPX_STASH)
        any_long = 1;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (l == 0) {
        group_sum[get_group_id(0)] = total;
        group_long[get_group_id(0)] = any_long;
    }
}

/// Writes the pairs whose place in the output lies in [window, window + capacity) to
/// pairs[place - window]; the host re-runs with the next window when the output is larger.
__kernel __attribute__((reqd_work_group_size(BPX_TILE, 1, 1)))
void bpx_brute_emit(__global const uint4 *lo_a, __global const uint4 *hi_a, uint ia,
                    __global const uint4 *lo_b, __global const uint4 *hi_b, uint nb, uint jb,
                    __global const uint *row_count, __global const uint *stash,
                    __global const ulong *group_offset, __global const uint *group_long,
                    __global uint2 *pairs, ulong window, ulong capacity)
{
    __local tile_planes tile;
    __local ulong scratch[BPX_TILE];
    uint r = get_global_id(0);
    uint g = get_group_id(0);
    uint i = ia + r;
    uint count = row_count[r];
    ulong total;
    ulong place = group_offset[g] + bpx_local_scan(count, scratch, BPX_TILE, &total);
    ulong end = window + capacity;
    // Nothing of this group lands in the window: done (uniform over the group).
    if (total == 0 || group_offset[g] >= end || group_offset[g] + total <= window)
        return;
    if (!group_long[g]) {
        for (uint k = 0; k < count; k++, place++)
            if (place >= window && place < end)
                pairs[place - window] = (uint2)(i, stash[r * BPX_STASH + k]);
        return;
    }
    uint4 my_lo = lo_a[r];
    uint4 my_hi = hi_a[r];
    for (uint c0 = first_tile(ia, jb); c0 < nb; c0 += BPX_TILE) {
        load_tile(&tile, lo_b, hi_b, c0);
        barrier(CLK_LOCAL_MEM_FENCE);
        uint j0 = jb + c0;
        // Rows here are long: the tile's hits as a bit mask (still one branch-free loop), then
        // one step per hit, lowest column first.
        ulong mask = 0;
        for (uint k = 0; k < BPX_TILE; k++)
            mask |= (ulong)BPX_HIT(&tile, k, j0 + k) << k;
        uint hits = (uint)popcount(mask);
        if (hits && place + hits > window && place < end) {
            for (; mask; mask &= mask - 1, place++) {
                uint k = 63u - (uint)clz(mask & (~mask + 1ul));
                if (place >= window && place < end)
                    pairs[place - window] = (uint2)(i, j0 + k);
            }
        } else {
            place += hits;
        }
        barrier(CLK_LOCAL_MEM_FENCE);
    }
}

/// Small sets (n <= BPX_SMALL_N, the paper's sizes) in one launch: one work-group loads every
/// box into local memory, counts each row's hits, scans the counts and writes the pairs in
/// (i, j) order, and its first item writes the total to registers[slot] -- the comparator and
/// the emitter of the paper on one chip, with one call and one read-back per cycle instead of
/// three calls and two. Pairs whose place is at or past capacity are not written (the host
/// grows the buffer and runs again). Rows are dealt out in turn (row i has n - 1 - i columns);
/// the scan gives each item a run of consecutive rows.
__kernel __attribute__((reqd_work_group_size(BPX_SMALL_WG, 1, 1)))
void bpx_brute_small(__global const uint4 *lo, __global const uint4 *hi, uint n,
                     __global uint2 *pairs, ulong capacity, __global ulong *registers, uint slot)
{
    __local uint lx[BPX_SMALL_N], ly[BPX_SMALL_N], lz[BPX_SMALL_N];
    __local uint hx[BPX_SMALL_N], hy[BPX_SMALL_N], hz[BPX_SMALL_N];
    __local uint offset[BPX_SMALL_N]; // hits per row, then where the row's pairs start
    __local ulong part[BPX_SMALL_WG];
    uint l = get_local_id(0);
    for (uint k = l; k < n; k += BPX_SMALL_WG) {
        uint4 a = lo[k], b = hi[k];
        lx[k] = a.x;
        ly[k] = a.y;
        lz[k] = a.z;
        hx[k] = b.x;
        hy[k] = b.y;
        hz[k] = b.z;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
// Algorithm 1 for row i against box j, both in local memory.
#define BPX_SMALL_HIT(i, j)                                                                        \
    ((lx[i] <= hx[j]) & (lx[j] <= hx[i]) & (ly[i] <= hy[j]) & (ly[j] <= hy[i]) &                  \
     (lz[i] <= hz[j]) & (lz[j] <= hz[i]))
    for (uint i = l; i < n; i += BPX_SMALL_WG) {
        uint hits = 0;
        for (uint j = i + 1; j < n; j++)
            hits += BPX_SMALL_HIT(i, j);
        offset[i] = hits;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    // Exclusive scan of offset[0, n): each item sums its run, the runs' sums are scanned
    // (n(n - 1) / 2 pairs at most: a uint holds them), each item rewrites its run as offsets.
    uint per = (n + BPX_SMALL_WG - 1) / BPX_SMALL_WG;
    uint r0 = min(l * per, n), r1 = min(r0 + per, n);
    uint sum = 0;
    for (uint r = r0; r < r1; r++)
        sum += offset[r];
    ulong total;
    uint run = (uint)bpx_local_scan(sum, part, BPX_SMALL_WG, &total);
    for (uint r = r0; r < r1; r++) {
        uint count = offset[r];
        offset[r] = run;
        run += count;
    }
    if (l == 0)
        registers[slot] = total;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint i = l; i < n; i += BPX_SMALL_WG) {
        ulong place = offset[i];
        for (uint j = i + 1; j < n && place < capacity; j++) {
            uint hit = BPX_SMALL_HIT(i, j);
            if (hit)
                pairs[place] = (uint2)(i, j);
            place += hit;
        }
    }
#undef BPX_SMALL_HIT
}
