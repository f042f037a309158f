// bpx OpenCL kernels: exclusive prefix sums (uint counts -> ulong offsets) for the emitter and
// the radix sort. SPDX-License-Identifier: MIT
//
// Two levels: bpx_scan_reduce sums each group's chunk (BPX_SCAN_WG items x BPX_SCAN_ITEMS
// consecutive values each), bpx_scan_sums scans those sums in one work-group and stores the
// total (the paper's collision-count register when the values are collision counts), and
// bpx_scan_apply writes each value's offset. The scan inside a group is bpx_local_scan
// (brute.cl, earlier in the program).
#ifndef BPX_SCAN_WG
#define BPX_SCAN_WG 128
#endif
#define BPX_SCAN_ITEMS 8
#define BPX_SCAN_CHUNK (BPX_SCAN_WG * BPX_SCAN_ITEMS)

__kernel __attribute__((reqd_work_group_size(BPX_SCAN_WG, 1, 1)))
void bpx_scan_reduce(__global const uint *in, uint n, __global ulong *sums)
{
    __local ulong scratch[BPX_SCAN_WG];
    ulong first = (ulong)get_group_id(0) * BPX_SCAN_CHUNK + get_local_id(0) * BPX_SCAN_ITEMS;
    ulong sum = 0;
    for (uint e = 0; e < BPX_SCAN_ITEMS; e++)
        if (first + e < n)
            sum += in[first + e];
    ulong total;
    bpx_local_scan(sum, scratch, BPX_SCAN_WG, &total);
    if (get_local_id(0) == 0)
        sums[get_group_id(0)] = total;
}

/// One work-group: sums[0..count) becomes its exclusive scan; registers[slot] the total.
__kernel __attribute__((reqd_work_group_size(BPX_SCAN_WG, 1, 1)))
void bpx_scan_sums(__global ulong *sums, uint count, __global ulong *registers, uint slot)
{
    __local ulong scratch[BPX_SCAN_WG];
    ulong carry = 0;
    for (uint base = 0; base < count; base += BPX_SCAN_WG) {
        uint k = base + get_local_id(0);
        ulong value = k < count ? sums[k] : 0ul;
        ulong total;
        ulong prefix = bpx_local_scan(value, scratch, BPX_SCAN_WG, &total);
        if (k < count)
            sums[k] = carry + prefix;
        carry += total;
    }
    if (get_local_id(0) == 0)
        registers[slot] = carry;
}

__kernel __attribute__((reqd_work_group_size(BPX_SCAN_WG, 1, 1)))
void bpx_scan_apply(__global const uint *in, uint n, __global const ulong *sums,
                    __global ulong *out)
{
    __local ulong scratch[BPX_SCAN_WG];
    ulong first = (ulong)get_group_id(0) * BPX_SCAN_CHUNK + get_local_id(0) * BPX_SCAN_ITEMS;
    ulong sum = 0;
    for (uint e = 0; e < BPX_SCAN_ITEMS; e++)
        if (first + e < n)
            sum += in[first + e];
    ulong total;
    ulong place = sums[get_group_id(0)] + bpx_local_scan(sum, scratch, BPX_SCAN_WG, &total);
    for (uint e = 0; e < BPX_SCAN_ITEMS; e++)
        if (first + e < n) {
            out[first + e] = place;
            place += in[first + e];
        }
}
