// The opencl backend's sort and sweep, for large sets: a device radix sort on min x, a tiled
// sweep, and the pairs put in (i, j) order by two more radix sorts.

#include "state.h"

// ---------------------------------------------------------------------------------------------
// Scans and radix sort

// Exclusive scan of count uints into ulong offsets; the total goes to registers[slot].
static bpx_status scan(cl_state *st, cl_mem in, uint32_t count, cl_mem out, cl_uint slot)
{
    size_t chunk = (size_t)st->dev->scan_wg * BPX_CL_SCAN_ITEMS;
    size_t groups = (count + chunk - 1) / chunk;
    TRY(bpx__cl_dbuf_reserve(st, &st->sums, (groups ? groups : 1) * sizeof(cl_ulong)));
    cl_uint count_arg = count, groups_arg = (cl_uint)groups;
    size_t wg = st->dev->scan_wg;
    const kernel_arg reduce[] = {ARG(in), ARG(count_arg), ARG(st->sums.mem)};
    TRY(bpx__cl_launch(st, K_SCAN_REDUCE, groups * wg, wg, 3, reduce));
    const kernel_arg sums[] = {ARG(st->sums.mem), ARG(groups_arg), ARG(st->registers.mem),
                               ARG(slot)};
    TRY(bpx__cl_launch(st, K_SCAN_SUMS, wg, wg, 4, sums));
    const kernel_arg apply[] = {ARG(in), ARG(count_arg), ARG(st->sums.mem), ARG(out)};
    return bpx__cl_launch(st, K_SCAN_APPLY, groups * wg, wg, 4, apply);
}

// Stable LSD radix sort of (keys[0], values[0]) by the low `bits` bits of the keys, through
// (keys[1], values[1]); *result tells which of the two holds the sorted data.
static bpx_status radix_sort(cl_state *st, dbuf *keys, dbuf *values, uint32_t count, unsigned bits,
                             int *result)
{
    *result = 0;
    if (count < 2)
        return BPX_OK;
    size_t wg = st->dev->scan_wg;
    size_t groups = (count + wg * BPX_CL_SCAN_ITEMS - 1) / (wg * BPX_CL_SCAN_ITEMS);
    uint32_t bins = 16 * (uint32_t)groups;
    TRY(bpx__cl_dbuf_reserve(st, &st->hist, bins * sizeof(cl_uint)));
    TRY(bpx__cl_dbuf_reserve(st, &st->hist_offsets, bins * sizeof(cl_ulong)));
    cl_uint count_arg = count;
    int cur = 0;
    for (unsigned shift = 0; shift < bits; shift += 4) {
        cl_uint shift_arg = shift;
        const kernel_arg c[] = {ARG(keys[cur].mem), ARG(count_arg), ARG(shift_arg),
                                ARG(st->hist.mem)};
        TRY(bpx__cl_launch(st, K_RADIX_COUNT, groups * wg, wg, 4, c));
        TRY(scan(st, st->hist.mem, bins, st->hist_offsets.mem, 2));
        const kernel_arg s[] = {
            ARG(keys[cur].mem),      ARG(values[cur].mem),      ARG(count_arg),
            ARG(shift_arg),          ARG(st->hist_offsets.mem), ARG(keys[1 - cur].mem),
            ARG(values[1 - cur].mem)};
        TRY(bpx__cl_launch(st, K_RADIX_SCATTER, groups * wg, wg, 7, s));
        cur = 1 - cur;
    }
    *result = cur;
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// Sort and sweep

static unsigned bits_for(uint32_t max_value)
{
    unsigned bits = 1;
    while (bits < 32 && (max_value >> bits) != 0)
        bits++;
    return bits;
}

// Returns BPX_ERR_DEVICE_MEMORY, before any pair is written, when the pairs would not fit:
// the caller then runs brute force, which can read pairs out in windows.
bpx_status bpx__cl_sweep_all(cl_state *st, bpx_world *w, bpx_block *block)
{
    uint32_t n = w->n;
    uint32_t padded = (uint32_t)round_up(n, st->tile);
    TRY(bpx__cl_upload_keys(st, w, 0, n, padded, 0, &st->lo, &st->hi));
    for (int k = 0; k < 2; k++) {
        TRY(bpx__cl_dbuf_reserve(st, &st->keys[k], (size_t)n * sizeof(cl_uint)));
        TRY(bpx__cl_dbuf_reserve(st, &st->values[k], (size_t)n * sizeof(cl_uint)));
    }
    cl_uint n_arg = n;
    const kernel_arg key_args[] = {ARG(st->lo.mem), ARG(n_arg), ARG(st->keys[0].mem),
                                   ARG(st->values[0].mem)};
    TRY(bpx__cl_launch(st, K_SWEEP_KEYS, n, 0, 4, key_args));
    int sorted;
    TRY(radix_sort(st, st->keys, st->values, n, 32, &sorted));
    cl_mem index = st->values[sorted].mem;
    TRY(bpx__cl_dbuf_reserve(st, &st->sorted_lo, (size_t)padded * 16));
    TRY(bpx__cl_dbuf_reserve(st, &st->sorted_hi, (size_t)padded * 16));
    cl_uint padded_arg = padded;
    const kernel_arg gather_args[] = {
        ARG(st->lo.mem),        ARG(st->hi.mem),       ARG(index), ARG(n_arg), ARG(padded_arg),
        ARG(st->sorted_lo.mem), ARG(st->sorted_hi.mem)};
    TRY(bpx__cl_launch(st, K_SWEEP_GATHER, padded, 0, 7, gather_args));
    TRY(bpx__cl_dbuf_reserve(st, &st->counts, (size_t)padded * sizeof(cl_uint)));
    TRY(bpx__cl_dbuf_reserve(st, &st->offsets, (size_t)n * sizeof(cl_ulong)));
    const kernel_arg count_args[] = {ARG(st->sorted_lo.mem), ARG(st->sorted_hi.mem),
                                     ARG(padded_arg), ARG(st->counts.mem)};
    TRY(bpx__cl_launch(st, K_SWEEP_COUNT, padded, st->tile, 4, count_args));
    TRY(scan(st, st->counts.mem, n, st->offsets.mem, 1));
    uint64_t total;
    TRY(bpx__cl_read_register(st, 1, &total));
    if (total == 0) {
        st->counters.sweep_cycles++;
        return BPX_OK;
    }
    // The pairs are sorted too: two sets of (i, j) planes and the packed result.
    uint64_t need = total * (4 * sizeof(cl_uint) + sizeof(bpx_pair));
    uint64_t held =
        st->pi[0].size + st->pi[1].size + st->pj[0].size + st->pj[1].size + st->pairs.size;
    if (total > UINT32_MAX)
        return BPX_ERR_TOO_MANY_PAIRS; // the device sort's keys and offsets are 32-bit
    if (total * sizeof(bpx_pair) > st->dev->max_alloc ||
        st->used - held + need > st->limit)
        return BPX_ERR_DEVICE_MEMORY;
    for (int k = 0; k < 2; k++) {
        TRY(bpx__cl_dbuf_reserve(st, &st->pi[k], total * sizeof(cl_uint)));
        TRY(bpx__cl_dbuf_reserve(st, &st->pj[k], total * sizeof(cl_uint)));
    }
    TRY(bpx__cl_dbuf_reserve(st, &st->pairs, total * sizeof(bpx_pair)));
    cl_ulong capacity = total;
    const kernel_arg write_args[] = {
        ARG(st->sorted_lo.mem), ARG(st->sorted_hi.mem), ARG(index),         ARG(n_arg),
        ARG(padded_arg),        ARG(st->offsets.mem),   ARG(st->pi[0].mem), ARG(st->pj[0].mem),
        ARG(capacity)};
    TRY(bpx__cl_launch(st, K_SWEEP_WRITE, padded, st->tile, 9, write_args));
    // (i, j) order: stable sort by j, then by i.
    unsigned bits = bits_for(n - 1);
    int by_j;
    TRY(radix_sort(st, st->pj, st->pi, (uint32_t)total, bits, &by_j));
    dbuf keys[2] = {st->pi[by_j], st->pi[1 - by_j]};
    dbuf values[2] = {st->pj[by_j], st->pj[1 - by_j]};
    int by_i;
    TRY(radix_sort(st, keys, values, (uint32_t)total, bits, &by_i));
    const kernel_arg pack_args[] = {ARG(keys[by_i].mem), ARG(values[by_i].mem), ARG(capacity),
                                    ARG(st->pairs.mem)};
    TRY(bpx__cl_launch(st, K_SWEEP_INTERLEAVE, (size_t)total, 0, 4, pack_args));
    TRY(bpx__cl_read_pairs(st, st->pairs.mem, (size_t)total, &block->hits));
    st->counters.sweep_cycles++;
    return BPX_OK;
}
