// The "rtl" backend: each collide runs the chip's RTL (rtl/*.sv, Verilated: board.h) on the
// world's boxes, clock by clock. The paper's build: m = 4, 512-box RAMs, FIFOs of 1024, SSRAM
// latency 2. The chip holds at most BPX_RTL_MAX_BOXES boxes and the RTL has no off-chip tiles
// (docs/rtl.md), so more is refused with BPX_ERR_TOO_MANY_BOXES.
//
// Two ways in, as the chip has them: general boxes (the six SSRAM banks: min x, y, z, max x, y,
// z), or the paper's two phases: the loaded extents once (initialisation: minima into the
// updater's RAM), then each cycle's centres alone, the chip's updater making the boxes with its
// adders. The host records the collision writes and sorts them into (i, j) order, as the
// contract asks.
#include <stdio.h>
#include <string.h>

#include "core/alloc.h"
#include "core/backend.h"
#include "rtl/board.h"

_Static_assert(BPX_RTL_DEPTH == BPX_RTL_MAX_BOXES, "the public limit is the chip's DEPTH");

// Kept between cycles: the board (the Verilated model), the cycle's centres, the sort's
// scratch, so that after the first cycles nothing is allocated.
typedef struct rtl_state {
    bpx_rtl_board *board;
    bool minima_loaded;      // the chip's minima RAM holds the world's extents
    bool centres_valid;      // centres[] made the world's boxes of version centres_version
    uint64_t centres_version;
    float centres[3 * BPX_RTL_DEPTH];
    bpx_pair_list sorted, spare;
    size_t last_count; // the last cycle's collisions
    uint32_t counts[BPX_RTL_DEPTH + 1];
} rtl_state;

static bool rtl_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    (void)def;
    *reason = "";
    snprintf(detail, size, "simulation: Verilated RTL, m = %d, %d boxes at most, FIFOs %d, "
             "SSRAM latency %d", BPX_RTL_M, BPX_RTL_DEPTH, BPX_RTL_FDEPTH, BPX_RTL_LAT);
    return true;
}

static void rtl_destroy(void *state)
{
    rtl_state *st = state;
    bpx__rtl_board_destroy(st->board);
    bpx__list_free(&st->sorted);
    bpx__list_free(&st->spare);
    bpx__free(st, sizeof *st);
}

static rtl_state *get_state(void **state)
{
    if (*state)
        return *state;
    rtl_state *st = bpx__alloc(sizeof *st);
    if (!st)
        return NULL;
    memset(st, 0, sizeof *st);
    st->board = bpx__rtl_board_create();
    if (!st->board) {
        bpx__free(st, sizeof *st);
        return NULL;
    }
    *state = st;
    return st;
}

// The world's boxes were replaced: newly loaded extents go to the chip at the next centres
// cycle; centres are kept for it (the caller's array is gone by then). Anything else (whole
// boxes, removed objects' inert boxes among the centres' ones) is run as general boxes.
static void rtl_boxes_set(void **state, const bpx_world_def *def, const bpx_boxes_change *change)
{
    (void)def;
    rtl_state *st = get_state(state);
    if (!st)
        return; // compare reports the memory
    st->centres_valid = false;
    if (!change->centres) {
        if (change->extents.count > 0)
            st->minima_loaded = false;
        return;
    }
    const uint32_t n = change->extents.count;
    if (n > BPX_RTL_DEPTH || change->inert_ids)
        return;
    memcpy(st->centres, change->centres, sizeof(float) * 3 * n);
    st->centres_valid = true;
    st->centres_version = change->boxes_version;
}

// The collision SSRAM: each write the chip makes, as a pair with i < j.
typedef struct recorder {
    bpx_pair_list *list;
    bool out_of_memory;
} recorder;

static bool record(void *user, uint32_t i, uint32_t j)
{
    recorder *r = user;
    if (!bpx__list_reserve(r->list, 1)) {
        r->out_of_memory = true;
        return false;
    }
    r->list->pairs[r->list->count++] = i < j ? (bpx_pair){i, j} : (bpx_pair){j, i};
    return true;
}

// One run of the chip on what the banks hold; its collisions into `out` (NULL: none expected).
static bpx_status run_chip(rtl_state *st, bpx_cycle *c, int mode, bpx_pair_list *out,
                           uint64_t *address_clocks)
{
    bpx_pair_list none = {0};
    recorder r = {out ? out : &none, false};
    bpx_rtl_run run = bpx__rtl_board_run(st->board, c->n, mode, record, &r);
    bpx__list_free(&none); // never grown: an initialisation writes no collision
    if (r.out_of_memory)
        return BPX_ERR_OUT_OF_MEMORY;
    if (!run.finished || run.error || run.overflow || run.count != r.list->count)
        return bpx__error(c->error, BPX_ERR_DEVICE, UINT32_MAX, -1,
                          "rtl: the chip (mode %d) %s after %llu clocks (STATUS error %d, "
                          "overflow %d; COUNT %u, %zu collisions written)",
                          mode, run.finished ? "finished wrong" : "did not finish",
                          (unsigned long long)run.clocks, (int)run.error, (int)run.overflow,
                          run.count, r.list->count);
    *address_clocks = run.address_clocks;
    return BPX_OK;
}

static bpx_status rtl_compare(void **state, bpx_cycle *c)
{
    const uint32_t n = c->n;
    if (n > BPX_RTL_DEPTH)
        return bpx__error(c->error, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "rtl: %u boxes; the chip holds at most %u (DEPTH)", n, BPX_RTL_DEPTH);
    rtl_state *st = get_state(state);
    if (!st)
        return BPX_ERR_OUT_OF_MEMORY;
    // The chip states its limit in its DEPTH register; the arrays here are sized for this one.
    const uint32_t depth = bpx__rtl_board_depth(st->board);
    if (depth != BPX_RTL_DEPTH)
        return bpx__error(c->error, BPX_ERR_DEVICE, UINT32_MAX, -1,
                          "rtl: the chip's DEPTH register reads %u, not %u", depth, BPX_RTL_DEPTH);
    bpx_status status = bpx__emitter_own_blocks(c->sink, 1);
    if (status != BPX_OK)
        return status;
    bpx_block *out = &c->sink->blocks[0];
    *out = (bpx_block){.row_begin = 0, .row_end = n, .hits = out->hits, .stage = out->stage};
    out->hits.count = 0;
    // The collision list takes turns with the sort's two (headroom alike), so that a pair
    // count that drifts between cycles settles without allocating.
    if (!bpx__list_reserve(&out->hits, st->last_count + st->last_count / 2))
        return BPX_ERR_OUT_OF_MEMORY;

    uint64_t address_clocks = 0;
    const bool centres = st->centres_valid && st->centres_version == c->boxes_version &&
                         c->extents.count == n && !c->inert_ids;
    if (centres) {
        if (!st->minima_loaded) { // the paper's initialisation phase, once per extents
            for (int a = 0; a < 3; a++)
                bpx__rtl_board_write(st->board, a, c->extents.minima[a], n, 1);
            status = run_chip(st, c, BPX_RTL_MODE_MINIMA, NULL, &address_clocks);
            if (status != BPX_OK)
                return status;
            st->minima_loaded = true;
        }
        for (int a = 0; a < 3; a++)
            bpx__rtl_board_write(st->board, a, st->centres + a, n, 3);
        status = run_chip(st, c, BPX_RTL_MODE_CENTRES, &out->hits, &address_clocks);
    } else {
        const bpx_soa s = c->boxes;
        const float *const banks[6] = {s.lo[0], s.lo[1], s.lo[2], s.hi[0], s.hi[1], s.hi[2]};
        for (int b = 0; b < 6; b++)
            bpx__rtl_board_write(st->board, b, banks[b], n, 1);
        status = run_chip(st, c, BPX_RTL_MODE_BOXES, &out->hits, &address_clocks);
    }
    if (status != BPX_OK)
        return status;
    out->tests = address_clocks * (2 * BPX_RTL_M - 1);
    st->last_count = out->hits.count;
    return bpx__emitter_sort_blocks(c->sink, n, &st->sorted, &st->spare, st->counts);
}

const bpx_backend_impl bpx__rtl_backend = {
    .id = BPX_BACKEND_RTL,
    .name = "rtl",
    .query = rtl_query,
    .compare = rtl_compare,
    .destroy = rtl_destroy,
    .boxes_set = rtl_boxes_set,
};
