// The opencl backend's brute-force comparator: tiles in local memory, per-row counts, a scan
// and ordered writes; one bpx__cl_launch for small sets; blocks streamed past the memory limit.

#include <string.h>

#include "core/alloc.h"
#include "state.h"

// ---------------------------------------------------------------------------------------------
// Brute force

// The first pair buffer: def.opencl_pair_capacity pairs (default 65536), or less when the
// memory limit is tight (down to 1024 pairs; pairs beyond are read out in windows).
static bpx_status reserve_pair_window(bpx_cl_state *st)
{
    size_t want = st->first_pair_capacity;
    for (;;) {
        bpx_status status = bpx__cl_dbuf_reserve(st, &st->pairs, want * sizeof(bpx_pair));
        if (status != BPX_ERR_DEVICE_MEMORY || want <= 1024)
            return status;
        want /= 2;
    }
}

// Rows (keys lo/hi, padded_rows of them, numbered from ia) against columns (lo_b/hi_b,
// padded_cols, numbered from jb): every pair with j > i.
typedef struct rows_cols {
    cl_mem lo, hi, lo_b, hi_b;
    cl_uint padded_rows, ia, padded_cols, jb;
} rows_cols;

// The arguments bpx_brute_count and bpx_brute_emit start with: the rows, the columns, each
// row's count and stash, each group's sum and long-row flag.
enum { ROW_ARGS = 11 };
static void row_args(bpx_cl_state *st, const rows_cols *rc, bpx_cl_arg *args)
{
    const bpx_cl_arg shared[ROW_ARGS] = {ARG(rc->lo),
                                         ARG(rc->hi),
                                         ARG(rc->ia),
                                         ARG(rc->lo_b),
                                         ARG(rc->hi_b),
                                         ARG(rc->padded_cols),
                                         ARG(rc->jb),
                                         ARG(st->row_count.mem),
                                         ARG(st->stash.mem),
                                         ARG(st->group_sum.mem),
                                         ARG(st->group_long.mem)};
    memcpy(args, shared, sizeof shared);
}

// Each row's hits counted, the groups' sums scanned, the total into reg[slot].
static bpx_status count_rows(bpx_cl_state *st, const rows_cols *rc, cl_mem reg, cl_uint slot)
{
    unsigned tile = st->tile;
    size_t groups = rc->padded_rows / tile;
    TRY(bpx__cl_dbuf_reserve(st, &st->row_count, (size_t)rc->padded_rows * sizeof(cl_uint)));
    TRY(bpx__cl_dbuf_reserve(st, &st->stash,
                             (size_t)rc->padded_rows * BPX_CL_STASH * sizeof(cl_uint)));
    TRY(bpx__cl_dbuf_reserve(st, &st->group_sum, groups * sizeof(cl_ulong)));
    TRY(bpx__cl_dbuf_reserve(st, &st->group_long, groups * sizeof(cl_uint)));
    cl_uint groups_arg = (cl_uint)groups;
    bpx_cl_arg count_args[ROW_ARGS];
    row_args(st, rc, count_args);
    TRY(bpx__cl_launch(st, K_BRUTE_COUNT, rc->padded_rows, tile, ROW_ARGS, count_args));
    const bpx_cl_arg sums_args[] = {ARG(st->group_sum.mem), ARG(groups_arg), ARG(reg), ARG(slot)};
    TRY(bpx__cl_launch(st, K_SCAN_SUMS, st->dev->scan_wg, st->dev->scan_wg, 4, sums_args));
    // Tests made, as the kernel walks them: each group from its first tile to the end.
    for (size_t g = 0; g < groups; g++) {
        uint64_t first = (uint64_t)rc->ia + g * tile + 1;
        uint64_t start = first <= rc->jb ? 0 : (first - rc->jb) / tile * tile;
        if (start < rc->padded_cols)
            st->tests += (rc->padded_cols - start) * (uint64_t)tile;
    }
    return BPX_OK;
}

// The pairs whose place lies in [window, window + capacity) into st->pairs (after count_rows).
static bpx_status emit_rows(bpx_cl_state *st, const rows_cols *rc, cl_ulong window,
                            cl_ulong capacity)
{
    bpx_cl_arg emit_args[ROW_ARGS + 3];
    row_args(st, rc, emit_args);
    emit_args[ROW_ARGS] = ARG(st->pairs.mem);
    emit_args[ROW_ARGS + 1] = ARG(window);
    emit_args[ROW_ARGS + 2] = ARG(capacity);
    return bpx__cl_launch(st, K_BRUTE_EMIT, rc->padded_rows, st->tile, ROW_ARGS + 3, emit_args);
}

// Every pair of rc appended to out in (i, j) order.
static bpx_status brute_block(bpx_cl_state *st, const rows_cols *rc, bpx_pair_list *out)
{
    cl_uint slot = 0;
    TRY(count_rows(st, rc, st->registers.mem, slot));
    // Emit at once into the buffer there is (the count is not known yet), then read the
    // register: when the buffer was too small, grow it (or, past the memory limit, read the
    // pairs out in windows) and emit again. No pair is lost either way.
    if (st->pairs.size == 0)
        TRY(reserve_pair_window(st));
    cl_ulong window = 0, capacity = st->pairs.size / sizeof(bpx_pair);
    TRY(emit_rows(st, rc, window, capacity));
    uint64_t total;
    TRY(bpx__cl_read_register(st, slot, &total));
    if (total > capacity) {
        // Too small: grow to the exact need and emit again; past the memory limit keep the
        // buffer, which holds the first window already, and read the rest window by window.
        bpx_status grown = bpx__cl_dbuf_reserve(st, &st->pairs, total * sizeof(bpx_pair));
        if (grown == BPX_OK) {
            st->counters.emit_reruns++;
            capacity = st->pairs.size / sizeof(bpx_pair);
            TRY(emit_rows(st, rc, window, capacity));
        } else if (grown != BPX_ERR_DEVICE_MEMORY) {
            return grown;
        }
    }
    for (;;) {
        size_t count = total - window < capacity ? (size_t)(total - window) : (size_t)capacity;
        TRY(bpx__cl_read_pairs(st, st->pairs.mem, count, out));
        window += count;
        if (window >= total)
            return BPX_OK;
        st->counters.pair_windows++;
        TRY(emit_rows(st, rc, window, capacity));
    }
}

// The whole set against itself (keys in st->lo / st->hi, padded).
static rows_cols whole_set(const bpx_cl_state *st, uint32_t padded)
{
    return (rows_cols){st->lo.mem, st->hi.mem, st->lo.mem, st->hi.mem, padded, 0, padded, 0};
}

// bpx_brute_small over n boxes into st->pairs up to capacity; the total into reg[slot].
static bpx_status launch_small(bpx_cl_state *st, cl_uint n, cl_ulong capacity, cl_mem reg,
                               cl_uint slot)
{
    const bpx_cl_arg args[] = {ARG(st->lo.mem), ARG(st->hi.mem), ARG(n),   ARG(st->pairs.mem),
                               ARG(capacity),   ARG(reg),        ARG(slot)};
    return bpx__cl_launch(st, K_BRUTE_SMALL, st->dev->small_wg, st->dev->small_wg, 7, args);
}

// Everything on the device at once.
bpx_status bpx__cl_brute_all(bpx_cl_state *st, const bpx_cycle *cycle, bpx_block *block)
{
    uint32_t padded = (uint32_t)round_up(cycle->n, st->tile);
    TRY(bpx__cl_upload_keys(st, cycle, 0, cycle->n, padded, 0, &st->lo, &st->hi));
    st->counters.brute_cycles++;
    rows_cols rc = whole_set(st, padded);
    return brute_block(st, &rc, &block->hits);
}

// Small sets: one bpx__cl_launch (bpx_brute_small), then the count and the pairs read back
// together, as many pairs as last cycle's count and a quarter more (a second read when that was
// short).
bpx_status bpx__cl_brute_small(bpx_cl_state *st, const bpx_cycle *cycle, bpx_block *block)
{
    uint32_t n = cycle->n;
    uint32_t padded = (uint32_t)round_up(n, st->tile);
    TRY(bpx__cl_upload_keys(st, cycle, 0, n, padded, 0, &st->lo, &st->hi));
    if (st->pairs.size == 0)
        TRY(reserve_pair_window(st));
    cl_ulong capacity = st->pairs.size / sizeof(bpx_pair);
    TRY(launch_small(st, n, capacity, st->registers.mem, 0));
    st->tests += (uint64_t)n * (n - 1) / 2;
    st->counters.brute_cycles++;
    uint64_t guess = st->last_pairs + st->last_pairs / 4 + 64;
    size_t first = (size_t)(guess < capacity ? guess : capacity);
    TRY(bpx__cl_pinned_reserve(st, &st->down, first * sizeof(bpx_pair)));
    TRY(bpx__cl_read_later(st, st->registers.mem, 0, sizeof(cl_ulong), st->reg.host));
    TRY(bpx__cl_read_later(st, st->pairs.mem, 0, first * sizeof(bpx_pair), st->down.host));
    CL_CHECK(st, clFinish(st->queue), "clFinish");
    cl_ulong total;
    memcpy(&total, st->reg.host, sizeof total);
    if (total > capacity) { // the buffer was too small: grow it to the need and run again
        bpx_status grown = bpx__cl_dbuf_reserve(st, &st->pairs, total * sizeof(bpx_pair));
        if (grown == BPX_ERR_DEVICE_MEMORY) {
            // Past the memory limit: the tiled path reads the pairs in windows, from now on
            // (its own buffers first, then a window in the room left).
            st->small_off = true;
            bpx__cl_dbuf_release(st, &st->pairs);
            return bpx__cl_brute_all(st, cycle, block);
        }
        if (grown != BPX_OK)
            return grown;
        st->counters.emit_reruns++;
        capacity = total;
        TRY(launch_small(st, n, capacity, st->registers.mem, 0));
    }
    if (total > first) // the guess was short: read them all
        return bpx__cl_read_pairs(st, st->pairs.mem, (size_t)total, &block->hits);
    if (!bpx__list_reserve(&block->hits, (size_t)total))
        return BPX_ERR_OUT_OF_MEMORY;
    memcpy(block->hits.pairs, st->down.host, (size_t)total * sizeof(bpx_pair));
    block->hits.count = (size_t)total;
    return BPX_OK;
}

// The paper's "streaming AABBs between CPU and FPGA": blocks of `block_boxes` boxes; each row
// block stays on the device while every later column block passes through. A row block's pairs
// arrive column block by column block, and are put back in row order on the host (stable
// counting sort by row), so the stream stays ordered by (i, j).
bpx_status bpx__cl_brute_streamed(bpx_cl_state *st, const bpx_cycle *cycle, bpx_block *block,
                                  uint32_t block_boxes)
{
    uint32_t n = cycle->n;
    uint32_t blocks = (n + block_boxes - 1) / block_boxes;
    size_t region = 6 * (size_t)block_boxes * sizeof(float);
    TRY(bpx__cl_pinned_reserve(st, &st->up, 2 * region));
    // Every block-sized buffer first, then the pair window takes what is left.
    size_t keys = (size_t)block_boxes * 16, groups = block_boxes / st->tile;
    TRY(bpx__cl_dbuf_reserve(st, &st->input, 2 * region));
    TRY(bpx__cl_dbuf_reserve(st, &st->lo, keys));
    TRY(bpx__cl_dbuf_reserve(st, &st->hi, keys));
    TRY(bpx__cl_dbuf_reserve(st, &st->lo_b, keys));
    TRY(bpx__cl_dbuf_reserve(st, &st->hi_b, keys));
    TRY(bpx__cl_dbuf_reserve(st, &st->row_count, (size_t)block_boxes * sizeof(cl_uint)));
    TRY(bpx__cl_dbuf_reserve(st, &st->stash, (size_t)block_boxes * BPX_CL_STASH * sizeof(cl_uint)));
    TRY(bpx__cl_dbuf_reserve(st, &st->group_sum, groups * sizeof(cl_ulong)));
    TRY(bpx__cl_dbuf_reserve(st, &st->group_long, groups * sizeof(cl_uint)));
    if (st->pairs.size == 0)
        TRY(reserve_pair_window(st));
    if (st->row_hist_count < (size_t)block_boxes + 1) {
        bpx__free(st->row_hist, st->row_hist_count * sizeof(uint32_t));
        st->row_hist_count = 0;
        if (!(st->row_hist = bpx__alloc(((size_t)block_boxes + 1) * sizeof(uint32_t))))
            return BPX_ERR_OUT_OF_MEMORY;
        st->row_hist_count = (size_t)block_boxes + 1;
    }
    bpx_pair_list *stage = &block->stage;
    for (uint32_t bi = 0; bi < blocks; bi++) {
        uint32_t ia = bi * block_boxes;
        uint32_t rows = n - ia < block_boxes ? n - ia : block_boxes;
        uint32_t padded_rows = (uint32_t)round_up(rows, st->tile);
        TRY(bpx__cl_upload_keys(st, cycle, ia, rows, padded_rows, 0, &st->lo, &st->hi));
        st->counters.streamed_blocks++;
        stage->count = 0;
        for (uint32_t bj = bi; bj < blocks; bj++) {
            uint32_t jb = bj * block_boxes;
            uint32_t cols = n - jb < block_boxes ? n - jb : block_boxes;
            uint32_t padded_cols = (uint32_t)round_up(cols, st->tile);
            cl_mem lo_b = st->lo.mem, hi_b = st->hi.mem;
            if (bj != bi) {
                TRY(bpx__cl_upload_keys(st, cycle, jb, cols, padded_cols, region, &st->lo_b,
                                        &st->hi_b));
                st->counters.streamed_blocks++;
                lo_b = st->lo_b.mem;
                hi_b = st->hi_b.mem;
            }
            rows_cols rc = {st->lo.mem, st->hi.mem, lo_b, hi_b, padded_rows, ia, padded_cols, jb};
            TRY(brute_block(st, &rc, stage));
        }
        // Stable counting sort of the row block's pairs by row.
        uint32_t *start = st->row_hist;
        memset(start, 0, ((size_t)rows + 1) * sizeof(uint32_t));
        for (size_t k = 0; k < stage->count; k++)
            start[stage->pairs[k].i - ia + 1]++;
        for (uint32_t r = 0; r < rows; r++)
            start[r + 1] += start[r];
        if (!bpx__list_reserve(&block->hits, stage->count))
            return BPX_ERR_OUT_OF_MEMORY;
        bpx_pair *dst = block->hits.pairs + block->hits.count;
        for (size_t k = 0; k < stage->count; k++)
            dst[start[stage->pairs[k].i - ia]++] = stage->pairs[k];
        block->hits.count += stage->count;
    }
    st->counters.brute_cycles++;
    return BPX_OK;
}

// A device-resident cycle (resident.c): the whole set, its pairs into st->pairs (room for at
// least `need`; *capacity gets the room) and its count into `count`, nothing read back.
bpx_status bpx__cl_brute_resident(bpx_cl_state *st, const bpx_cycle *cycle, uint64_t need,
                                  cl_mem count, cl_ulong *capacity)
{
    uint32_t n = cycle->n;
    uint32_t padded = (uint32_t)round_up(n, st->tile);
    TRY(bpx__cl_dbuf_reserve(st, &st->pairs, need * sizeof(bpx_pair)));
    *capacity = st->pairs.size / sizeof(bpx_pair);
    TRY(bpx__cl_upload_keys(st, cycle, 0, n, padded, 0, &st->lo, &st->hi));
    st->counters.brute_cycles++;
    if (n <= st->dev->small_n && !st->small_off) {
        st->tests += (uint64_t)n * (n - 1) / 2;
        return launch_small(st, n, *capacity, count, 0);
    }
    rows_cols rc = whole_set(st, padded);
    TRY(count_rows(st, &rc, count, 0));
    return emit_rows(st, &rc, 0, *capacity);
}
