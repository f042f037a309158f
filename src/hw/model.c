// The model's machine (clock, controller) and the public bpx_model API.
#include "hw/model.h"

#include <math.h>
#include <string.h>

#include "core/alloc.h"
#include "core/validate.h"

enum {
    MAX_RAM_DEPTH = 1u << 20,
    MAX_FIFO_DEPTH = 1u << 20,
    WORDS_PER_BLOCK_RAM = 512,   // Virtex-II 18 Kb block RAM as 512 x 36: one 32-bit word each
    ENTRIES_PER_FIFO_RAM = 1024, // as 1K x 18: one index (up to 18 bits) per entry
    SMALL_INDEX_LIMIT = 65536,   // two 16-bit indices fit one 32-bit word read over the bus
};

// ---------------------------------------------------------------------------------------------
// Configuration

bpx_model_config bpx_model_default_config(void)
{
    return (bpx_model_config){
        .m = 4,
        .clock_hz = 108e6,
        .ram_depth = 512,
        .ssram_depth = 524288,
        .store = BPX_MODEL_STORE_ON_CHIP,
        .fifo_depth = 1024,
        .ssram_latency = 2,
        .link = {.bytes_per_s = 264e6, .setup_ns = 104000.0, .register_ns = 500.0},
    };
}

const char *bpx_model_store_name(bpx_model_store store)
{
    static const char *const names[BPX_MODEL_STORE_COUNT] = {"on-chip", "ssram", "stream"};
    return (unsigned)store < BPX_MODEL_STORE_COUNT ? names[store] : NULL;
}

// Whole clocks for a duration, rounded up (no libm: the library links only pthreads).
static uint64_t clocks_for(double ns, double clock_hz)
{
    double clocks = ns * clock_hz * 1e-9;
    uint64_t whole = (uint64_t)clocks;
    return whole + ((double)whole < clocks);
}

static bool finite_in(double v, double lo, double hi)
{
    return isfinite(v) && v >= lo && v <= hi;
}

bpx_status bpx_model_check_config(const bpx_model_config *c, bpx_error *err)
{
    bpx__error_clear(err);
    if (!c)
        return bpx__error(err, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "config is NULL");
    const bpx_status bad = BPX_ERR_INVALID_ARGUMENT;
    if (c->m < 1 || c->m > BPX_MODEL_MAX_M)
        return bpx__error(err, bad, UINT32_MAX, -1, "m = %d is outside 1..%d", c->m,
                          BPX_MODEL_MAX_M);
    if (!finite_in(c->clock_hz, 1.0, 1e12))
        return bpx__error(err, bad, UINT32_MAX, -1, "clock %g Hz is outside 1 Hz..1 THz",
                          c->clock_hz);
    uint32_t least = 4u * (uint32_t)c->m;
    if (c->ram_depth < least || c->ram_depth > MAX_RAM_DEPTH || c->ram_depth % 2 != 0)
        return bpx__error(err, bad, UINT32_MAX, -1,
                          "ram_depth %u must be even and within %u (4m)..%u", c->ram_depth, least,
                          MAX_RAM_DEPTH);
    if (c->ssram_depth < 1)
        return bpx__error(err, bad, UINT32_MAX, -1, "ssram_depth must be at least 1");
    if ((unsigned)c->store >= BPX_MODEL_STORE_COUNT)
        return bpx__error(err, bad, UINT32_MAX, -1, "store %d is not a bpx_model_store",
                          (int)c->store);
    if (c->fifo_depth < 1 || c->fifo_depth > MAX_FIFO_DEPTH)
        return bpx__error(err, bad, UINT32_MAX, -1, "fifo_depth %u is outside 1..%u", c->fifo_depth,
                          MAX_FIFO_DEPTH);
    if (c->ssram_latency < 1 || c->ssram_latency > BPX_HW_MAX_LATENCY)
        return bpx__error(err, bad, UINT32_MAX, -1, "ssram_latency %d is outside 1..%d",
                          c->ssram_latency, BPX_HW_MAX_LATENCY);
    if (!finite_in(c->link.bytes_per_s, 1.0, 1e15) || !finite_in(c->link.setup_ns, 0.0, 1e12) ||
        !finite_in(c->link.register_ns, 0.0, 1e12))
        return bpx__error(err, bad, UINT32_MAX, -1,
                          "link: bytes_per_s must be positive, setup_ns and register_ns >= 0, "
                          "all finite");
    return BPX_OK;
}

bpx_status bpx__hw_machine_check_n(const bpx_model_config *c, uint32_t n, bpx_error *err)
{
    if (n > BPX_MAX_BOXES)
        return bpx__error(err, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "%u boxes exceed BPX_MAX_BOXES (%u)", n, BPX_MAX_BOXES);
    if (c->store == BPX_MODEL_STORE_ON_CHIP && n > c->ram_depth)
        return bpx__error(err, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "%u boxes exceed the on-chip RAM depth of %u (the paper's FPGA holds "
                          "at most 512 AABBs); use the ssram or stream store",
                          n, c->ram_depth);
    if (c->store == BPX_MODEL_STORE_SSRAM && n > c->ssram_depth)
        return bpx__error(err, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "%u boxes exceed the SSRAM bank depth of %u; use the stream store", n,
                          c->ssram_depth);
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// The machine

bpx_status bpx__hw_machine_init(bpx_hw_machine *mc, const bpx_model_config *config)
{
    memset(mc, 0, sizeof *mc);
    mc->config = *config;
    const size_t m = (size_t)config->m, depth = config->ram_depth;
    const size_t lanes = 2 * m - 1;
    mc->ram = bpx__alloc(sizeof(float) * (BPX_HW_AXES * m * depth + BPX_HW_RAM_SLACK));
    mc->minima_ram = bpx__alloc(sizeof(float) * 3 * depth);
    mc->fifo = bpx__alloc(sizeof(bpx_pair) * lanes * config->fifo_depth);
    if (!mc->ram || !mc->minima_ram || !mc->fifo) {
        bpx__hw_machine_free(mc);
        return BPX_ERR_OUT_OF_MEMORY;
    }
    // Block RAMs power up holding zeros; discarded ports read whatever is there.
    memset(mc->ram, 0, sizeof(float) * (BPX_HW_AXES * m * depth + BPX_HW_RAM_SLACK));
    memset(mc->minima_ram, 0, sizeof(float) * 3 * depth);
    mc->tile = config->ram_depth / 2;
    bpx__hw_comparator_init(&mc->cmp, config->m, config->ram_depth, mc->ram);
    bpx__hw_updater_init(&mc->upd, config->ram_depth, mc->minima_ram, mc->minima_ram + depth,
                         mc->minima_ram + 2 * depth);
    bpx__hw_emitter_init(&mc->emi, (int)lanes, config->fifo_depth, mc->fifo);
    mc->minima_count = UINT32_MAX;
    return BPX_OK;
}

void bpx__hw_machine_free(bpx_hw_machine *mc)
{
    const size_t m = (size_t)mc->config.m, depth = mc->config.ram_depth;
    bpx__free(mc->ram, sizeof(float) * (BPX_HW_AXES * m * depth + BPX_HW_RAM_SLACK));
    bpx__free(mc->minima_ram, sizeof(float) * 3 * depth);
    bpx__free(mc->fifo, sizeof(bpx_pair) * (2 * m - 1) * mc->config.fifo_depth);
    mc->ram = mc->minima_ram = NULL;
    mc->fifo = NULL;
}

// The trace record of a clock: addresses and results as registered before the edge, the
// emitter's output and FIFO fills after it.
typedef struct trace_before {
    uint64_t clock;
    bpx_hw_addrgen a;
    bool hits_valid;
    uint64_t hits;
    uint32_t hit_row;
    bool stalled;
} trace_before;

static void trace_clock(bpx_hw_machine *mc, const trace_before *b)
{
    const int ports = 2 * mc->config.m;
    const bpx_hw_addrgen *a = &b->a;
    if (a->active) {
        mc->trace_ports[0] = a->first;
        for (int p = 1; p < ports; p++) {
            uint32_t address = a->base + (uint32_t)p - 1;
            mc->trace_ports[p] = address <= a->max ? address : BPX_MODEL_DISCARDED;
        }
    }
    bpx_model_clock record = {
        .clock = b->clock,
        .phase = mc->phase,
        .port_count = ports,
        .addressing = a->active,
        .ports = a->active ? mc->trace_ports : NULL,
        .max_address = a->active ? a->max : 0,
        .hits = b->hits_valid ? b->hits : 0,
        .hit_row = b->hits_valid ? b->hit_row : 0,
        .stalled = b->stalled,
        .emitted = mc->emi.out_valid,
        .pair = mc->emi.out_valid ? mc->emi.out : (bpx_pair){0, 0},
        .fifo_fill_max = bpx__hw_emitter_fill_max(&mc->emi),
    };
    mc->config.trace(&record, mc->config.trace_user);
}

// The clock edge: every unit evaluates from the committed state, then every unit commits, so
// all registers change together.
static inline bool clock_edge(bpx_hw_machine *mc, bool stall, bool ready)
{
    bpx_hw_comparator *c = &mc->cmp;
    bpx__hw_updater_evaluate(&mc->upd, &mc->ifc, c);
    bpx__hw_comparator_evaluate(c, stall);
    bpx__hw_emitter_evaluate(&mc->emi, c, stall, ready);
    bpx__hw_interface_evaluate(&mc->ifc, mc->emi.out_valid && ready, mc->emi.out);

    const bool stall_next = mc->emi.stall_next;
    bpx__hw_updater_commit(&mc->upd);
    bpx__hw_comparator_commit(c);
    bpx__hw_emitter_commit(&mc->emi);
    bool ok = bpx__hw_interface_commit(&mc->ifc);
    mc->stall = stall_next;

    mc->phase_clocks[mc->phase]++;
    mc->stall_clocks += stall; // only a comparator with a result in flight can be stalled
    mc->clock++;
    return ok;
}

// One clock. The comparator is held when the emitter decided, two clocks before, that a FIFO
// might overflow (bpx__hw_emitter_stall_decide); the collision port takes the output register when it is ready (the back-pressure hook).
static bool step(bpx_hw_machine *mc)
{
    const bool stall = mc->stall;
    const bpx_model_config *c = &mc->config;
    const bool ready = !c->collision_ready || c->collision_ready(mc->clock, c->collision_ready_user);
    if (!c->trace)
        return clock_edge(mc, stall, ready);
    const bpx_hw_cmp_regs *r = mc->cmp.cur;
    trace_before before = {mc->clock, r->a, r->h_valid, r->h_mask, r->h_i, stall};
    bool ok = clock_edge(mc, stall, ready);
    trace_clock(mc, &before);
    return ok;
}

static bpx_status run_updater(bpx_hw_machine *mc, bpx_model_phase phase, bpx_hw_update_mode mode,
                              uint32_t begin, uint32_t end, uint32_t to)
{
    mc->phase = phase;
    bpx__hw_updater_start(&mc->upd, mode, begin, end, to);
    mc->report->tile_loads += phase == BPX_MODEL_PHASE_UPDATE;
    while (!bpx__hw_updater_done(&mc->upd))
        if (!step(mc))
            return BPX_ERR_OUT_OF_MEMORY;
    return BPX_OK;
}

// Only the comparator has work this clock (see bpx__hw_comparator_run_quiet); with a trace
// hook every clock is stepped in full, so that the hook sees each one. No stall now or next,
// and none decided in those clocks: empty FIFOs, no hit registered, and at most one result
// (p1) still to arrive, which fills no FIFO of depth >= 2 (a FIFO of 1 stalls for it).
static bool quiet(const bpx_hw_machine *mc)
{
    return !mc->config.trace && !mc->upd.active && !bpx__hw_emitter_busy(&mc->emi) &&
           !bpx__hw_interface_busy(&mc->ifc) && !mc->stall && !mc->emi.stall_next &&
           mc->config.fifo_depth >= 2;
}

static bpx_status run_comparator(bpx_hw_machine *mc, uint32_t first_begin, uint32_t first_end,
                                 bool diagonal, uint32_t sweep, uint32_t max, uint32_t i_offset,
                                 uint32_t j_offset)
{
    mc->phase = BPX_MODEL_PHASE_COMPARE;
    bpx__hw_comparator_start(&mc->cmp, first_begin, first_end, diagonal, sweep, max, i_offset,
                             j_offset);
    while (bpx__hw_comparator_busy(&mc->cmp)) {
        if (quiet(mc)) {
            uint64_t clocks = bpx__hw_comparator_run_quiet(&mc->cmp);
            mc->phase_clocks[BPX_MODEL_PHASE_COMPARE] += clocks;
            mc->clock += clocks;
            if (clocks > 0)
                continue;
        }
        if (!step(mc))
            return BPX_ERR_OUT_OF_MEMORY;
    }
    return BPX_OK;
}

static bpx_status run_drain(bpx_hw_machine *mc)
{
    mc->phase = BPX_MODEL_PHASE_DRAIN;
    while (bpx__hw_emitter_busy(&mc->emi))
        if (!step(mc))
            return BPX_ERR_OUT_OF_MEMORY;
    return BPX_OK;
}

// A DMA transfer the chip waits for: the emitter keeps draining meanwhile; clocks with nothing
// else to do are skipped, not stepped.
static bpx_status run_wait(bpx_hw_machine *mc, uint64_t bytes)
{
    double ns = bpx__hw_link_dma_ns(&mc->ifc.link, bytes);
    bpx__hw_link_dma(&mc->ifc, bytes, true);
    uint64_t clocks = clocks_for(ns, mc->config.clock_hz);
    mc->phase = BPX_MODEL_PHASE_WAIT;
    while (clocks > 0 && bpx__hw_emitter_busy(&mc->emi)) {
        if (!step(mc))
            return BPX_ERR_OUT_OF_MEMORY;
        clocks--;
    }
    mc->clock += clocks;
    return BPX_OK;
}

static void begin_run(bpx_hw_machine *mc, bpx_model_report *report, uint32_t n,
                      bpx_pair_list *collisions)
{
    const bpx_model_config *c = &mc->config;
    *report = (bpx_model_report){
        .n = n,
        .m = c->m,
        .clock_hz = c->clock_hz,
        .store = c->store,
        .on_chip = n <= c->ram_depth,
        .tiles = n <= c->ram_depth ? 1 : (n + mc->tile - 1) / mc->tile,
    };
    mc->report = report;
    mc->clock = 0;
    memset(mc->phase_clocks, 0, sizeof mc->phase_clocks);
    mc->stall_clocks = 0;
    mc->stall = false;
    bpx__hw_interface_reset(&mc->ifc, c->ssram_latency, &c->link, collisions);
    mc->ifc.n_register = n;
    bpx__hw_comparator_reset(&mc->cmp);
    bpx__hw_emitter_reset(&mc->emi);
}

static void end_run(bpx_hw_machine *mc)
{
    const bpx_model_config *c = &mc->config;
    bpx_model_report *r = mc->report;
    const double f = c->clock_hz;
    const uint64_t *clocks = mc->phase_clocks;
    r->update_clocks = clocks[BPX_MODEL_PHASE_INIT] + clocks[BPX_MODEL_PHASE_UPDATE];
    r->compare_clocks = clocks[BPX_MODEL_PHASE_COMPARE];
    r->stall_clocks = mc->stall_clocks;
    r->emit_clocks = clocks[BPX_MODEL_PHASE_DRAIN];
    r->simulated_clocks = 0;
    for (int p = 0; p < BPX_MODEL_PHASE_COUNT; p++)
        r->simulated_clocks += clocks[p];
    r->collisions = mc->ifc.count_register;
    r->chip_clocks = r->update_clocks + r->compare_clocks + r->emit_clocks;
    r->chip_ns = (double)r->chip_clocks / f * 1e9;
    r->transfer_ns = mc->ifc.transfer_ns;
    r->transfer_clocks = clocks_for(r->transfer_ns, f);
    r->cycle_ns = r->chip_ns + r->transfer_ns;
    r->communication_share = r->cycle_ns > 0 ? r->transfer_ns / r->cycle_ns : 0;
    r->dma_transfers = mc->ifc.dma_transfers;
    r->register_accesses = mc->ifc.register_accesses;
    r->bytes_to_board = mc->ifc.bytes_to_board;
    r->bytes_to_host = mc->ifc.bytes_to_host;
    r->unit_tests = mc->cmp.address_clocks * (uint64_t)(2 * c->m - 1);
    r->discarded_tests = mc->cmp.discarded;
    // The paper's measure counts one 2m-width memory: 2m ports of 4 bytes each clock.
    r->peak_read_bytes_per_s = 2.0 * c->m * 4.0 * f;
    if (r->compare_clocks > 0) {
        double kept_reads =
            (double)mc->cmp.address_clocks + (double)(r->unit_tests - r->discarded_tests);
        r->achieved_read_bytes_per_s = kept_reads * 4.0 * f / (double)r->compare_clocks;
    }
    r->fifo_peak = mc->emi.peak_fill;
    const uint64_t m = (uint64_t)c->m, depth = c->ram_depth, fifos = 4 * m - 2;
    r->on_chip_bytes = 4 * (6 * m * depth + 3 * depth) + 2 * fifos * c->fifo_depth;
    uint64_t per_ram = (depth + WORDS_PER_BLOCK_RAM - 1) / WORDS_PER_BLOCK_RAM;
    uint64_t per_fifo = (c->fifo_depth + ENTRIES_PER_FIFO_RAM - 1) / ENTRIES_PER_FIFO_RAM;
    r->block_rams = (int)((6 * m + 3) * per_ram + fifos * per_fifo);
    r->collision_words = r->collisions;
    r->collision_overflow = r->collisions > c->ssram_depth;
    mc->report = NULL;
}

bpx_status bpx__hw_machine_extents(bpx_hw_machine *mc, const float *const minima[3], uint32_t n,
                                   bpx_model_report *report)
{
    begin_run(mc, report, n, NULL);
    const bpx_model_config *c = &mc->config;
    mc->minima_count = UINT32_MAX;
    bpx_status status = BPX_OK;
    // The host writes the minima to one address across banks 0-2 (beyond the on-chip RAMs, to
    // banks 3-5 where the tiles' loads read them; a streaming host keeps them) and sets n.
    if (n > 0 && (n <= c->ram_depth || c->store != BPX_MODEL_STORE_STREAM))
        bpx__hw_link_dma(&mc->ifc, 12ull * n, true);
    bpx__hw_link_register(&mc->ifc);
    if (n <= c->ram_depth) {
        for (int a = 0; a < 3; a++)
            mc->ifc.bank[a] = minima[a];
        status = run_updater(mc, BPX_MODEL_PHASE_INIT, BPX_HW_STORE_MINIMA, 0, n, 0);
        if (status == BPX_OK)
            mc->minima_count = n;
    }
    end_run(mc);
    return status;
}

static bpx_status run_tiles(bpx_hw_machine *mc, bpx_hw_update_mode mode, uint32_t n)
{
    const uint32_t tile = mc->tile;
    const bool stream = mc->config.store == BPX_MODEL_STORE_STREAM;
    bpx_status status = BPX_OK;
    // Tile a sits in the lower half of the RAMs and is compared with itself (Table 1 within the
    // tile), then each later tile b is loaded into the upper half and compared with it: port 0
    // walks tile a, ports 1 .. 2m - 1 sweep tile b.
    for (uint32_t a0 = 0; a0 < n && status == BPX_OK; a0 += tile) {
        uint32_t a_len = n - a0 < tile ? n - a0 : tile;
        if (stream)
            status = run_wait(mc, 24ull * a_len);
        if (status == BPX_OK)
            status = run_updater(mc, BPX_MODEL_PHASE_UPDATE, mode, a0, a0 + a_len, 0);
        if (status == BPX_OK && a_len >= 2)
            status = run_comparator(mc, 0, a_len - 1, true, 0, a_len - 1, a0, a0);
        for (uint32_t b0 = a0 + a_len; b0 < n && status == BPX_OK; b0 += tile) {
            uint32_t b_len = n - b0 < tile ? n - b0 : tile;
            if (stream)
                status = run_wait(mc, 24ull * b_len);
            if (status == BPX_OK)
                status = run_updater(mc, BPX_MODEL_PHASE_UPDATE, mode, b0, b0 + b_len, tile);
            if (status == BPX_OK)
                status = run_comparator(mc, 0, a_len, false, tile, tile + b_len - 1, a0, b0 - tile);
        }
    }
    return status;
}

bpx_status bpx__hw_machine_cycle(bpx_hw_machine *mc, bpx_hw_format format,
                                 const float *const banks[BPX_HW_BANKS], uint32_t n,
                                 bpx_pair_list *collisions, bpx_model_report *report)
{
    const bpx_model_config *c = &mc->config;
    const bool on_chip = n <= c->ram_depth;
    if (format == BPX_HW_FORMAT_CENTRES && on_chip && mc->minima_count != n)
        return BPX_ERR_BAD_STATE;
    begin_run(mc, report, n, collisions);
    for (int b = 0; b < BPX_HW_BANKS; b++)
        mc->ifc.bank[b] = banks[b];
    const uint64_t object_bytes = format == BPX_HW_FORMAT_CENTRES ? 12 : 24;

    // Host: write this cycle's data (a streaming host sends it tile by tile instead) and start.
    if (n > 0 && (on_chip || c->store != BPX_MODEL_STORE_STREAM))
        bpx__hw_link_dma(&mc->ifc, object_bytes * n, true);
    bpx__hw_link_register(&mc->ifc);

    bpx_status status;
    if (on_chip) {
        bpx_hw_update_mode mode =
            format == BPX_HW_FORMAT_CENTRES ? BPX_HW_ADD_ON_CHIP : BPX_HW_PASS_BOXES;
        status = run_updater(mc, BPX_MODEL_PHASE_UPDATE, mode, 0, n, 0);
        if (status == BPX_OK && n >= 2)
            status = run_comparator(mc, 0, n - 1, true, 0, n - 1, 0, 0);
    } else {
        bpx_hw_update_mode mode =
            format == BPX_HW_FORMAT_CENTRES ? BPX_HW_ADD_FROM_BANKS : BPX_HW_PASS_BOXES;
        status = run_tiles(mc, mode, n);
    }
    if (status == BPX_OK)
        status = run_drain(mc);

    // Host: read the collision count, then the collisions (one SSRAM address each).
    bpx__hw_link_register(&mc->ifc);
    uint64_t count = mc->ifc.count_register;
    if (status == BPX_OK && count > 0)
        bpx__hw_link_dma(&mc->ifc, count * (n <= SMALL_INDEX_LIMIT ? 4 : 8), false);
    end_run(mc);
    return status;
}

// ---------------------------------------------------------------------------------------------
// Table 1

bpx_status bpx_model_schedule(int m, uint32_t max_address, uint32_t *ports, size_t capacity,
                              size_t *rows)
{
    if (!rows || (!ports && capacity > 0))
        return BPX_ERR_NULL_ARGUMENT;
    *rows = 0;
    if (m < 1 || m > BPX_MODEL_MAX_M)
        return BPX_ERR_INVALID_ARGUMENT;
    const int lanes = 2 * m - 1;
    // The comparator's own address generator, run without data.
    bpx_hw_addrgen g;
    size_t count = 0;
    for (bpx__hw_addrgen_start(&g, lanes, 0, max_address, true, 0, max_address); g.active;
         bpx__hw_addrgen_next(&g))
        count++;
    *rows = count;
    if (count > capacity)
        return BPX_ERR_CAPACITY;
    size_t row = 0;
    for (bpx__hw_addrgen_start(&g, lanes, 0, max_address, true, 0, max_address); g.active;
         bpx__hw_addrgen_next(&g), row++) {
        uint32_t *out = ports + row * (size_t)(2 * m);
        out[0] = g.first;
        for (int p = 1; p < 2 * m; p++) {
            uint32_t address = g.base + (uint32_t)p - 1;
            out[p] = address <= g.max ? address : BPX_MODEL_DISCARDED;
        }
    }
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// The public model: the host's side of the board.

struct bpx_model {
    bpx_hw_machine machine;
    bpx_error error;
    // Host arrays in bank layout: centres (or box minima) 0-2, minima (or box maxima) 3-5.
    float *host[BPX_HW_BANKS];
    uint32_t host_capacity;
    uint32_t extent_count;
    bool extents_loaded;
    bool have_pairs;
    uint32_t pairs_n;
    bpx_pair_list emitted; // the collision RAM, emitter order
    bpx_pair_list scratch;
    bpx_pair_list sorted;
    size_t *counts;
    uint32_t counts_capacity; // entries
};

bpx_status bpx_model_create(const bpx_model_config *config, bpx_model **out)
{
    if (!out)
        return BPX_ERR_NULL_ARGUMENT;
    *out = NULL;
    bpx_status status = bpx_model_check_config(config, NULL);
    if (status != BPX_OK)
        return status;
    bpx_model *model = bpx__alloc(sizeof *model);
    if (!model)
        return BPX_ERR_OUT_OF_MEMORY;
    memset(model, 0, sizeof *model);
    if (bpx__hw_machine_init(&model->machine, config) != BPX_OK) {
        bpx__free(model, sizeof *model);
        return BPX_ERR_OUT_OF_MEMORY;
    }
    bpx__error_clear(&model->error);
    *out = model;
    return BPX_OK;
}

static void list_free(bpx_pair_list *list)
{
    bpx__free(list->pairs, list->capacity * sizeof(bpx_pair));
    *list = (bpx_pair_list){0};
}

void bpx_model_destroy(bpx_model *model)
{
    if (!model)
        return;
    bpx__hw_machine_free(&model->machine);
    for (int b = 0; b < BPX_HW_BANKS; b++)
        bpx__free(model->host[b], sizeof(float) * model->host_capacity);
    list_free(&model->emitted);
    list_free(&model->scratch);
    list_free(&model->sorted);
    bpx__free(model->counts, sizeof(size_t) * model->counts_capacity);
    bpx__free(model, sizeof *model);
}

const bpx_error *bpx_model_error(const bpx_model *model)
{
    static const bpx_error null_model = {BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "model is NULL"};
    return model ? &model->error : &null_model;
}

// Host arrays for n objects; their contents are not kept when they grow.
static bool reserve_host(bpx_model *model, uint32_t n)
{
    if (n <= model->host_capacity)
        return true;
    float *grown[BPX_HW_BANKS] = {0};
    for (int b = 0; b < BPX_HW_BANKS; b++)
        if (!(grown[b] = bpx__alloc(sizeof(float) * n))) {
            for (int f = 0; f < b; f++)
                bpx__free(grown[f], sizeof(float) * n);
            return false;
        }
    for (int b = 0; b < BPX_HW_BANKS; b++) {
        bpx__free(model->host[b], sizeof(float) * model->host_capacity);
        model->host[b] = grown[b];
    }
    model->host_capacity = n;
    return true;
}

// After a cycle: the host sorts what it read from the collision RAM.
static bpx_status sort_pairs(bpx_model *model, uint32_t n)
{
    size_t count = model->emitted.count;
    model->sorted.count = 0;
    model->scratch.count = 0;
    if (count == 0)
        return BPX_OK;
    if (n + 1 > model->counts_capacity) {
        size_t *counts = bpx__alloc(sizeof(size_t) * ((size_t)n + 1));
        if (!counts)
            return BPX_ERR_OUT_OF_MEMORY;
        bpx__free(model->counts, sizeof(size_t) * model->counts_capacity);
        model->counts = counts;
        model->counts_capacity = n + 1;
    }
    if (!bpx__list_reserve(&model->scratch, count) || !bpx__list_reserve(&model->sorted, count))
        return BPX_ERR_OUT_OF_MEMORY;
    bpx__hw_host_sort(model->emitted.pairs, count, n, model->counts, model->scratch.pairs,
                      model->sorted.pairs);
    model->sorted.count = count;
    return BPX_OK;
}

static bpx_status run_cycle(bpx_model *model, bpx_hw_format format, uint32_t n,
                            bpx_model_report *report)
{
    bpx_model_report local;
    bpx_model_report *r = report ? report : &local;
    const float *const banks[BPX_HW_BANKS] = {model->host[0], model->host[1], model->host[2],
                                              model->host[3], model->host[4], model->host[5]};
    model->have_pairs = false;
    bpx_status status =
        bpx__hw_machine_cycle(&model->machine, format, banks, n, &model->emitted, r);
    if (status == BPX_OK)
        status = sort_pairs(model, n);
    if (status != BPX_OK)
        return bpx__error(&model->error, status, UINT32_MAX, -1, "model cycle: %s",
                          bpx_status_string(status));
    model->have_pairs = true;
    model->pairs_n = n;
    return BPX_OK;
}

bpx_status bpx_model_load_extents(bpx_model *model, const float *minima, uint32_t n,
                                  bpx_model_report *report)
{
    if (!model)
        return BPX_ERR_NULL_ARGUMENT;
    bpx_error *err = &model->error;
    bpx__error_clear(err);
    bpx_status status = bpx__hw_machine_check_n(&model->machine.config, n, err);
    if (status != BPX_OK)
        return status;
    if (!minima && n > 0)
        return bpx__error(err, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "minima is NULL");
    if ((status = bpx__check_minima(minima, n, err)) != BPX_OK)
        return status;
    if (!reserve_host(model, n))
        return bpx__error(err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1, "no memory for %u objects",
                          n);
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++)
            model->host[3 + a][i] = minima[3 * (size_t)i + a];
    bpx_model_report local;
    const float *const arrays[3] = {model->host[3], model->host[4], model->host[5]};
    model->extents_loaded = false;
    status = bpx__hw_machine_extents(&model->machine, arrays, n, report ? report : &local);
    if (status != BPX_OK)
        return bpx__error(err, status, UINT32_MAX, -1, "initialisation: %s",
                          bpx_status_string(status));
    model->extent_count = n;
    model->extents_loaded = true;
    return BPX_OK;
}

bpx_status bpx_model_run_centres(bpx_model *model, const float *centres, bpx_model_report *report)
{
    if (!model)
        return BPX_ERR_NULL_ARGUMENT;
    bpx_error *err = &model->error;
    bpx__error_clear(err);
    if (!model->extents_loaded)
        return bpx__error(err, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "run_centres before load_extents");
    uint32_t n = model->extent_count;
    if (!centres && n > 0)
        return bpx__error(err, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "centres is NULL");
    const float *const minima[3] = {model->host[3], model->host[4], model->host[5]};
    bpx_status status = bpx__check_centres(centres, minima, n, err);
    if (status != BPX_OK)
        return status;
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++)
            model->host[a][i] = centres[3 * (size_t)i + a];
    return run_cycle(model, BPX_HW_FORMAT_CENTRES, n, report);
}

bpx_status bpx_model_run_boxes(bpx_model *model, const bpx_box *boxes, uint32_t n,
                               bpx_model_report *report)
{
    if (!model)
        return BPX_ERR_NULL_ARGUMENT;
    bpx_error *err = &model->error;
    bpx__error_clear(err);
    bpx_status status = bpx__hw_machine_check_n(&model->machine.config, n, err);
    if (status != BPX_OK)
        return status;
    if (!boxes && n > 0)
        return bpx__error(err, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "boxes is NULL");
    if ((status = bpx__check_boxes(boxes, n, err)) != BPX_OK)
        return status;
    if (!reserve_host(model, n))
        return bpx__error(err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1, "no memory for %u boxes", n);
    // The host arrays now hold boxes: loaded extents are gone.
    model->extents_loaded = false;
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            model->host[a][i] = boxes[i].min[a];
            model->host[3 + a][i] = boxes[i].max[a];
        }
    return run_cycle(model, BPX_HW_FORMAT_BOXES, n, report);
}

const bpx_pair *bpx_model_pairs(const bpx_model *model, size_t *count)
{
    if (count)
        *count = 0;
    if (!model || !model->have_pairs)
        return NULL;
    if (count)
        *count = model->sorted.count;
    return model->sorted.pairs;
}

const bpx_pair *bpx_model_emitted(const bpx_model *model, size_t *count)
{
    if (count)
        *count = 0;
    if (!model || !model->have_pairs)
        return NULL;
    if (count)
        *count = model->emitted.count;
    return model->emitted.pairs;
}
