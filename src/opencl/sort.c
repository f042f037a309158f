// The opencl backend's scans and radix sorts (kernels/scan.cl, kernels/sort.cl), shared by sort
// and sweep (sweep.c) and the tree (tree.c).

#include "state.h"

unsigned bpx__cl_bits_for(uint32_t max_value)
{
    unsigned bits = 1;
    while (bits < 32 && (max_value >> bits) != 0)
        bits++;
    return bits;
}

// The scan's group sums: one per chunk of count values; the total goes to registers[slot].
static bpx_status scan_sums(bpx_cl_state *st, cl_mem in, uint32_t count, cl_uint slot,
                            size_t *groups)
{
    size_t chunk = (size_t)st->dev->scan_wg * BPX_CL_SCAN_ITEMS;
    *groups = (count + chunk - 1) / chunk;
    TRY(bpx__cl_dbuf_reserve(st, &st->sums, (*groups ? *groups : 1) * sizeof(cl_ulong)));
    cl_uint count_arg = count, groups_arg = (cl_uint)*groups;
    size_t wg = st->dev->scan_wg;
    const bpx_cl_arg reduce[] = {ARG(in), ARG(count_arg), ARG(st->sums.mem)};
    TRY(bpx__cl_launch(st, K_SCAN_REDUCE, *groups * wg, wg, 3, reduce));
    const bpx_cl_arg sums[] = {ARG(st->sums.mem), ARG(groups_arg), ARG(st->registers.mem),
                               ARG(slot)};
    return bpx__cl_launch(st, K_SCAN_SUMS, wg, wg, 4, sums);
}

bpx_status bpx__cl_sum(bpx_cl_state *st, cl_mem in, uint32_t count, cl_uint slot)
{
    size_t groups;
    return scan_sums(st, in, count, slot, &groups);
}

bpx_status bpx__cl_scan(bpx_cl_state *st, cl_mem in, uint32_t count, cl_mem out, cl_uint slot)
{
    size_t groups;
    TRY(scan_sums(st, in, count, slot, &groups));
    size_t wg = st->dev->scan_wg;
    cl_uint count_arg = count;
    const bpx_cl_arg apply[] = {ARG(in), ARG(count_arg), ARG(st->sums.mem), ARG(out)};
    return bpx__cl_launch(st, K_SCAN_APPLY, groups * wg, wg, 4, apply);
}

// Per pass (a digit of radix_bits): each group's digit counts, their scan (digit-major: equal
// digits keep group order), the scatter. `values` NULL: 64-bit keys alone, else 32-bit keys with
// 32-bit values.
static bpx_status radix_passes(bpx_cl_state *st, bpx_cl_buffer *keys, bpx_cl_buffer *values,
                               uint32_t count, unsigned bits, int *result)
{
    *result = 0;
    if (count < 2)
        return BPX_OK;
    size_t wg = st->dev->scan_wg, chunk = wg * st->dev->radix_items;
    size_t groups = (count + chunk - 1) / chunk;
    unsigned digit = st->dev->radix_bits;
    uint32_t bins = (1u << digit) * (uint32_t)groups;
    TRY(bpx__cl_dbuf_reserve(st, &st->hist, bins * sizeof(cl_uint)));
    TRY(bpx__cl_dbuf_reserve(st, &st->hist_offsets, bins * sizeof(cl_ulong)));
    cl_uint count_arg = count;
    int cur = 0;
    for (unsigned shift = 0; shift < bits; shift += digit) {
        cl_uint shift_arg = shift;
        const bpx_cl_arg c[] = {ARG(keys[cur].mem), ARG(count_arg), ARG(shift_arg),
                                ARG(st->hist.mem)};
        TRY(bpx__cl_launch(st, values ? K_RADIX_COUNT : K_RADIX_COUNT64, groups * wg, wg, 4, c));
        TRY(bpx__cl_scan(st, st->hist.mem, bins, st->hist_offsets.mem, 2));
        if (values) {
            const bpx_cl_arg s[] = {
                ARG(keys[cur].mem),      ARG(values[cur].mem),      ARG(count_arg),
                ARG(shift_arg),          ARG(st->hist_offsets.mem), ARG(keys[1 - cur].mem),
                ARG(values[1 - cur].mem)};
            TRY(bpx__cl_launch(st, K_RADIX_SCATTER, groups * wg, wg, 7, s));
        } else {
            const bpx_cl_arg s[] = {ARG(keys[cur].mem), ARG(count_arg), ARG(shift_arg),
                                    ARG(st->hist_offsets.mem), ARG(keys[1 - cur].mem)};
            TRY(bpx__cl_launch(st, K_RADIX_SCATTER64, groups * wg, wg, 5, s));
        }
        cur = 1 - cur;
    }
    *result = cur;
    return BPX_OK;
}

bpx_status bpx__cl_radix_sort(bpx_cl_state *st, bpx_cl_buffer *keys, bpx_cl_buffer *values,
                              uint32_t count, unsigned bits, int *result)
{
    return radix_passes(st, keys, values, count, bits, result);
}

bpx_status bpx__cl_radix_sort64(bpx_cl_state *st, bpx_cl_buffer *keys, uint32_t count,
                                unsigned bits, int *result)
{
    return radix_passes(st, keys, NULL, count, bits, result);
}
