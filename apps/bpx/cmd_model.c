// bpx model: the clock-by-clock model of the paper's FPGA (include/bpx/model.h) on a scene or a
// trace; its address schedule (Table 1); a per-clock trace; and --paper, the model next to
// Table 2's measured FPGA times. SPDX-License-Identifier: MIT
//
// The scene is the paper's test scenario (§5) as `bpx demo` runs it (apps/demo/demo_sim.h, with
// its defaults: one layer of spheres of radius 25 m with 10 m gaps in a box 400 m high, random
// velocities in (-40, 40) m/s per axis, elastic, time step 1/60 s). Only n and the collisions
// per cycle matter to the model.
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "demo_sim.h"

static const char *const command = "model";

enum {
    DEFAULT_BOXES = 500,
    DEFAULT_SCHEDULE_BOXES = 11, // Table 1: maximum address 10
    DEFAULT_CYCLES = 200,
    DEFAULT_PAPER_CYCLES = 1000,
    DEFAULT_WARMUP = 1200,
    MAX_SCENE_BOXES = 1000000,
    PAPER_ROWS = 10,
};

// ---------------------------------------------------------------------------------------------
// Table 2 of the paper: the FPGA columns, the communication column and collisions per cycle.

typedef struct paper_row {
    uint32_t n;
    double fpga_ms[2]; // m = 4, m = 8
    double comm_ms;
    double share[2]; // communication share, %, m = 4, m = 8
    double collisions;
} paper_row;

static const paper_row table2[PAPER_ROWS] = {
    {50, {0.242, 0.216}, 0.178, {73.542, 82.096}, 7.47},
    {100, {0.289, 0.276}, 0.194, {67.304, 70.478}, 12.588},
    {150, {0.332, 0.289}, 0.199, {59.825, 68.701}, 20.413},
    {200, {0.356, 0.312}, 0.208, {58.418, 66.653}, 26.703},
    {250, {0.419, 0.348}, 0.218, {51.958, 62.578}, 35.628},
    {300, {0.471, 0.368}, 0.225, {47.772, 61.064}, 44.61},
    {350, {0.5, 0.394}, 0.235, {47.094, 59.709}, 51.416},
    {400, {0.569, 0.425}, 0.25, {43.935, 58.822}, 60.053},
    {450, {0.631, 0.464}, 0.253, {40.183, 54.594}, 64.427},
    {500, {0.731, 0.513}, 0.27, {37.001, 52.743}, 76.079},
};
static const int paper_m[2] = {4, 8};

// ---------------------------------------------------------------------------------------------
// Options

typedef struct model_options {
    bpx_model_config config;
    uint32_t boxes; // 0: not given
    const char *trace_path;
    int cycles;
    bool cycles_given;
    int warmup;
    uint64_t seed;
    int clocks; // per-clock lines to print
    bool schedule;
    bool paper;
} model_options;

static void print_help(void)
{
    printf("usage: bpx model [--m M] [--clock MHZ] [--boxes N | --trace FILE] [--schedule]\n"
           "                 [--paper] [--clocks K] [--cycles C] [--warmup W] [--seed S]\n"
           "                 [--store NAME] [--ram-depth D] [--fifo-depth F]\n"
           "                 [--setup-us US] [--link-mbs MBS] [--register-us US]\n"
           "\n"
           "Runs the clock-by-clock model of the paper's FPGA (updater, comparator, collision\n"
           "emitter, CPU-IC interface) and reports per broad-phase cycle: clocks per stage\n"
           "(update, compare, emit, transfer), stall clocks, the predicted time at the clock,\n"
           "the comparator's peak read bandwidth, on-chip memory use and the communication\n"
           "share. The scene is the paper's as `bpx demo` runs it (its defaults): n spheres of\n"
           "radius 25 m, 10 m gaps, a box 400 m high, velocities in (-40, 40) m/s, elastic.\n"
           "\n"
           "  --m M           2m RAM ports, 2m - 1 comparison units, 1..%d (default 4)\n"
           "  --clock MHZ     chip clock (default 108)\n"
           "  --boxes N       spheres in the scene (default %d); with --schedule, boxes to\n"
           "                  address (default %d, Table 1's maximum address 10)\n"
           "  --trace FILE    replay an AABB trace (BPXTRACE version 1) instead of the scene:\n"
           "                  general boxes, min and max sent each cycle (24 bytes per box)\n"
           "  --schedule      print the comparator's address schedule (Table 1 layout) and stop\n"
           "  --clocks K      print the first K clocks of the first measured cycle\n"
           "  --paper         sweep n = 50..500 for m = 4 and 8 and print the model next to\n"
           "                  Table 2 of the paper, with the link's setup cost fitted\n"
           "  --cycles C      measured cycles (default %d; %d with --paper)\n"
           "  --warmup W      simulated cycles before measuring (default %d)\n"
           "  --seed S        seed of the initial velocities (default 1)\n"
           "  --store NAME    where boxes beyond the on-chip RAMs live: on-chip (the paper's\n"
           "                  512-box limit, default), ssram (524288), stream (any n)\n"
           "  --ram-depth D   boxes per on-chip RAM (default 512)\n"
           "  --fifo-depth F  entries per emitter FIFO (default 1024)\n"
           "  --setup-us US   link cost per DMA transfer, us (default %.1f)\n"
           "  --link-mbs MBS  link bandwidth, MB/s (default %.0f: PCI 32 bit, 66 MHz)\n"
           "  --register-us US  link cost per register access, us (default %.2f)\n"
           "  -h, --help      show this help\n",
           BPX_MODEL_MAX_M, DEFAULT_BOXES, DEFAULT_SCHEDULE_BOXES, DEFAULT_CYCLES,
           DEFAULT_PAPER_CYCLES, DEFAULT_WARMUP, bpx_model_default_config().link.setup_ns * 1e-3,
           bpx_model_default_config().link.bytes_per_s * 1e-6,
           bpx_model_default_config().link.register_ns * 1e-3);
}

static bool parse_double(const char *text, double lo, double hi, double *out)
{
    char *end = NULL;
    double v = strtod(text, &end);
    if (end == text || *end != '\0' || !(v >= lo && v <= hi))
        return false;
    *out = v;
    return true;
}

static int parse_args(int argc, char **argv, model_options *o)
{
    for (int k = 1; k < argc; k++) {
        const char *v = NULL;
        cli_match m;
        double d;
        int i;
#define FLAG(name) (m = cli_flag_value(argc, argv, &k, name, &v)) != CLI_NO_MATCH
#define NEED(ok, message)                                                                          \
    if (m == CLI_MISSING_VALUE || !(ok))                                                           \
        return cli_usage_error(command, message);
        if (cli_is_flag(argv[k], "--schedule")) {
            o->schedule = true;
        } else if (cli_is_flag(argv[k], "--paper")) {
            o->paper = true;
        } else if (FLAG("--m")) {
            NEED(cli_parse_int(v, 1, BPX_MODEL_MAX_M, &o->config.m), "--m wants 1..32");
        } else if (FLAG("--clock")) {
            NEED(parse_double(v, 1e-3, 1e6, &d), "--clock wants MHz, e.g. 108");
            o->config.clock_hz = d * 1e6;
        } else if (FLAG("--boxes")) {
            NEED(cli_parse_int(v, 1, MAX_SCENE_BOXES, &i), "--boxes wants 1..1000000");
            o->boxes = (uint32_t)i;
        } else if (FLAG("--trace")) {
            NEED(v[0] != '\0', "--trace wants a file name");
            o->trace_path = v;
        } else if (FLAG("--clocks")) {
            NEED(cli_parse_int(v, 0, 100000000, &o->clocks), "--clocks wants a count");
        } else if (FLAG("--cycles")) {
            NEED(cli_parse_int(v, 1, 10000000, &o->cycles), "--cycles wants a positive count");
            o->cycles_given = true;
        } else if (FLAG("--warmup")) {
            NEED(cli_parse_int(v, 0, 10000000, &o->warmup), "--warmup wants a count");
        } else if (FLAG("--seed")) {
            char *end = NULL;
            o->seed = m == CLI_MATCH ? strtoull(v, &end, 10) : 0;
            NEED(end && end != v && *end == '\0', "--seed wants an unsigned integer");
        } else if (FLAG("--store")) {
            bool found = false;
            for (int s = 0; s < BPX_MODEL_STORE_COUNT && m == CLI_MATCH; s++)
                if (strcmp(v, bpx_model_store_name((bpx_model_store)s)) == 0) {
                    o->config.store = (bpx_model_store)s;
                    found = true;
                }
            NEED(found, "--store wants on-chip, ssram or stream");
        } else if (FLAG("--ram-depth")) {
            NEED(cli_parse_int(v, 4, 1 << 20, &i), "--ram-depth wants 4..1048576");
            o->config.ram_depth = (uint32_t)i;
        } else if (FLAG("--fifo-depth")) {
            NEED(cli_parse_int(v, 1, 1 << 20, &i), "--fifo-depth wants 1..1048576");
            o->config.fifo_depth = (uint32_t)i;
        } else if (FLAG("--setup-us")) {
            NEED(parse_double(v, 0, 1e9, &d), "--setup-us wants microseconds >= 0");
            o->config.link.setup_ns = d * 1e3;
        } else if (FLAG("--link-mbs")) {
            NEED(parse_double(v, 1e-6, 1e9, &d), "--link-mbs wants MB/s > 0");
            o->config.link.bytes_per_s = d * 1e6;
        } else if (FLAG("--register-us")) {
            NEED(parse_double(v, 0, 1e9, &d), "--register-us wants microseconds >= 0");
            o->config.link.register_ns = d * 1e3;
        } else {
            return cli_usage_error(command, "unknown argument \"%s\"", argv[k]);
        }
#undef FLAG
#undef NEED
    }
    if (o->trace_path && o->boxes)
        return cli_usage_error(command, "--boxes and --trace exclude each other");
    if (o->paper && (o->trace_path || o->boxes || o->schedule))
        return cli_usage_error(command, "--paper runs its own scenes: no --boxes, --trace or "
                                        "--schedule");
    if (o->schedule && o->trace_path)
        return cli_usage_error(command, "--schedule takes --boxes, not --trace");
    bpx_error err;
    if (bpx_model_check_config(&o->config, &err) != BPX_OK)
        return cli_usage_error(command, "%s", err.message);
    return CLI_EXIT_OK;
}

// ---------------------------------------------------------------------------------------------
// The paper's scene: spheres in a box, the demo's simulation (apps/demo/demo_sim.h), so the
// model sees exactly the cycles `bpx demo` runs.

typedef struct spheres {
    uint32_t n;
    demo_sim *sim;
    float *minima;  // 3n: the origin-centred AABB minima, -radius
    float *centres; // 3n: this cycle's centres as sent to the board
} spheres;

static void spheres_free(spheres *s)
{
    free(s->minima);
    free(s->centres);
    demo_sim_destroy(s->sim);
    memset(s, 0, sizeof *s);
}

// The centres as the demo's broad phase sends them to bpx: the positions rounded to float.
static void spheres_centres(spheres *s)
{
    const double *pos = demo_sim_positions(s->sim);
    for (size_t k = 0; k < 3 * (size_t)s->n; k++)
        s->centres[k] = (float)pos[k];
}

// The demo's defaults (docs/demo.md) with n spheres and the given seed.
static int spheres_init(spheres *s, uint32_t n, uint64_t seed)
{
    memset(s, 0, sizeof *s);
    demo_params params = demo_default_params();
    params.sphere_count = n;
    params.seed = seed;
    demo_error err;
    s->n = n;
    s->minima = malloc(sizeof(float) * 3 * n);
    s->centres = malloc(sizeof(float) * 3 * n);
    if (!s->minima || !s->centres || demo_sim_create(&params, NULL, &s->sim, &err) != 0) {
        spheres_free(s);
        return -1;
    }
    for (size_t k = 0; k < 3 * (size_t)n; k++)
        s->minima[k] = (float)-params.radius;
    spheres_centres(s);
    return 0;
}

// One cycle of the demo's loop; *pairs are its broad phase's, valid until the next call.
static int spheres_advance(spheres *s, const bpx_pair **pairs, size_t *count)
{
    demo_error err;
    if (demo_sim_step(s->sim, NULL, &err) != 0)
        return -1;
    *pairs = demo_sim_pairs(s->sim, count);
    spheres_centres(s);
    return 0;
}

// ---------------------------------------------------------------------------------------------
// A trace file, BPXTRACE version 1: 32-byte header ("BPXTRACE", u32 version 1, u32 n,
// u64 cycles, u32 floats per box = 6, u32 reserved = 0), then the cycles' boxes, 24 bytes
// each, little-endian.

typedef struct trace_file {
    FILE *file;
    uint32_t n;
    uint64_t cycles;
    unsigned char *bytes;
} trace_file;

static uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static int trace_open(trace_file *t, const char *path, char *message, size_t size)
{
    memset(t, 0, sizeof *t);
    unsigned char h[32];
    t->file = fopen(path, "rb");
    if (!t->file) {
        snprintf(message, size, "cannot open %s", path);
        return -1;
    }
    if (fread(h, 1, sizeof h, t->file) != sizeof h || memcmp(h, "BPXTRACE", 8) != 0 ||
        le32(h + 8) != 1 || le32(h + 24) != 6 || le32(h + 28) != 0) {
        snprintf(message, size, "%s: not a BPXTRACE version 1 file", path);
        return -1;
    }
    t->n = le32(h + 12);
    t->cycles = (uint64_t)le32(h + 16) | (uint64_t)le32(h + 20) << 32;
    if (t->n == 0 || t->n > MAX_SCENE_BOXES || t->cycles == 0) {
        snprintf(message, size, "%s: %u boxes and %llu cycles: nothing this tool can replay", path,
                 t->n, (unsigned long long)t->cycles);
        return -1;
    }
    if (!(t->bytes = malloc((size_t)t->n * 24))) {
        snprintf(message, size, "out of memory");
        return -1;
    }
    return 0;
}

// Reads one cycle into boxes (the model validates every box).
static int trace_read(trace_file *t, bpx_box *boxes, char *message, size_t size)
{
    if (fread(t->bytes, 24, t->n, t->file) != t->n) {
        snprintf(message, size, "the trace ends before its announced cycles");
        return -1;
    }
    for (uint32_t i = 0; i < t->n; i++)
        for (int c = 0; c < 6; c++) {
            uint32_t bits = le32(t->bytes + 24 * (size_t)i + 4 * (size_t)c);
            float v;
            memcpy(&v, &bits, sizeof v);
            if (c < 3)
                boxes[i].min[c] = v;
            else
                boxes[i].max[c - 3] = v;
        }
    return 0;
}

static void trace_close(trace_file *t)
{
    if (t->file)
        fclose(t->file);
    free(t->bytes);
    memset(t, 0, sizeof *t);
}

// ---------------------------------------------------------------------------------------------
// Reports

typedef struct report_sum {
    int cycles;
    double collisions, update, compare, stall, emit, chip, transfer_clocks;
    double chip_ns, transfer_ns, cycle_ns, dma, registers, bytes_down, bytes_up;
    double unit_tests, discarded, achieved;
    uint32_t fifo_peak;
    bpx_model_report last;
} report_sum;

static void report_add(report_sum *s, const bpx_model_report *r)
{
    s->cycles++;
    s->collisions += (double)r->collisions;
    s->update += (double)r->update_clocks;
    s->compare += (double)r->compare_clocks;
    s->stall += (double)r->stall_clocks;
    s->emit += (double)r->emit_clocks;
    s->chip += (double)r->chip_clocks;
    s->transfer_clocks += (double)r->transfer_clocks;
    s->chip_ns += r->chip_ns;
    s->transfer_ns += r->transfer_ns;
    s->cycle_ns += r->cycle_ns;
    s->dma += (double)r->dma_transfers;
    s->registers += (double)r->register_accesses;
    s->bytes_down += (double)r->bytes_to_board;
    s->bytes_up += (double)r->bytes_to_host;
    s->unit_tests += (double)r->unit_tests;
    s->discarded += (double)r->discarded_tests;
    s->achieved += r->achieved_read_bytes_per_s;
    s->fifo_peak = r->fifo_peak > s->fifo_peak ? r->fifo_peak : s->fifo_peak;
    s->last = *r;
}

static double mean(const report_sum *s, double total)
{
    return s->cycles ? total / s->cycles : 0;
}

static const double gib = 1024.0 * 1024.0 * 1024.0;

static void print_report(const report_sum *s, const bpx_model_config *c)
{
    const bpx_model_report *r = &s->last;
    double cycle = mean(s, s->cycle_ns);
    printf("per cycle (mean of %d)   clocks        us   of the cycle\n", s->cycles);
    const struct {
        const char *name;
        double clocks, ns;
    } rows[] = {
        {"update", mean(s, s->update), mean(s, s->update) / c->clock_hz * 1e9},
        {"compare", mean(s, s->compare), mean(s, s->compare) / c->clock_hz * 1e9},
        {"  of which stalled", mean(s, s->stall), mean(s, s->stall) / c->clock_hz * 1e9},
        {"emit (after compare)", mean(s, s->emit), mean(s, s->emit) / c->clock_hz * 1e9},
        {"chip", mean(s, s->chip), mean(s, s->chip_ns)},
        {"transfer (link)", mean(s, s->transfer_clocks), mean(s, s->transfer_ns)},
    };
    for (size_t k = 0; k < sizeof rows / sizeof rows[0]; k++)
        printf("  %-20s %10.1f %10.2f   %5.1f %%\n", rows[k].name, rows[k].clocks,
               rows[k].ns * 1e-3, cycle > 0 ? 100 * rows[k].ns / cycle : 0);
    printf("  %-20s %10s %10.2f   predicted at %.1f MHz; communication share %.1f %%\n", "cycle",
           "", cycle * 1e-3, c->clock_hz * 1e-6,
           cycle > 0 ? 100 * mean(s, s->transfer_ns) / cycle : 0);
    printf("collisions per cycle: %.2f (emitter: %d FIFOs of %u entries, fullest %u)\n",
           mean(s, s->collisions), 4 * c->m - 2, c->fifo_depth, s->fifo_peak);
    printf("comparator: %.0f unit tests per cycle, %.1f %% discarded; peak read bandwidth %.3f "
           "GiB/s per 2m-width memory (%.3f GiB/s for all six), achieved %.3f GiB/s\n",
           mean(s, s->unit_tests), s->unit_tests > 0 ? 100 * s->discarded / s->unit_tests : 0,
           r->peak_read_bytes_per_s / gib, 6 * r->peak_read_bytes_per_s / gib,
           mean(s, s->achieved) / gib);
    printf("link: %.2f DMA transfers (%.0f bytes to the board, %.0f back) and %.0f register "
           "accesses per cycle\n",
           mean(s, s->dma), mean(s, s->bytes_down), mean(s, s->bytes_up), mean(s, s->registers));
    printf("boxes: %s (%u tile%s of %u)\n", r->on_chip ? "all on chip" : "tiled", r->tiles,
           r->tiles == 1 ? "" : "s", r->on_chip ? r->n : c->ram_depth / 2);
    printf("on-chip memory: comparator 6 x %d x %u words, updater 3 x %u words, FIFOs %d x %u "
           "entries: %.1f KiB in %d block RAMs of 18 Kb (%.1f %% of the XC2V6000's 144; the "
           "paper: 28 %% at m = 4, 56 %% at m = 8)\n",
           c->m, c->ram_depth, c->ram_depth, 4 * c->m - 2, c->fifo_depth,
           (double)r->on_chip_bytes / 1024, r->block_rams, 100.0 * r->block_rams / 144);
    if (r->collision_overflow)
        printf("note: more collisions than one SSRAM bank holds (%u words)\n", c->ssram_depth);
}

static void print_config(const bpx_model_config *c)
{
    printf("model: m = %d (%d ports, %d comparison units), %.1f MHz, on-chip RAMs of %u boxes, "
           "store %s, FIFOs of %u, SSRAM latency %d\n",
           c->m, 2 * c->m, 2 * c->m - 1, c->clock_hz * 1e-6, c->ram_depth,
           bpx_model_store_name(c->store), c->fifo_depth, c->ssram_latency);
    printf("link: %.1f MB/s, %.1f us per DMA transfer, %.2f us per register access\n",
           c->link.bytes_per_s * 1e-6, c->link.setup_ns * 1e-3, c->link.register_ns * 1e-3);
}

// ---------------------------------------------------------------------------------------------
// Per-clock printing (--clocks)

typedef struct clock_printer {
    int left;
} clock_printer;

static void print_clock(const bpx_model_clock *c, void *user)
{
    clock_printer *p = user;
    if (p->left <= 0)
        return;
    p->left--;
    static const char *const phases[BPX_MODEL_PHASE_COUNT] = {"init", "update", "compare", "drain",
                                                              "wait"};
    printf("%8llu %-7s", (unsigned long long)c->clock, phases[c->phase]);
    if (c->addressing) {
        printf(" ports %u |", c->ports[0]);
        for (int k = 1; k < c->port_count; k++)
            if (c->ports[k] == BPX_MODEL_DISCARDED)
                printf(" -");
            else
                printf(" %u", c->ports[k]);
    }
    if (c->hits)
        printf("  hits 0x%llx (row %u)", (unsigned long long)c->hits, c->hit_row);
    if (c->stalled)
        printf("  STALL");
    if (c->emitted)
        printf("  out (%u, %u)", c->pair.i, c->pair.j);
    printf("  fifo %u\n", c->fifo_fill_max);
}

// ---------------------------------------------------------------------------------------------
// Modes

static int run_schedule(const model_options *o)
{
    uint32_t boxes = o->boxes ? o->boxes : DEFAULT_SCHEDULE_BOXES;
    int m = o->config.m, ports = 2 * m;
    size_t rows = 0;
    bpx_model_schedule(m, boxes - 1, NULL, 0, &rows);
    if (rows > 10000000) {
        cli_error(command, "%zu rows: too many to print", rows);
        return CLI_EXIT_ERROR;
    }
    uint32_t *table = malloc(sizeof(uint32_t) * (rows ? rows : 1) * (size_t)ports);
    if (!table || bpx_model_schedule(m, boxes - 1, table, rows, &rows) != BPX_OK) {
        free(table);
        cli_error(command, "out of memory");
        return CLI_EXIT_ERROR;
    }
    printf("address schedule, m = %d (%d ports), maximum address %u; '-' = read and discarded\n"
           "\n| clock |",
           m, ports, boxes - 1);
    for (int p = 0; p < ports; p++)
        printf(" %d |", p);
    printf("\n|---:|");
    for (int p = 0; p < ports; p++)
        printf("---:|");
    printf("\n");
    for (size_t r = 0; r < rows; r++) {
        printf("| %zu |", r + 1);
        for (int p = 0; p < ports; p++) {
            uint32_t a = table[r * (size_t)ports + (size_t)p];
            if (a == BPX_MODEL_DISCARDED)
                printf(" - |");
            else
                printf(" %u |", a);
        }
        printf("\n");
    }
    printf("\n%zu clocks (first address i takes ceil((%u - i) / %d))\n", rows, boxes - 1,
           2 * m - 1);
    free(table);
    return CLI_EXIT_OK;
}

// Runs the scene: warm-up cycles on the simulation alone, then measured cycles through the
// model(s). models[k] gets configs[k]; sums[k] its reports. *mismatches counts cycles where a
// model's pairs differed from the simulation's broad phase (the brute backend).
static int run_spheres(const model_options *o, uint32_t n, const bpx_model_config *configs,
                       int model_count, report_sum *sums, int *mismatches, bool print_clocks)
{
    spheres s;
    if (spheres_init(&s, n, o->seed) != 0) {
        cli_error(command, "cannot set up %u spheres", n);
        return CLI_EXIT_ERROR;
    }
    int code = CLI_EXIT_OK;
    const bpx_pair *pairs = NULL;
    size_t count = 0;
    for (int c = 0; c < o->warmup && code == CLI_EXIT_OK; c++)
        if (spheres_advance(&s, &pairs, &count) != 0)
            code = CLI_EXIT_ERROR;
    bpx_model *models[2] = {0};
    clock_printer printer = {0};
    for (int k = 0; k < model_count && code == CLI_EXIT_OK; k++) {
        bpx_model_config config = configs[k];
        if (print_clocks && k == 0) {
            config.trace = print_clock;
            config.trace_user = &printer;
        }
        bpx_status st = bpx_model_create(&config, &models[k]);
        if (st == BPX_OK)
            st = bpx_model_load_extents(models[k], s.minima, n, NULL);
        if (st != BPX_OK) {
            cli_error(command, "%s",
                      models[k] ? bpx_model_error(models[k])->message : bpx_status_string(st));
            code = CLI_EXIT_ERROR;
        }
    }
    for (int c = 0; c < o->cycles && code == CLI_EXIT_OK; c++) {
        // The board gets this cycle's centres; the demo's broad phase then sees the same ones.
        printer.left = c == 0 ? o->clocks : 0;
        bpx_model_report reports[2];
        for (int k = 0; k < model_count && code == CLI_EXIT_OK; k++) {
            if (bpx_model_run_centres(models[k], s.centres, &reports[k]) != BPX_OK) {
                cli_error(command, "%s", bpx_model_error(models[k])->message);
                code = CLI_EXIT_ERROR;
            }
            if (print_clocks && k == 0 && c == 0 && o->clocks > 0)
                printf("\n");
        }
        if (code != CLI_EXIT_OK || spheres_advance(&s, &pairs, &count) != 0) {
            code = CLI_EXIT_ERROR;
            break;
        }
        for (int k = 0; k < model_count; k++) {
            report_add(&sums[k], &reports[k]);
            size_t got = 0;
            const bpx_pair *model_pairs = bpx_model_pairs(models[k], &got);
            *mismatches +=
                got != count || (count && memcmp(model_pairs, pairs, count * sizeof *pairs) != 0);
        }
    }
    for (int k = 0; k < model_count; k++)
        bpx_model_destroy(models[k]);
    spheres_free(&s);
    return code;
}

static int run_scene(const model_options *o)
{
    uint32_t n = o->boxes ? o->boxes : DEFAULT_BOXES;
    print_config(&o->config);
    printf("scene: the paper's spheres, n = %u, %d measured cycles after %d warm-up cycles, "
           "seed %llu\n",
           n, o->cycles, o->warmup, (unsigned long long)o->seed);
    if (o->clocks > 0)
        printf("\nfirst %d clocks of the first measured cycle:\n", o->clocks);
    fflush(stdout);
    report_sum sum = {0};
    int mismatches = 0;
    int code = run_spheres(o, n, &o->config, 1, &sum, &mismatches, o->clocks > 0);
    if (code != CLI_EXIT_OK)
        return code;
    printf("\n");
    print_report(&sum, &o->config);
    printf("pairs: %s the brute backend's on every measured cycle\n",
           mismatches ? "DIFFERENT FROM" : "identical to");
    return mismatches ? CLI_EXIT_ERROR : CLI_EXIT_OK;
}

static int run_trace(const model_options *o)
{
    trace_file t;
    char message[256];
    if (trace_open(&t, o->trace_path, message, sizeof message) != 0) {
        cli_error(command, "%s", message);
        trace_close(&t);
        return CLI_EXIT_ERROR;
    }
    print_config(&o->config);
    uint64_t cycles = t.cycles < (uint64_t)o->cycles ? t.cycles : (uint64_t)o->cycles;
    printf("trace: %s, n = %u, %llu of %llu cycles (general boxes: 24 bytes per box sent)\n",
           o->trace_path, t.n, (unsigned long long)cycles, (unsigned long long)t.cycles);
    bpx_box *boxes = malloc(sizeof(bpx_box) * t.n);
    bpx_model_config config = o->config;
    clock_printer printer = {o->clocks};
    if (o->clocks > 0) {
        config.trace = print_clock;
        config.trace_user = &printer;
        printf("\nfirst %d clocks of the first cycle:\n", o->clocks);
    }
    bpx_model *model = NULL;
    int code = boxes && bpx_model_create(&config, &model) == BPX_OK ? CLI_EXIT_OK : CLI_EXIT_ERROR;
    if (code != CLI_EXIT_OK)
        cli_error(command, "out of memory");
    report_sum sum = {0};
    for (uint64_t c = 0; c < cycles && code == CLI_EXIT_OK; c++) {
        bpx_model_report r;
        if (trace_read(&t, boxes, message, sizeof message) != 0) {
            cli_error(command, "%s: cycle %llu: %s", o->trace_path, (unsigned long long)c, message);
            code = CLI_EXIT_ERROR;
        } else if (bpx_model_run_boxes(model, boxes, t.n, &r) != BPX_OK) {
            cli_error(command, "%s: cycle %llu: %s", o->trace_path, (unsigned long long)c,
                      bpx_model_error(model)->message);
            code = CLI_EXIT_ERROR;
        } else {
            report_add(&sum, &r);
        }
        printer.left = 0;
    }
    if (code == CLI_EXIT_OK) {
        printf("\n");
        print_report(&sum, &o->config);
    }
    bpx_model_destroy(model);
    free(boxes);
    trace_close(&t);
    return code;
}

// ---------------------------------------------------------------------------------------------
// --paper

typedef struct paper_result {
    double collisions;
    double chip_ns[2];
    double chip_clocks[2];
    double fixed_ns;  // link time without the DMA setup cost
    double transfers; // DMA transfers per cycle
    double bytes;     // bytes over the link per cycle
    double registers_ns;
} paper_result;

// Least squares fit of y = a + b x.
static void fit_line(const double *x, const double *y, int count, double *a, double *b)
{
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (int k = 0; k < count; k++) {
        sx += x[k];
        sy += y[k];
        sxx += x[k] * x[k];
        sxy += x[k] * y[k];
    }
    double det = count * sxx - sx * sx;
    *b = det != 0 ? (count * sxy - sx * sy) / det : 0;
    *a = (sy - *b * sx) / count;
}

static int run_paper(const model_options *o)
{
    paper_result res[PAPER_ROWS];
    bpx_model_config configs[2] = {o->config, o->config};
    for (int k = 0; k < 2; k++)
        configs[k].m = paper_m[k];
    const double setup = o->config.link.setup_ns;
    printf("bpx model --paper: the paper's scene for n = 50..500, m = 4 and m = 8, %d measured "
           "cycles after %d warm-up cycles each, seed %llu\n",
           o->cycles, o->warmup, (unsigned long long)o->seed);
    print_config(&configs[0]);
    fflush(stdout);
    int mismatches = 0;
    for (int row = 0; row < PAPER_ROWS; row++) {
        report_sum sums[2] = {{0}};
        int code = run_spheres(o, table2[row].n, configs, 2, sums, &mismatches, false);
        if (code != CLI_EXIT_OK)
            return code;
        paper_result *p = &res[row];
        p->collisions = mean(&sums[0], sums[0].collisions);
        for (int k = 0; k < 2; k++) {
            p->chip_ns[k] = mean(&sums[k], sums[k].chip_ns);
            p->chip_clocks[k] = mean(&sums[k], sums[k].chip);
        }
        // The link's cost does not depend on m: the same data cross it.
        p->transfers = mean(&sums[0], sums[0].dma);
        p->fixed_ns = mean(&sums[0], sums[0].transfer_ns) - setup * p->transfers;
        p->bytes = mean(&sums[0], sums[0].bytes_down + sums[0].bytes_up);
        p->registers_ns = mean(&sums[0], sums[0].registers) * o->config.link.register_ns;
    }

    // The setup cost per DMA transfer that best fits Table 2's communication column (least
    // squares), with the bandwidth and register cost as configured.
    double num = 0, den = 0;
    for (int row = 0; row < PAPER_ROWS; row++) {
        num += res[row].transfers * (table2[row].comm_ms * 1e6 - res[row].fixed_ns);
        den += res[row].transfers * res[row].transfers;
    }
    double fitted = den > 0 ? num / den : 0;
    if (fitted < 0)
        fitted = 0;

    printf("\nlink setup cost fitted to Table 2's communication column: %.1f us per DMA "
           "transfer (configured: %.1f us)\n\n",
           fitted * 1e-3, setup * 1e-3);
    printf("| n | collisions/cycle model / paper | communication ms model / paper "
           "| m = 4 ms model / paper | m = 8 ms model / paper "
           "| comm. share m = 4 %% model / paper | comm. share m = 8 %% model / paper |\n"
           "|---:|---:|---:|---:|---:|---:|---:|\n");
    double comm[PAPER_ROWS], total[PAPER_ROWS][2];
    for (int row = 0; row < PAPER_ROWS; row++) {
        const paper_result *p = &res[row];
        const paper_row *t = &table2[row];
        comm[row] = p->fixed_ns + p->transfers * fitted;
        for (int k = 0; k < 2; k++)
            total[row][k] = p->chip_ns[k] + comm[row];
        printf("| %u | %.2f / %.2f | %.3f / %.3f | %.3f / %.3f | %.3f / %.3f | %.1f / %.1f "
               "| %.1f / %.1f |\n",
               t->n, p->collisions, t->collisions, comm[row] * 1e-6, t->comm_ms,
               total[row][0] * 1e-6, t->fpga_ms[0], total[row][1] * 1e-6, t->fpga_ms[1],
               100 * comm[row] / total[row][0], t->share[0], 100 * comm[row] / total[row][1],
               t->share[1]);
    }

    printf("\nThe chip's part: the model's clocks per cycle (update + compare + emit) at %.1f "
           "MHz, next to the paper's FPGA time less its communication time.\n\n",
           o->config.clock_hz * 1e-6);
    printf("| n | m = 4 clocks | m = 4 chip ms model / paper | paper / model "
           "| m = 8 clocks | m = 8 chip ms model / paper | paper / model |\n"
           "|---:|---:|---:|---:|---:|---:|---:|\n");
    double x[2][PAPER_ROWS], y[2][PAPER_ROWS];
    for (int row = 0; row < PAPER_ROWS; row++) {
        printf("| %u |", table2[row].n);
        for (int k = 0; k < 2; k++) {
            double paper_chip = (table2[row].fpga_ms[k] - table2[row].comm_ms) * 1e6;
            x[k][row] = res[row].chip_clocks[k];
            y[k][row] = paper_chip;
            printf(" %.0f | %.4f / %.4f | %.2f |", res[row].chip_clocks[k],
                   res[row].chip_ns[k] * 1e-6, paper_chip * 1e-6, paper_chip / res[row].chip_ns[k]);
        }
        printf("\n");
    }

    // What else would have to differ: the link's bandwidth (a two-parameter fit of the
    // communication column), and the chip's time per clock (a line through the chip column).
    double s11 = 0, s12 = 0, s22 = 0, t1 = 0, t2 = 0;
    for (int row = 0; row < PAPER_ROWS; row++) {
        double k = res[row].transfers, bytes = res[row].bytes;
        double target = table2[row].comm_ms * 1e6 - res[row].registers_ns;
        s11 += k * k;
        s12 += k * bytes;
        s22 += bytes * bytes;
        t1 += k * target;
        t2 += bytes * target;
    }
    double det = s11 * s22 - s12 * s12;
    double setup2 = det != 0 ? (t1 * s22 - t2 * s12) / det : 0;
    double per_byte = det != 0 ? (s11 * t2 - s12 * t1) / det : 0;
    printf("\nWith the bandwidth free too, the communication column fits %.1f us per transfer "
           "and %.1f MB/s (configured %.1f MB/s).\n",
           setup2 * 1e-3, per_byte > 0 ? 1e3 / per_byte : 0, o->config.link.bytes_per_s * 1e-6);
    for (int k = 0; k < 2; k++) {
        double a, b;
        fit_line(x[k], y[k], PAPER_ROWS, &a, &b);
        printf("m = %d: the paper's chip time fits %.1f us + %.2f ns x model clocks (%.1f MHz "
               "effective; the model: %.2f ns per clock at %.1f MHz).\n",
               paper_m[k], a * 1e-3, b, b > 0 ? 1e3 / b : 0, 1e9 / o->config.clock_hz,
               o->config.clock_hz * 1e-6);
    }
    printf("pairs: %s the brute backend's on every measured cycle\n",
           mismatches ? "DIFFERENT FROM" : "identical to");
    return mismatches ? CLI_EXIT_ERROR : CLI_EXIT_OK;
}

int cmd_model(int argc, char **argv)
{
    for (int k = 1; k < argc; k++)
        if (cli_is_help(argv[k])) {
            print_help();
            return CLI_EXIT_OK;
        }
    model_options o = {
        .config = bpx_model_default_config(),
        .cycles = DEFAULT_CYCLES,
        .warmup = DEFAULT_WARMUP,
        .seed = 1,
    };
    int code = parse_args(argc, argv, &o);
    if (code != CLI_EXIT_OK)
        return code;
    if (o.schedule)
        return run_schedule(&o);
    if (o.paper) {
        if (!o.cycles_given)
            o.cycles = DEFAULT_PAPER_CYCLES;
        return run_paper(&o);
    }
    if (o.trace_path)
        return run_trace(&o);
    return run_scene(&o);
}
