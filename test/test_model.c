// The clock-by-clock model of the paper's FPGA (include/bpx/model.h, src/hw/): the address
// schedule against Table 1 and its clock count per first address, the peak read bandwidth the
// paper quotes, pairs equal to the reference for m = 1, 2, 4, 8, 16 on every scene kind (on chip,
// tiled from the SSRAM, streamed beyond the on-chip RAMs, FIFOs small enough to overflow), the
// paper's two phases, clock counts, the trace hook and the model backend. The 512-box limit,
// errors and allocation failure: test_model_errors.c.
#include <math.h>

#include "model_util.h"
#include "scenes.h"

#define D BPX_MODEL_DISCARDED

// ---------------------------------------------------------------------------------------------
// Table 1

static void test_table1(void)
{
    check_set_context("Table 1: m = 4, maximum address 10");
    static const uint32_t table1[13][8] = {
        {0, 1, 2, 3, 4, 5, 6, 7},  {0, 8, 9, 10, D, D, D, D}, {1, 2, 3, 4, 5, 6, 7, 8},
        {1, 9, 10, D, D, D, D, D}, {2, 3, 4, 5, 6, 7, 8, 9},  {2, 10, D, D, D, D, D, D},
        {3, 4, 5, 6, 7, 8, 9, 10}, {4, 5, 6, 7, 8, 9, 10, D}, {5, 6, 7, 8, 9, 10, D, D},
        {6, 7, 8, 9, 10, D, D, D}, {7, 8, 9, 10, D, D, D, D}, {8, 9, 10, D, D, D, D, D},
        {9, 10, D, D, D, D, D, D},
    };
    size_t rows = 0;
    CHECK_STATUS(bpx_model_schedule(4, 10, NULL, 0, &rows), BPX_ERR_CAPACITY);
    CHECK_EQ_U64(rows, 13);
    uint32_t got[14][8];
    memset(got, 0xA5, sizeof got);
    CHECK_STATUS(bpx_model_schedule(4, 10, &got[0][0], 12, &rows), BPX_ERR_CAPACITY);
    CHECK_EQ_U64(rows, 13);
    CHECK(got[0][0] == 0xA5A5A5A5u); // nothing written on CAPACITY
    CHECK_STATUS(bpx_model_schedule(4, 10, &got[0][0], 14, &rows), BPX_OK);
    CHECK_EQ_U64(rows, 13);
    for (int r = 0; r < 13; r++)
        for (int p = 0; p < 8; p++)
            CHECK_MSG(got[r][p] == table1[r][p], "clock %d port %d: got %d, Table 1 says %d", r + 1,
                      p, got[r][p] == D ? -1 : (int)got[r][p],
                      table1[r][p] == D ? -1 : (int)table1[r][p]);
    CHECK(got[13][0] == 0xA5A5A5A5u);

    check_set_context("schedule arguments");
    CHECK_STATUS(bpx_model_schedule(4, 10, NULL, 1, &rows), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_model_schedule(4, 10, &got[0][0], 14, NULL), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_model_schedule(0, 10, &got[0][0], 14, &rows), BPX_ERR_INVALID_ARGUMENT);
    CHECK_STATUS(bpx_model_schedule(BPX_MODEL_MAX_M + 1, 10, &got[0][0], 14, &rows),
                 BPX_ERR_INVALID_ARGUMENT);
    CHECK_STATUS(bpx_model_schedule(4, 0, NULL, 0, &rows), BPX_OK); // one box: no clock
    CHECK_EQ_U64(rows, 0);
}

// For other m and maximum addresses: clocks per first address i are ceil((max - i) / (2m - 1)),
// and the kept ports cover every pair i < j <= max exactly once.
static void test_schedule_clocks(void)
{
    static const int ms[] = {1, 2, 3, 4, 5, 8, 16, 32};
    static const uint32_t maxima[] = {0, 1, 2, 3, 6, 7, 8, 10, 14, 15, 16, 31, 64, 100, 511};
    uint32_t *ports = NULL;
    size_t capacity = 0;
    uint8_t *seen = check_alloc(512 * 512);
    for (size_t mi = 0; mi < sizeof ms / sizeof ms[0]; mi++) {
        for (size_t xi = 0; xi < sizeof maxima / sizeof maxima[0]; xi++) {
            int m = ms[mi];
            uint32_t max = maxima[xi];
            uint32_t lanes = 2 * (uint32_t)m - 1;
            check_set_context("schedule m=%d max=%u", m, max);
            size_t rows = 0;
            bpx_status s = bpx_model_schedule(m, max, NULL, 0, &rows);
            CHECK(s == (rows ? BPX_ERR_CAPACITY : BPX_OK));
            size_t want_rows = 0;
            for (uint32_t i = 0; i < max; i++)
                want_rows += (max - i + lanes - 1) / lanes;
            CHECK_EQ_U64(rows, want_rows);
            if (rows > capacity) {
                free(ports);
                capacity = rows;
                ports = check_alloc(sizeof(uint32_t) * rows * 2 * (size_t)m);
            }
            CHECK_STATUS(bpx_model_schedule(m, max, ports, capacity, &rows), BPX_OK);
            memset(seen, 0, 512 * 512);
            size_t row = 0;
            for (uint32_t i = 0; i < max; i++) {
                size_t clocks = 0;
                while (row < rows && ports[row * 2 * (size_t)m] == i) {
                    const uint32_t *p = ports + row * 2 * (size_t)m;
                    for (int k = 1; k < 2 * m; k++)
                        if (p[k] != D) {
                            CHECK(p[k] > i && p[k] <= max);
                            if (p[k] > i && p[k] <= max)
                                seen[i * 512 + p[k]]++;
                        } else {
                            CHECK(k > 1); // a row reads at least one kept address
                        }
                    row++;
                    clocks++;
                }
                CHECK_MSG(clocks == (max - i + lanes - 1) / lanes,
                          "first address %u: %zu clocks, want ceil((%u - %u) / %u)", i, clocks, max,
                          i, lanes);
            }
            CHECK_EQ_U64(row, rows);
            for (uint32_t i = 0; i <= max; i++)
                for (uint32_t j = i + 1; j <= max; j++)
                    CHECK_MSG(seen[i * 512 + j] == 1, "pair (%u, %u) read %d times", i, j,
                              seen[i * 512 + j]);
        }
    }
    free(ports);
    free(seen);
}

// ---------------------------------------------------------------------------------------------
// Reports

static void test_bandwidth(void)
{
    check_set_context("peak read bandwidth");
    static const struct {
        int m;
        double gib;
    } paper[] = {{4, 3.219}, {8, 6.437}};
    bpx_box boxes[40];
    CHECK(scene_generate(SCENE_SPARSE, 40, 3, boxes) == 0);
    for (int k = 0; k < 2; k++) {
        bpx_model_config config = bpx_model_default_config();
        config.m = paper[k].m;
        bpx_model *model = new_model(&config);
        if (!model)
            continue;
        bpx_model_report r;
        CHECK_STATUS(bpx_model_run_boxes(model, boxes, 40, &r), BPX_OK);
        double gib = r.peak_read_bytes_per_s / (1024.0 * 1024.0 * 1024.0);
        CHECK_MSG(fabs(gib - paper[k].gib) < 0.0005, "m = %d: %.4f GiB/s, the paper %.3f",
                  paper[k].m, gib, paper[k].gib);
        CHECK(r.achieved_read_bytes_per_s > 0 &&
              r.achieved_read_bytes_per_s <= r.peak_read_bytes_per_s);
        // Block RAM: 6m comparator RAMs + 3 minima RAMs + 4m - 2 FIFOs = 28.5 % and 56.3 % of
        // the XC2V6000's 144 (the paper: 28 % and 56 %).
        CHECK_EQ_U64(r.block_rams, 6 * paper[k].m + 3 + 4 * paper[k].m - 2);
        bpx_model_destroy(model);
    }
}

// Clock counts of the stages, on boxes that never overlap (no stall, no collision).
static void test_clock_counts(void)
{
    static const int ms[] = {1, 2, 4, 8};
    static const uint32_t ns[] = {0, 1, 2, 11, 100, 512};
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * 512);
    for (size_t mi = 0; mi < sizeof ms / sizeof ms[0]; mi++)
        for (size_t ni = 0; ni < sizeof ns / sizeof ns[0]; ni++) {
            int m = ms[mi];
            uint32_t n = ns[ni];
            check_set_context("clock counts m=%d n=%u", m, n);
            CHECK(scene_generate(SCENE_NONE_OVERLAP, n, 5, boxes) == 0);
            bpx_model_config config = bpx_model_default_config();
            config.m = m;
            bpx_model *model = new_model(&config);
            if (!model)
                continue;
            bpx_model_report r;
            CHECK_STATUS(bpx_model_run_boxes(model, boxes, n, &r), BPX_OK);
            uint64_t lanes = 2 * (uint64_t)m - 1, rows = 0;
            for (uint32_t i = 0; i + 1 < n; i++)
                rows += (n - 1 - i + lanes - 1) / lanes;
            CHECK_EQ_U64(r.collisions, 0);
            CHECK_EQ_U64(r.stall_clocks, 0);
            // Updater: n reads, SSRAM latency, the operand register, eight adder registers and the
            // add register (the RAM write follows the last).
            CHECK_EQ_U64(r.update_clocks, n ? n + (uint64_t)config.ssram_latency + 10 : 0);
            // Comparator: one clock per schedule row, then the RAM read, RAM output and result
            // registers empty.
            CHECK_EQ_U64(r.compare_clocks, rows ? rows + 3 : 0);
            CHECK_EQ_U64(r.emit_clocks, 0);
            CHECK_EQ_U64(r.unit_tests, rows * lanes);
            CHECK_EQ_U64(r.chip_clocks, r.update_clocks + r.compare_clocks + r.emit_clocks);
            // Link: boxes down (24 bytes each), start and count registers, nothing read back.
            CHECK_EQ_U64(r.bytes_to_board, 24ull * n);
            CHECK_EQ_U64(r.dma_transfers, n ? 1 : 0);
            CHECK_EQ_U64(r.register_accesses, 2);
            double want_ns =
                (n ? config.link.setup_ns + 24.0 * n / config.link.bytes_per_s * 1e9 : 0) +
                2 * config.link.register_ns;
            CHECK(fabs(r.transfer_ns - want_ns) < 1e-6 * want_ns);
            CHECK(fabs(r.chip_ns - (double)r.chip_clocks / config.clock_hz * 1e9) < 1e-6);
            CHECK(fabs(r.cycle_ns - r.chip_ns - r.transfer_ns) < 1e-6);
            CHECK(r.tiles == 1 && r.on_chip);
            bpx_model_destroy(model);
        }
    free(boxes);
}

// ---------------------------------------------------------------------------------------------
// Pairs against the reference

// A hash of a multiset of pairs: equal for any order of the same pairs.
static uint64_t multiset_hash(const bpx_pair *pairs, size_t count)
{
    uint64_t sum = 0;
    for (size_t k = 0; k < count; k++) {
        uint64_t z = ((uint64_t)pairs[k].i << 32 | pairs[k].j) + 0x9e3779b97f4a7c15ull;
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        sum += z ^ (z >> 31);
    }
    return sum;
}

// The model's sorted pairs equal want; the emitted order holds the same pairs.
static void check_model_pairs(bpx_model *model, const pair_list *want)
{
    size_t count = 0;
    const bpx_pair *pairs = bpx_model_pairs(model, &count);
    CHECK_PAIRS_EQ(want->pairs, want->count, pairs, count);
    size_t emitted_count = 0;
    const bpx_pair *emitted = bpx_model_emitted(model, &emitted_count);
    CHECK_EQ_U64(emitted_count, want->count);
    CHECK(multiset_hash(emitted, emitted_count) == multiset_hash(want->pairs, want->count));
}

typedef struct variant {
    int m;
    bpx_model_store store;
    uint32_t ram_depth;
    uint32_t fifo_depth;
    uint32_t max_n; // largest scene size run on this variant
} variant;

static void test_differential(void)
{
    static const uint32_t sizes[] = {0, 1, 2, 3, 17, 100, 257, 511, 512, 513, 1234, 4099};
    static const variant variants[] = {
        // The paper's RAMs; beyond 512 boxes the host streams tiles of 256.
        {1, BPX_MODEL_STORE_STREAM, 512, 1024, 513},
        {2, BPX_MODEL_STORE_STREAM, 512, 1024, 1234},
        {4, BPX_MODEL_STORE_STREAM, 512, 1024, 4099},
        {8, BPX_MODEL_STORE_STREAM, 512, 1024, 1234},
        {16, BPX_MODEL_STORE_STREAM, 512, 1024, 4099},
        // Tiles from the SSRAM, small RAMs so that even small scenes take many tiles.
        {4, BPX_MODEL_STORE_SSRAM, 64, 1024, 1234},
        {16, BPX_MODEL_STORE_SSRAM, 128, 1024, 1234},
        // FIFOs of one and three entries: dense scenes stall the comparator.
        {4, BPX_MODEL_STORE_STREAM, 512, 1, 1234},
        {8, BPX_MODEL_STORE_STREAM, 512, 3, 513},
    };
    enum { variant_count = sizeof variants / sizeof variants[0] };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * 4099);
    pair_list want = {0};
    uint64_t stalls[variant_count] = {0};
    double seconds[variant_count] = {0};
    bpx_model *models[variant_count] = {0};
    for (int v = 0; v < variant_count; v++) {
        bpx_model_config config = bpx_model_default_config();
        config.m = variants[v].m;
        config.store = variants[v].store;
        config.ram_depth = variants[v].ram_depth;
        config.fifo_depth = variants[v].fifo_depth;
        models[v] = new_model(&config);
    }
    bpx_world *reference = reference_world();
    for (int k = 0; k < SCENE_KIND_COUNT && reference; k++) {
        for (size_t si = 0; si < sizeof sizes / sizeof sizes[0]; si++) {
            uint32_t n = sizes[si];
            if (k == SCENE_ALL_OVERLAP && n > 1234)
                continue;
            // The largest size on a few kinds only: it costs a million clocks each.
            if (n == 4099 && k != SCENE_SPARSE && k != SCENE_DENSE && k != SCENE_TOUCHING &&
                k != SCENE_SHARED_COORD)
                continue;
            uint64_t seed = 1000 + (uint64_t)si;
            check_set_seed(seed);
            check_set_context("scene=%s n=%u reference", scene_kind_name((scene_kind)k), n);
            CHECK(scene_generate((scene_kind)k, n, seed, boxes) == 0);
            reference_pairs(reference, boxes, n, &want);
            for (int v = 0; v < variant_count; v++) {
                const variant *va = &variants[v];
                if (!models[v] || n > va->max_n)
                    continue;
                check_set_context("scene=%s n=%u m=%d store=%s ram=%u fifo=%u",
                                  scene_kind_name((scene_kind)k), n, va->m,
                                  bpx_model_store_name(va->store), va->ram_depth, va->fifo_depth);
                double t0 = now_s();
                bpx_model_report r;
                CHECK_STATUS(bpx_model_run_boxes(models[v], boxes, n, &r), BPX_OK);
                seconds[v] += now_s() - t0;
                check_model_pairs(models[v], &want);
                CHECK_EQ_U64(r.collisions, want.count);
                CHECK_EQ_U64(r.n, n);
                CHECK(r.on_chip == (n <= va->ram_depth));
                CHECK(r.fifo_peak <= va->fifo_depth);
                CHECK(r.stall_clocks <= r.compare_clocks);
                CHECK_EQ_U64(r.chip_clocks, r.update_clocks + r.compare_clocks + r.emit_clocks);
                if (!r.on_chip) {
                    uint32_t tile = va->ram_depth / 2, tiles = (n + tile - 1) / tile;
                    CHECK_EQ_U64(r.tiles, tiles);
                    CHECK_EQ_U64(r.tile_loads, (uint64_t)tiles * (tiles + 1) / 2);
                }
                stalls[v] += r.stall_clocks;
            }
        }
    }
    for (int v = 0; v < variant_count; v++) {
        printf("  m=%-2d store=%-7s ram=%-4u fifo=%-4u up to n=%-4u: %6.2f s, %" PRIu64
               " stall clocks\n",
               variants[v].m, bpx_model_store_name(variants[v].store), variants[v].ram_depth,
               variants[v].fifo_depth, variants[v].max_n, seconds[v], stalls[v]);
        if (variants[v].fifo_depth <= 3) {
            check_set_context("m=%d fifo=%u", variants[v].m, variants[v].fifo_depth);
            CHECK_MSG(stalls[v] > 0, "tiny FIFOs never overflowed");
        }
        bpx_model_destroy(models[v]);
    }
    bpx_world_destroy(reference);
    pair_list_free(&want);
    free(boxes);
}

// The paper's two phases (minima once, centres each cycle) against a reference world fed the
// same minima and centres: on chip, and tiled from the SSRAM and streamed with small RAMs.
static void test_centres(void)
{
    static const struct {
        bpx_model_store store;
        uint32_t ram_depth;
        uint32_t n;
    } cases[] = {
        {BPX_MODEL_STORE_ON_CHIP, 512, 0},  {BPX_MODEL_STORE_ON_CHIP, 512, 1},
        {BPX_MODEL_STORE_ON_CHIP, 512, 50}, {BPX_MODEL_STORE_ON_CHIP, 512, 512},
        {BPX_MODEL_STORE_SSRAM, 64, 300},   {BPX_MODEL_STORE_STREAM, 64, 300},
        {BPX_MODEL_STORE_STREAM, 512, 700},
    };
    static const scene_kind kinds[] = {SCENE_UNIFORM_DENSITY, SCENE_TOUCHING, SCENE_MIXED_SIZES,
                                       SCENE_SIGNED_ZERO, SCENE_DENSE};
    enum { cycles = 3, max_n = 700 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * max_n);
    float *minima = check_alloc(sizeof(float) * 3 * max_n);
    float *centres = check_alloc(sizeof(float) * 3 * max_n);
    pair_list want = {0};
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_REFERENCE;
    bpx_world *truth = NULL;
    CHECK_STATUS(bpx_world_create(&def, &truth), BPX_OK);
    for (size_t c = 0; c < sizeof cases / sizeof cases[0] && truth; c++) {
        for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++) {
            uint32_t n = cases[c].n;
            uint64_t seed = 77 + k;
            check_set_seed(seed);
            check_set_context("centres scene=%s n=%u store=%s ram=%u", scene_kind_name(kinds[k]), n,
                              bpx_model_store_name(cases[c].store), cases[c].ram_depth);
            CHECK(scene_generate(kinds[k], n, seed, boxes) == 0);
            for (uint32_t i = 0; i < n; i++)
                for (int a = 0; a < 3; a++) {
                    float half = (boxes[i].max[a] - boxes[i].min[a]) * 0.5f;
                    minima[3 * i + a] = -half;
                    centres[3 * i + a] = boxes[i].min[a] + half;
                }
            bpx_model_config config = bpx_model_default_config();
            config.store = cases[c].store;
            config.ram_depth = cases[c].ram_depth;
            bpx_model *model = new_model(&config);
            if (!model)
                continue;
            bpx_model_report r;
            CHECK_STATUS(bpx_model_load_extents(model, minima, n, &r), BPX_OK);
            CHECK_STATUS(bpx_world_load_extents(truth, minima, n), BPX_OK);
            if (n <= cases[c].ram_depth) // the updater copies the minima on chip
                CHECK_EQ_U64(r.update_clocks, n ? n + (uint64_t)config.ssram_latency + 10 : 0);
            scene_rng motion;
            scene_rng_seed(&motion, seed);
            for (int cycle = 0; cycle < cycles; cycle++) {
                for (uint32_t i = 0; i < 3 * n && cycle > 0; i++)
                    centres[i] += scene_rng_range(&motion, -0.05f, 0.05f);
                CHECK_STATUS(bpx_world_update_centres(truth, centres), BPX_OK);
                CHECK_STATUS(bpx_world_collide(truth), BPX_OK);
                size_t count = 0;
                const bpx_pair *pairs = bpx_world_pairs(truth, &count);
                pair_list_set(&want, pairs, count);
                CHECK_STATUS(bpx_model_run_centres(model, centres, &r), BPX_OK);
                check_model_pairs(model, &want);
                // Centres are 12 bytes an object; a streaming host sends 24 (centre and
                // minimum) with every tile it loads.
                if (n <= cases[c].ram_depth || cases[c].store == BPX_MODEL_STORE_SSRAM)
                    CHECK_EQ_U64(r.bytes_to_board, 12ull * n);
                else
                    CHECK(r.bytes_to_board > 24ull * n);
                CHECK_EQ_U64(r.bytes_to_host, 4 * want.count);
            }
            bpx_model_destroy(model);
        }
    }
    bpx_world_destroy(truth);
    pair_list_free(&want);
    free(boxes);
    free(minima);
    free(centres);
}

// ---------------------------------------------------------------------------------------------
// Trace hook

typedef struct trace_log {
    uint64_t calls;
    uint64_t last_clock;
    bool ordered;
    uint32_t (*rows)[8];
    size_t row_count;
    size_t compare_rows; // addressing clocks seen, not stalled
    bool rows_match;
    pair_list emitted;
    size_t emitted_capacity;
    uint64_t stalled;
} trace_log;

static void trace_hook(const bpx_model_clock *c, void *user)
{
    trace_log *log = user;
    if (log->calls > 0 && c->clock <= log->last_clock)
        log->ordered = false;
    log->calls++;
    log->last_clock = c->clock;
    log->stalled += c->stalled;
    if (c->addressing && !c->stalled && c->port_count == 8) {
        size_t r = log->compare_rows++;
        if (r >= log->row_count || memcmp(log->rows[r], c->ports, sizeof log->rows[r]) != 0)
            log->rows_match = false;
    }
    if (c->emitted) {
        if (log->emitted.count == log->emitted.capacity) {
            pair_list grown = {0};
            pair_list_reserve(&grown, 2 * log->emitted.capacity + 16);
            pair_list_set(&grown, log->emitted.pairs, log->emitted.count);
            pair_list_free(&log->emitted);
            log->emitted = grown;
        }
        log->emitted.pairs[log->emitted.count++] = c->pair;
    }
}

static void test_trace(void)
{
    check_set_context("trace hook");
    enum { n = 11 };
    // Eleven boxes that all overlap: Table 1's schedule, and FIFOs of two entries overflow.
    bpx_box boxes[n];
    for (int i = 0; i < n; i++)
        boxes[i] = (bpx_box){{(float)i, 0, 0}, {(float)i + 20, 1, 1}};
    trace_log log = {.ordered = true, .rows_match = true};
    uint32_t rows[13][8];
    size_t row_count = 0;
    CHECK_STATUS(bpx_model_schedule(4, n - 1, &rows[0][0], 13, &row_count), BPX_OK);
    log.rows = rows;
    log.row_count = row_count;
    bpx_model_config config = bpx_model_default_config();
    config.fifo_depth = 2;
    config.trace = trace_hook;
    config.trace_user = &log;
    bpx_model *model = new_model(&config);
    if (!model)
        return;
    bpx_model_report r;
    CHECK_STATUS(bpx_model_run_boxes(model, boxes, n, &r), BPX_OK);
    CHECK_EQ_U64(log.calls, r.simulated_clocks);
    CHECK_EQ_U64(log.calls, r.chip_clocks); // nothing streamed: every clock is stepped
    CHECK(log.ordered);
    CHECK(log.rows_match);
    CHECK_EQ_U64(log.compare_rows, row_count);
    CHECK_EQ_U64(log.stalled, r.stall_clocks);
    CHECK(r.stall_clocks > 0);
    CHECK_EQ_U64(r.collisions, n * (n - 1) / 2);
    size_t count = 0;
    const bpx_pair *emitted = bpx_model_emitted(model, &count);
    CHECK_PAIRS_EQ(emitted, count, log.emitted.pairs, log.emitted.count);
    // The round robin interleaves the units' FIFOs: the natural order is not (i, j) order.
    const bpx_pair *sorted = bpx_model_pairs(model, &count);
    CHECK(count > 0 && memcmp(sorted, emitted, count * sizeof(bpx_pair)) != 0);
    CHECK(pairs_well_formed(sorted, count, n));
    pair_list_free(&log.emitted);
    bpx_model_destroy(model);
}

static void count_hook(const bpx_model_clock *c, void *user)
{
    (void)c;
    ++*(uint64_t *)user;
}

// Without a trace hook the machine steps the comparator alone while the other units have
// nothing to do (quiet clocks); with one, every unit is stepped every clock. Both must give
// the same clocks, stalls and emitted order.
static void test_quiet_clocks(void)
{
    static const struct {
        scene_kind kind;
        uint32_t n;
        bpx_model_store store;
        uint32_t fifo_depth;
    } cases[] = {
        {SCENE_SPARSE, 400, BPX_MODEL_STORE_ON_CHIP, 1024},
        {SCENE_DENSE, 500, BPX_MODEL_STORE_ON_CHIP, 1024},
        {SCENE_DENSE, 500, BPX_MODEL_STORE_ON_CHIP, 2},
        {SCENE_CLUSTERED, 1100, BPX_MODEL_STORE_STREAM, 1024},
        {SCENE_ALL_OVERLAP, 300, BPX_MODEL_STORE_SSRAM, 4},
    };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * 1100);
    pair_list first = {0};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        check_set_context("quiet clocks: scene=%s n=%u store=%s fifo=%u",
                          scene_kind_name(cases[c].kind), cases[c].n,
                          bpx_model_store_name(cases[c].store), cases[c].fifo_depth);
        CHECK(scene_generate(cases[c].kind, cases[c].n, 3, boxes) == 0);
        bpx_model_report r[2];
        uint64_t calls = 0;
        for (int traced = 0; traced < 2; traced++) {
            bpx_model_config config = bpx_model_default_config();
            config.store = cases[c].store;
            config.fifo_depth = cases[c].fifo_depth;
            if (traced) {
                config.trace = count_hook;
                config.trace_user = &calls;
            }
            bpx_model *model = new_model(&config);
            if (!model)
                return;
            CHECK_STATUS(bpx_model_run_boxes(model, boxes, cases[c].n, &r[traced]), BPX_OK);
            size_t count = 0;
            const bpx_pair *emitted = bpx_model_emitted(model, &count);
            if (!traced)
                pair_list_set(&first, emitted, count);
            else
                CHECK_PAIRS_EQ(first.pairs, first.count, emitted, count);
            bpx_model_destroy(model);
        }
        CHECK_EQ_U64(r[0].update_clocks, r[1].update_clocks);
        CHECK_EQ_U64(r[0].compare_clocks, r[1].compare_clocks);
        CHECK_EQ_U64(r[0].stall_clocks, r[1].stall_clocks);
        CHECK_EQ_U64(r[0].emit_clocks, r[1].emit_clocks);
        CHECK_EQ_U64(r[0].unit_tests, r[1].unit_tests);
        CHECK_EQ_U64(r[0].discarded_tests, r[1].discarded_tests);
        CHECK_EQ_U64(r[0].fifo_peak, r[1].fifo_peak);
        CHECK(r[0].transfer_ns == r[1].transfer_ns);
        CHECK_EQ_U64(calls, r[1].simulated_clocks);
        CHECK(r[0].simulated_clocks <= r[1].simulated_clocks);
    }
    pair_list_free(&first);
    free(boxes);
}

// ---------------------------------------------------------------------------------------------
// The backend "model" through a world

static void test_backend(void)
{
    check_set_context("backend model");
    bpx_backend_info info = bpx_backend_query(BPX_BACKEND_MODEL);
    CHECK(info.available);
    CHECK(strcmp(info.name, "model") == 0);
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_MODEL;
    bpx_world *world = NULL;
    CHECK_STATUS(bpx_world_create(&def, &world), BPX_OK);
    if (!world)
        return;
    enum { n = 2000 }; // beyond the on-chip RAMs: streamed tiles
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    pair_list want = {0};
    bpx_world *reference = reference_world();
    for (uint64_t seed = 1; seed <= 3 && reference; seed++) {
        CHECK(scene_generate(SCENE_DENSE, n, seed, boxes) == 0);
        reference_pairs(reference, boxes, n, &want);
        CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
        double t0 = now_s();
        CHECK_STATUS(bpx_world_collide(world), BPX_OK);
        if (seed == 1)
            printf("  backend model: dense n=%d, %zu pairs, %.3f s per collide\n", n, want.count,
                   now_s() - t0);
        size_t count = 0;
        const bpx_pair *pairs = bpx_world_pairs(world, &count);
        CHECK_PAIRS_EQ(want.pairs, want.count, pairs, count);
        CHECK(bpx_world_stats(world).pair_tests >= (uint64_t)n * (n - 1) / 2);
    }
    pair_list_free(&want);
    free(boxes);
    bpx_world_destroy(reference);
    bpx_world_destroy(world);
}
int main(void)
{
    double t0 = now_s();
    printf("test_model: Table 1, schedules, clocks, reports, differential (m = 1, 2, 4, 8, 16), "
           "two phases, trace, backend\n");
    test_table1();
    test_schedule_clocks();
    test_bandwidth();
    test_clock_counts();
    test_differential();
    test_centres();
    test_trace();
    test_quiet_clocks();
    test_backend();
    printf("  %.2f s\n", now_s() - t0);
    return check_finish("test_model", 1);
}
