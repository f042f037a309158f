// The opencl backend's sort and sweep, for mid-sized sets: a device radix sort on min x (sort.c),
// a tiled sweep, and the pairs put in (i, j) order by two more radix sorts.

#include "state.h"

// ---------------------------------------------------------------------------------------------
// Sort and sweep

// Keys sorted by min x (*index: the box at each sorted position) and gathered in that order,
// each position's pairs counted and the counts scanned: the total into register 1.
static bpx_status count_positions(bpx_cl_state *st, const bpx_cycle *cycle, cl_mem *index)
{
    uint32_t n = cycle->n;
    uint32_t padded = (uint32_t)round_up(n, st->tile);
    TRY(bpx__cl_upload_keys(st, cycle, 0, n, padded, 0, &st->lo, &st->hi));
    for (int k = 0; k < 2; k++) {
        TRY(bpx__cl_dbuf_reserve(st, &st->keys[k], (size_t)n * sizeof(cl_uint)));
        TRY(bpx__cl_dbuf_reserve(st, &st->values[k], (size_t)n * sizeof(cl_uint)));
    }
    cl_uint n_arg = n;
    const bpx_cl_arg key_args[] = {ARG(st->lo.mem), ARG(n_arg), ARG(st->keys[0].mem),
                                   ARG(st->values[0].mem)};
    TRY(bpx__cl_launch(st, K_SWEEP_KEYS, n, 0, 4, key_args));
    int sorted;
    TRY(bpx__cl_radix_sort(st, st->keys, st->values, n, 32, &sorted));
    *index = st->values[sorted].mem;
    TRY(bpx__cl_dbuf_reserve(st, &st->sorted_lo, (size_t)padded * 16));
    TRY(bpx__cl_dbuf_reserve(st, &st->sorted_hi, (size_t)padded * 16));
    cl_uint padded_arg = padded;
    const bpx_cl_arg gather_args[] = {
        ARG(st->lo.mem), ARG(st->hi.mem),        ARG(*index),           ARG(n_arg),
        ARG(padded_arg), ARG(st->sorted_lo.mem), ARG(st->sorted_hi.mem)};
    TRY(bpx__cl_launch(st, K_SWEEP_GATHER, padded, 0, 7, gather_args));
    TRY(bpx__cl_dbuf_reserve(st, &st->counts, (size_t)padded * sizeof(cl_uint)));
    TRY(bpx__cl_dbuf_reserve(st, &st->offsets, (size_t)n * sizeof(cl_ulong)));
    const bpx_cl_arg count_args[] = {ARG(st->sorted_lo.mem), ARG(st->sorted_hi.mem),
                                     ARG(padded_arg), ARG(st->counts.mem)};
    TRY(bpx__cl_launch(st, K_SWEEP_COUNT, padded, st->tile, 4, count_args));
    return bpx__cl_scan(st, st->counts.mem, n, st->offsets.mem, 1);
}

// Room for `pairs` pairs: two sets of (i, j) planes and the packed result; DEVICE_MEMORY
// (nothing changed) past the memory limit.
static bpx_status reserve_pairs(bpx_cl_state *st, uint64_t pairs)
{
    uint64_t need = pairs * (4 * sizeof(cl_uint) + sizeof(bpx_pair));
    uint64_t held =
        st->pi[0].size + st->pi[1].size + st->pj[0].size + st->pj[1].size + st->pairs.size;
    if (pairs * sizeof(bpx_pair) > st->dev->max_alloc || st->used - held + need > st->limit)
        return BPX_ERR_DEVICE_MEMORY;
    for (int k = 0; k < 2; k++) {
        TRY(bpx__cl_dbuf_reserve(st, &st->pi[k], pairs * sizeof(cl_uint)));
        TRY(bpx__cl_dbuf_reserve(st, &st->pj[k], pairs * sizeof(cl_uint)));
    }
    return bpx__cl_dbuf_reserve(st, &st->pairs, pairs * sizeof(bpx_pair));
}

// Each position's pairs written from its offset (those at `capacity` or beyond dropped), put
// in (i, j) order by two stable radix sorts of the first `count` (by j, then by i) and packed
// into st->pairs.
static bpx_status order(bpx_cl_state *st, uint32_t n, cl_mem index, cl_ulong capacity,
                        uint32_t count)
{
    cl_uint n_arg = n, padded_arg = (cl_uint)round_up(n, st->tile);
    const bpx_cl_arg write_args[] = {
        ARG(st->sorted_lo.mem), ARG(st->sorted_hi.mem), ARG(index),         ARG(n_arg),
        ARG(padded_arg),        ARG(st->offsets.mem),   ARG(st->pi[0].mem), ARG(st->pj[0].mem),
        ARG(capacity)};
    TRY(bpx__cl_launch(st, K_SWEEP_WRITE, padded_arg, st->tile, 9, write_args));
    unsigned bits = bpx__cl_bits_for(n - 1);
    int by_j;
    TRY(bpx__cl_radix_sort(st, st->pj, st->pi, count, bits, &by_j));
    bpx_cl_buffer keys[2] = {st->pi[by_j], st->pi[1 - by_j]};
    bpx_cl_buffer values[2] = {st->pj[by_j], st->pj[1 - by_j]};
    int by_i;
    TRY(bpx__cl_radix_sort(st, keys, values, count, bits, &by_i));
    cl_ulong count_arg = count;
    const bpx_cl_arg pack_args[] = {ARG(keys[by_i].mem), ARG(values[by_i].mem), ARG(count_arg),
                                    ARG(st->pairs.mem)};
    return bpx__cl_launch(st, K_SWEEP_INTERLEAVE, count, 0, 4, pack_args);
}

// Returns BPX_ERR_DEVICE_MEMORY, before any pair is written, when the pairs would not fit:
// the caller then runs brute force, which can read pairs out in windows.
bpx_status bpx__cl_sweep_all(bpx_cl_state *st, const bpx_cycle *cycle, bpx_block *block)
{
    cl_mem index;
    TRY(count_positions(st, cycle, &index));
    uint64_t total;
    TRY(bpx__cl_read_register(st, 1, &total));
    if (total == 0) {
        st->counters.sweep_cycles++;
        return BPX_OK;
    }
    if (total > UINT32_MAX)
        return BPX_ERR_TOO_MANY_PAIRS; // the device sort's keys and offsets are 32-bit
    TRY(reserve_pairs(st, total));
    TRY(order(st, cycle->n, index, total, (uint32_t)total));
    TRY(bpx__cl_read_pairs(st, st->pairs.mem, (size_t)total, &block->hits));
    st->counters.sweep_cycles++;
    return BPX_OK;
}

// A device-resident cycle (resident.c; n >= 2): room for `need` pairs or DEVICE_MEMORY before
// anything is enqueued; as the tree's, the sorts run over the whole room (*capacity = need),
// whose places past the count hold all-ones ends (they sort last: no box number reaches
// 2^bits - 1 as an i), and the count goes to `count` from register 1.
bpx_status bpx__cl_sweep_resident(bpx_cl_state *st, const bpx_cycle *cycle, uint64_t need,
                                  cl_mem count, cl_ulong *capacity)
{
    if (need > UINT32_MAX)
        return BPX_ERR_DEVICE_MEMORY;
    TRY(reserve_pairs(st, need));
    *capacity = need;
    cl_mem index;
    TRY(count_positions(st, cycle, &index));
    TRY(bpx__cl_copy(st, st->registers.mem, 1 * sizeof(cl_ulong), count, sizeof(cl_ulong)));
    TRY(bpx__cl_fill(st, st->pi[0].mem, 0xFF, need * sizeof(cl_uint)));
    TRY(bpx__cl_fill(st, st->pj[0].mem, 0xFF, need * sizeof(cl_uint)));
    TRY(order(st, cycle->n, index, need, (uint32_t)need));
    st->counters.sweep_cycles++;
    return BPX_OK;
}
