// The opencl backend's tree, for large sets: a linear BVH over the boxes' Morton-ordered centres
// (Karras 2012) built every cycle, walked once per box over the later Morton positions, the pairs
// appended as 64-bit keys and radix sorted into (i, j) order (kernels/tree.cl, kernels/lbvh.h).
// At constant density each box's walk, from its leaf up, tests about twenty nodes, growing only
// with the tree's depth (half a test per level), whatever the boxes' sizes, where the sweep's
// candidates per box grow like n^(2/3).

#include <string.h>

#include "state.h"

// Device bytes of the pairs' stages for `keys` pair keys: two key buffers (the sort's two
// sides) and the packed pairs.
static uint64_t pair_bytes(uint64_t keys)
{
    return keys * (2 * sizeof(cl_ulong) + sizeof(bpx_pair));
}

// Makes room for `keys` pair keys and their pairs; DEVICE_MEMORY (nothing changed) when that
// passes the limit, so that the caller can fall back to brute force's windows.
static bpx_status reserve_pairs(bpx_cl_state *st, uint64_t keys)
{
    uint64_t held = st->pair_keys[0].size + st->pair_keys[1].size + st->pairs.size;
    if (keys > UINT32_MAX || keys * sizeof(cl_ulong) > st->dev->max_alloc ||
        st->used - held + pair_bytes(keys) > st->limit)
        return BPX_ERR_DEVICE_MEMORY;
    for (int k = 0; k < 2; k++)
        TRY(bpx__cl_dbuf_reserve(st, &st->pair_keys[k], keys * sizeof(cl_ulong)));
    return bpx__cl_dbuf_reserve(st, &st->pairs, keys * sizeof(bpx_pair));
}

// The pair keys that all three pair buffers have room for. reserve_pairs grows them one by one,
// so a failed creation can leave the first grown and the others not: the walks and the sort
// must then see the smallest, or the sort's passes write past the second key buffer.
static uint64_t pair_room(const bpx_cl_state *st)
{
    uint64_t room = st->pair_keys[0].size / sizeof(cl_ulong);
    uint64_t other = st->pair_keys[1].size / sizeof(cl_ulong);
    uint64_t pairs = st->pairs.size / sizeof(bpx_pair);
    room = other < room ? other : room;
    return pairs < room ? pairs : room;
}

// tree_small holds the scene's bounds (six words) and the walks' pair counter (two: the count and
// a wrap flag); bpx_tree_reset clears them.
static bpx_status reset(bpx_cl_state *st)
{
    const bpx_cl_arg args[] = {ARG(st->tree_small.mem)};
    return bpx__cl_launch(st, K_TREE_RESET, 1, 1, 1, args);
}

// The walks, appending pair keys into pair_keys[0] up to `capacity`.
static bpx_status walk(bpx_cl_state *st, cl_uint n, cl_uint bits, cl_mem ids, cl_ulong capacity)
{
    const bpx_cl_arg args[] = {ARG(st->sorted_lo.mem),
                               ARG(st->sorted_hi.mem),
                               ARG(n),
                               ARG(ids),
                               ARG(st->leaf_parent.mem),
                               ARG(st->node_parent.mem),
                               ARG(st->nodes.mem),
                               ARG(bits),
                               ARG(st->pair_keys[0].mem),
                               ARG(capacity),
                               ARG(st->tree_small.mem),
                               ARG(st->walk_tests.mem)};
    return bpx__cl_launch(st, K_TREE_WALK, n - 1, 0, 12, args);
}

// Everything up to the walks (n >= 2, keys uploaded): the bounds and the pair counter reset,
// the Morton codes sorted with their boxes (*ids: the box at each position), the keys gathered
// in that order, the nodes built and refitted. *bits: the bits of a pair key's j.
static bpx_status build(bpx_cl_state *st, uint32_t n, cl_mem *ids, cl_uint *bits)
{
    uint32_t padded = (uint32_t)round_up(n, st->tile);
    size_t nodes = (size_t)n - 1;
    for (int k = 0; k < 2; k++) {
        TRY(bpx__cl_dbuf_reserve(st, &st->keys[k], (size_t)n * sizeof(cl_uint)));
        TRY(bpx__cl_dbuf_reserve(st, &st->values[k], (size_t)n * sizeof(cl_uint)));
    }
    TRY(bpx__cl_dbuf_reserve(st, &st->leaf_parent, (size_t)n * sizeof(cl_uint)));
    TRY(bpx__cl_dbuf_reserve(st, &st->node_parent, nodes * sizeof(cl_uint)));
    TRY(bpx__cl_dbuf_reserve(st, &st->flags, nodes * sizeof(cl_uint)));
    // Two child slots per node, eight keys each (kernels/lbvh.h, BPX_LBVH_SLOT).
    TRY(bpx__cl_dbuf_reserve(st, &st->nodes, nodes * 2 * 8 * sizeof(cl_uint)));
    TRY(bpx__cl_dbuf_reserve(st, &st->tree_small, 8 * sizeof(cl_uint)));
    TRY(bpx__cl_dbuf_reserve(st, &st->walk_tests, nodes * sizeof(cl_uint)));

    cl_uint n_arg = n;
    cl_mem small = st->tree_small.mem;
    TRY(reset(st));
    size_t wg = st->dev->scan_wg;
    size_t per_group = wg * 16; // BPX_TREE_ITEMS (tree.cl) boxes per item
    size_t groups = (n + per_group - 1) / per_group;
    const bpx_cl_arg bounds_args[] = {ARG(st->lo.mem), ARG(st->hi.mem), ARG(n_arg), ARG(small)};
    TRY(bpx__cl_launch(st, K_TREE_BOUNDS, groups * wg, wg, 4, bounds_args));
    const bpx_cl_arg code_args[] = {ARG(st->lo.mem), ARG(st->hi.mem),      ARG(n_arg),
                                    ARG(small),      ARG(st->keys[0].mem), ARG(st->values[0].mem)};
    TRY(bpx__cl_launch(st, K_TREE_CODES, n, 0, 6, code_args));
    int sorted;
    TRY(bpx__cl_radix_sort(st, st->keys, st->values, n, 32, &sorted));
    cl_mem codes = st->keys[sorted].mem;
    *ids = st->values[sorted].mem;
    // The keys in Morton order: the refit and the walks then read neighbouring boxes.
    TRY(bpx__cl_dbuf_reserve(st, &st->sorted_lo, (size_t)padded * 16));
    TRY(bpx__cl_dbuf_reserve(st, &st->sorted_hi, (size_t)padded * 16));
    cl_uint padded_arg = padded;
    const bpx_cl_arg gather_args[] = {
        ARG(st->lo.mem),        ARG(st->hi.mem),       ARG(*ids), ARG(n_arg), ARG(padded_arg),
        ARG(st->sorted_lo.mem), ARG(st->sorted_hi.mem)};
    TRY(bpx__cl_launch(st, K_SWEEP_GATHER, padded, 0, 7, gather_args));
    const bpx_cl_arg build_args[] = {ARG(codes), ARG(n_arg), ARG(st->leaf_parent.mem),
                                     ARG(st->node_parent.mem), ARG(st->flags.mem)};
    TRY(bpx__cl_launch(st, K_TREE_BUILD, nodes, 0, 5, build_args));
    const bpx_cl_arg refit_args[] = {
        ARG(st->sorted_lo.mem),   ARG(st->sorted_hi.mem),   ARG(n_arg),
        ARG(st->leaf_parent.mem), ARG(st->node_parent.mem), ARG(st->nodes.mem),
        ARG(st->flags.mem)};
    TRY(bpx__cl_launch(st, K_TREE_REFIT, n, 0, 7, refit_args));
    *bits = bpx__cl_bits_for(n - 1);
    return BPX_OK;
}

// The first `count` pair keys sorted ((i, j) order: 2 * bits bits) and unpacked into st->pairs.
static bpx_status order(bpx_cl_state *st, uint32_t count, cl_uint bits)
{
    int by_key;
    TRY(bpx__cl_radix_sort64(st, st->pair_keys, count, 2 * bits, &by_key));
    cl_uint count_arg = count;
    const bpx_cl_arg unpack_args[] = {ARG(st->pair_keys[by_key].mem), ARG(count_arg), ARG(bits),
                                      ARG(st->pairs.mem)};
    return bpx__cl_launch(st, K_TREE_UNPACK, count, 0, 4, unpack_args);
}

bpx_status bpx__cl_tree_all(bpx_cl_state *st, const bpx_cycle *cycle, bpx_block *block)
{
    uint32_t n = cycle->n;
    uint32_t padded = (uint32_t)round_up(n, st->tile);
    TRY(bpx__cl_upload_keys(st, cycle, 0, n, padded, 0, &st->lo, &st->hi));
    if (n < 2) {
        st->counters.tree_cycles++;
        return BPX_OK;
    }
    cl_mem ids;
    cl_uint bits;
    TRY(build(st, n, &ids, &bits));
    if (pair_room(st) < st->first_pair_capacity)
        TRY(reserve_pairs(st, st->first_pair_capacity));
    TRY(walk(st, n, bits, ids, pair_room(st)));
    // The walks' bounds tests (the cycle's statistics) summed into register 3, read back behind
    // the count: one wait for both.
    TRY(bpx__cl_sum(st, st->walk_tests.mem, n - 1, 3));
    char *test_register = (char *)st->reg.host + 3 * sizeof(cl_ulong);
    TRY(bpx__cl_read_later(st, st->registers.mem, 3 * sizeof(cl_ulong), sizeof(cl_ulong),
                           test_register));
    // The count, read once: room for every pair, or more room and the walks again.
    cl_uint found[8];
    TRY(bpx__cl_read_buffer(st, st->tree_small.mem, 0, sizeof found, found));
    cl_ulong tests;
    memcpy(&tests, test_register, sizeof tests); // the in-order queue read it before `found`
    st->tests += tests;
    uint64_t total = found[6];
    bool wrapped = found[7] != 0;
    if (wrapped)
        return BPX_ERR_DEVICE_MEMORY; // 2^32 pairs or more: brute force reads them in windows
    if (total > pair_room(st)) {
        TRY(reserve_pairs(st, total));
        TRY(reset(st));
        TRY(walk(st, n, bits, ids, pair_room(st)));
        st->counters.emit_reruns++;
    }
    if (total > 0) {
        TRY(order(st, (uint32_t)total, bits));
        TRY(bpx__cl_read_pairs(st, st->pairs.mem, (size_t)total, &block->hits));
    }
    st->counters.tree_cycles++;
    return BPX_OK;
}

// A device-resident cycle (resident.c; n >= 2): room for `need` pairs or DEVICE_MEMORY before
// anything is enqueued. The count cannot come back inside the cycle, so the sort's length is
// the room (*capacity = need), known now: the key buffer is filled with all-ones keys first,
// which sort after every pair, and the walks write theirs over the start of it. The count goes
// to `count` (bpx_tree_count: all ones when the counter wrapped); the pairs past it hold
// padding.
bpx_status bpx__cl_tree_resident(bpx_cl_state *st, const bpx_cycle *cycle, uint64_t need,
                                 cl_mem count, cl_ulong *capacity)
{
    uint32_t n = cycle->n;
    TRY(reserve_pairs(st, need));
    *capacity = need;
    TRY(bpx__cl_upload_keys(st, cycle, 0, n, (uint32_t)round_up(n, st->tile), 0, &st->lo, &st->hi));
    cl_mem ids;
    cl_uint bits;
    TRY(build(st, n, &ids, &bits));
    TRY(bpx__cl_fill(st, st->pair_keys[0].mem, 0xFF, need * sizeof(cl_ulong)));
    TRY(walk(st, n, bits, ids, need));
    const bpx_cl_arg count_args[] = {ARG(st->tree_small.mem), ARG(count)};
    TRY(bpx__cl_launch(st, K_TREE_COUNT, 1, 1, 2, count_args));
    TRY(order(st, (uint32_t)need, bits));
    st->counters.tree_cycles++;
    return BPX_OK;
}
