// The opencl backend's sort and sweep, for mid-sized sets: a device radix sort on min x (sort.c),
// a tiled sweep, and the pairs put in (i, j) order by two more radix sorts.

#include "state.h"

// ---------------------------------------------------------------------------------------------
// Sort and sweep

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
    TRY(bpx__cl_radix_sort(st, st->keys, st->values, n, 32, &sorted));
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
    TRY(bpx__cl_scan(st, st->counts.mem, n, st->offsets.mem, 1));
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
    unsigned bits = bpx__cl_bits_for(n - 1);
    int by_j;
    TRY(bpx__cl_radix_sort(st, st->pj, st->pi, (uint32_t)total, bits, &by_j));
    dbuf keys[2] = {st->pi[by_j], st->pi[1 - by_j]};
    dbuf values[2] = {st->pj[by_j], st->pj[1 - by_j]};
    int by_i;
    TRY(bpx__cl_radix_sort(st, keys, values, (uint32_t)total, bits, &by_i));
    const kernel_arg pack_args[] = {ARG(keys[by_i].mem), ARG(values[by_i].mem), ARG(capacity),
                                    ARG(st->pairs.mem)};
    TRY(bpx__cl_launch(st, K_SWEEP_INTERLEAVE, (size_t)total, 0, 4, pack_args));
    TRY(bpx__cl_read_pairs(st, st->pairs.mem, (size_t)total, &block->hits));
    st->counters.sweep_cycles++;
    return BPX_OK;
}
