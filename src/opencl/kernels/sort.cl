// bpx OpenCL kernels: a stable least-significant-digit radix sort of (uint key, uint value),
// BPX_RADIX_BITS bits per pass, for the sort-and-sweep path and the tree's Morton codes, and of
// ulong keys alone for the tree's pairs. SPDX-License-Identifier: MIT
//
// Per pass: bpx_radix_count counts each group's digits (hist[digit * groups + group]), the scan
// kernels turn the counts into offsets (digit-major, so equal digits keep group order), and
// bpx_radix_scatter moves each key to its place. Each work-item owns BPX_RADIX_ITEMS consecutive
// elements and walks them in order, and the items' places for each digit are a scan over the
// items, so the sort is stable: ties keep their input order.
//
// The digit's width and the elements per item are the device's (BPX_CL_RADIX_* in
// src/opencl/device.h): 4 bits and 8 elements by default, 6 bits and 64 elements on a CPU
// device, where each pass is a sweep through memory and fewer passes is what counts.
#ifndef BPX_RADIX_BITS
#define BPX_RADIX_BITS 4
#endif
#ifndef BPX_RADIX_ITEMS
#define BPX_RADIX_ITEMS 8
#endif
#define BPX_RADIX_BINS (1u << BPX_RADIX_BITS)
#define BPX_RADIX_CHUNK (BPX_SCAN_WG * BPX_RADIX_ITEMS)

// Each item's digit counts over its BPX_RADIX_ITEMS keys, into counts[digit * BPX_SCAN_WG + item];
// one body for 32-bit keys (sort and sweep, Morton codes) and 64-bit keys (the tree's pairs).
#define BPX_DIGIT_COUNTS(name, key_t)                                                              \
    inline void name(__global const key_t *keys, uint n, uint shift, __local uint *counts)        \
    {                                                                                              \
        uint t = get_local_id(0);                                                                  \
        ulong first = (ulong)get_group_id(0) * BPX_RADIX_CHUNK + t * BPX_RADIX_ITEMS;              \
        uint mine[BPX_RADIX_BINS];                                                                 \
        for (uint d = 0; d < BPX_RADIX_BINS; d++)                                                  \
            mine[d] = 0;                                                                           \
        for (uint e = 0; e < BPX_RADIX_ITEMS; e++)                                                 \
            if (first + e < n)                                                                     \
                mine[(uint)(keys[first + e] >> shift) & (BPX_RADIX_BINS - 1)]++;                   \
        for (uint d = 0; d < BPX_RADIX_BINS; d++)                                                  \
            counts[d * BPX_SCAN_WG + t] = mine[d];                                                 \
        barrier(CLK_LOCAL_MEM_FENCE);                                                              \
    }
BPX_DIGIT_COUNTS(digit_counts, uint)
BPX_DIGIT_COUNTS(digit_counts64, ulong)

// The group's count of each digit into hist[digit * groups + group].
inline void group_histogram(__local const uint *counts, __global uint *hist)
{
    for (uint d = get_local_id(0); d < BPX_RADIX_BINS; d += BPX_SCAN_WG) {
        uint sum = 0;
        for (uint u = 0; u < BPX_SCAN_WG; u++)
            sum += counts[d * BPX_SCAN_WG + u];
        hist[d * get_num_groups(0) + get_group_id(0)] = sum;
    }
}

// Each item's first place for each digit: the digit's offset for the group plus the counts of
// the group's earlier items.
inline void item_places(__local uint *counts, __global const ulong *offsets,
                        ulong place[BPX_RADIX_BINS])
{
    uint t = get_local_id(0);
    for (uint d = t; d < BPX_RADIX_BINS; d += BPX_SCAN_WG) {
        uint running = 0;
        for (uint u = 0; u < BPX_SCAN_WG; u++) {
            uint v = counts[d * BPX_SCAN_WG + u];
            counts[d * BPX_SCAN_WG + u] = running;
            running += v;
        }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint d = 0; d < BPX_RADIX_BINS; d++)
        place[d] = offsets[d * get_num_groups(0) + get_group_id(0)] + counts[d * BPX_SCAN_WG + t];
}

__kernel __attribute__((reqd_work_group_size(BPX_SCAN_WG, 1, 1)))
void bpx_radix_count(__global const uint *keys, uint n, uint shift, __global uint *hist)
{
    __local uint counts[BPX_RADIX_BINS * BPX_SCAN_WG];
    digit_counts(keys, n, shift, counts);
    group_histogram(counts, hist);
}

__kernel __attribute__((reqd_work_group_size(BPX_SCAN_WG, 1, 1)))
void bpx_radix_scatter(__global const uint *keys, __global const uint *values, uint n, uint shift,
                       __global const ulong *offsets, __global uint *keys_out,
                       __global uint *values_out)
{
    __local uint counts[BPX_RADIX_BINS * BPX_SCAN_WG];
    digit_counts(keys, n, shift, counts);
    ulong place[BPX_RADIX_BINS];
    item_places(counts, offsets, place);
    ulong first = (ulong)get_group_id(0) * BPX_RADIX_CHUNK + get_local_id(0) * BPX_RADIX_ITEMS;
    for (uint e = 0; e < BPX_RADIX_ITEMS; e++)
        if (first + e < n) {
            uint key = keys[first + e];
            ulong to = place[(key >> shift) & (BPX_RADIX_BINS - 1)]++;
            keys_out[to] = key;
            values_out[to] = values[first + e];
        }
}

/// 64-bit keys alone (the tree's pair keys carry their pair).
__kernel __attribute__((reqd_work_group_size(BPX_SCAN_WG, 1, 1)))
void bpx_radix_count64(__global const ulong *keys, uint n, uint shift, __global uint *hist)
{
    __local uint counts[BPX_RADIX_BINS * BPX_SCAN_WG];
    digit_counts64(keys, n, shift, counts);
    group_histogram(counts, hist);
}

__kernel __attribute__((reqd_work_group_size(BPX_SCAN_WG, 1, 1)))
void bpx_radix_scatter64(__global const ulong *keys, uint n, uint shift,
                         __global const ulong *offsets, __global ulong *keys_out)
{
    __local uint counts[BPX_RADIX_BINS * BPX_SCAN_WG];
    digit_counts64(keys, n, shift, counts);
    ulong place[BPX_RADIX_BINS];
    item_places(counts, offsets, place);
    ulong first = (ulong)get_group_id(0) * BPX_RADIX_CHUNK + get_local_id(0) * BPX_RADIX_ITEMS;
    for (uint e = 0; e < BPX_RADIX_ITEMS; e++)
        if (first + e < n) {
            ulong key = keys[first + e];
            keys_out[place[(uint)(key >> shift) & (BPX_RADIX_BINS - 1)]++] = key;
        }
}
