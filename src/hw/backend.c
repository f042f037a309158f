// The "model" backend (paper modules: all four, as the chip has them): each collide runs one
// updating phase of the clock-by-clock model of the paper's FPGA (m = 4, 108 MHz, 512-box RAMs;
// beyond 512 boxes the host streams tiles, so any n works). The world's boxes are the host's data
// in general-box layout (six SoA arrays = six SSRAM banks). The host sorts the collision RAM into
// (i, j) order, as the contract asks.
#include <stdio.h>

#include "core/alloc.h"
#include "core/backend.h"
#include "hw/model.h"

static bool model_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    (void)def;
    *reason = "";
    snprintf(detail, size, "FPGA model, m = 4, 108 MHz, 512-box RAMs, tiles streamed beyond");
    return true;
}

static void swap_lists(bpx_pair_list *a, bpx_pair_list *b)
{
    bpx_pair_list t = *a;
    *a = *b;
    *b = t;
}

// Kept between cycles as the backend's state: after the first cycles nothing is allocated.
typedef struct model_state {
    bpx_hw_machine machine;
    size_t *counts; // the host's sort, n + 1 entries
    uint32_t counts_capacity;
} model_state;

static void model_destroy(void *state)
{
    model_state *st = state;
    bpx__hw_machine_free(&st->machine);
    bpx__free(st->counts, sizeof(size_t) * st->counts_capacity);
    bpx__free(st, sizeof *st);
}

static model_state *get_state(void **state)
{
    if (*state)
        return *state;
    model_state *st = bpx__alloc(sizeof *st);
    if (!st)
        return NULL;
    bpx_model_config config = bpx_model_default_config();
    config.store = BPX_MODEL_STORE_STREAM;
    if (bpx__hw_machine_init(&st->machine, &config) != BPX_OK) {
        bpx__free(st, sizeof *st);
        return NULL;
    }
    st->counts = NULL;
    st->counts_capacity = 0;
    *state = st;
    return st;
}

static bpx_status model_compare(void **state, bpx_cycle *c)
{
    bpx_block *out;
    bpx_status status = bpx__emitter_one_block(c->sink, c->n, &out);
    if (status != BPX_OK)
        return status;
    model_state *st = get_state(state);
    if (!st)
        return BPX_ERR_OUT_OF_MEMORY;

    bpx_soa s = c->boxes;
    const float *const banks[BPX_HW_BANKS] = {s.lo[0], s.lo[1], s.lo[2], s.hi[0], s.hi[1], s.hi[2]};
    bpx_model_report report;
    // The collision RAM is the block's stage list; hits receives the sorted pairs.
    status =
        bpx__hw_machine_cycle(&st->machine, BPX_HW_FORMAT_BOXES, banks, s.n, &out->stage, &report);
    if (status != BPX_OK)
        return status;

    size_t count = out->stage.count;
    if (count > 0) {
        if (s.n + 1 > st->counts_capacity) {
            size_t *counts = bpx__alloc(sizeof(size_t) * ((size_t)s.n + 1));
            if (!counts)
                return BPX_ERR_OUT_OF_MEMORY;
            bpx__free(st->counts, sizeof(size_t) * st->counts_capacity);
            st->counts = counts;
            st->counts_capacity = s.n + 1;
        }
        if (!bpx__list_reserve(&out->hits, count))
            return BPX_ERR_OUT_OF_MEMORY;
        bpx__hw_host_sort(out->stage.pairs, count, s.n, st->counts, out->hits.pairs,
                          out->stage.pairs);
        swap_lists(&out->hits, &out->stage);
        out->hits.count = count;
        out->stage.count = 0;
    }
    out->tests = report.unit_tests;
    return BPX_OK;
}

const bpx_backend_impl bpx__model_backend = {
    .id = BPX_BACKEND_MODEL,
    .name = "model",
    .query = model_query,
    .compare = model_compare,
    .destroy = model_destroy,
};
