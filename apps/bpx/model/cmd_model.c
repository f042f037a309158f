// bpx model: the clock-by-clock model of the paper's FPGA (include/bpx/model.h) on a scene or a
// trace; its address schedule (Table 1); a per-clock trace; and --paper, the model next to
// Table 2's measured FPGA times. SPDX-License-Identifier: MIT
//
// The scene is the paper's test scenario (§5) as `bpx demo` runs it (apps/demo/demo_sim.h, with
// its defaults: one layer of spheres of radius 25 m with 10 m gaps in a box 400 m high, random
// velocities in (-40, 40) m/s per axis, elastic, time step 1/60 s). Only n and the collisions
// per cycle matter to the model.

#define _POSIX_C_SOURCE 200809L
#include <stdlib.h>
#include <string.h>

#include "model_cmd.h"

// ---------------------------------------------------------------------------------------------
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
int model_run_spheres(const model_options *o, uint32_t n, const bpx_model_config *configs,
                      int model_count, report_sum *sums, int *mismatches, bool print_clocks)
{
    spheres s;
    if (model_spheres_init(&s, n, o->seed) != 0) {
        cli_error(command, "cannot set up %u spheres", n);
        return CLI_EXIT_ERROR;
    }
    int code = CLI_EXIT_OK;
    const bpx_pair *pairs = NULL;
    size_t count = 0;
    for (int c = 0; c < o->warmup && code == CLI_EXIT_OK; c++)
        if (model_spheres_advance(&s, &pairs, &count) != 0)
            code = CLI_EXIT_ERROR;
    bpx_model *models[2] = {0};
    clock_printer printer = {0};
    for (int k = 0; k < model_count && code == CLI_EXIT_OK; k++) {
        bpx_model_config config = configs[k];
        if (print_clocks && k == 0) {
            config.trace = model_print_clock;
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
        if (code != CLI_EXIT_OK || model_spheres_advance(&s, &pairs, &count) != 0) {
            code = CLI_EXIT_ERROR;
            break;
        }
        for (int k = 0; k < model_count; k++) {
            model_report_add(&sums[k], &reports[k]);
            size_t got = 0;
            const bpx_pair *model_pairs = bpx_model_pairs(models[k], &got);
            *mismatches +=
                got != count || (count && memcmp(model_pairs, pairs, count * sizeof *pairs) != 0);
        }
    }
    for (int k = 0; k < model_count; k++)
        bpx_model_destroy(models[k]);
    model_spheres_free(&s);
    return code;
}

static int run_scene(const model_options *o)
{
    uint32_t n = o->boxes ? o->boxes : DEFAULT_BOXES;
    model_print_config(&o->config);
    printf("scene: the paper's spheres, n = %u, %d measured cycles after %d warm-up cycles, "
           "seed %llu\n",
           n, o->cycles, o->warmup, (unsigned long long)o->seed);
    if (o->clocks > 0)
        printf("\nfirst %d clocks of the first measured cycle:\n", o->clocks);
    fflush(stdout);
    report_sum sum = {0};
    int mismatches = 0;
    int code = model_run_spheres(o, n, &o->config, 1, &sum, &mismatches, o->clocks > 0);
    if (code != CLI_EXIT_OK)
        return code;
    printf("\n");
    model_print_report(&sum, &o->config);
    printf("pairs: %s the brute backend's on every measured cycle\n",
           mismatches ? "DIFFERENT FROM" : "identical to");
    return mismatches ? CLI_EXIT_ERROR : CLI_EXIT_OK;
}

static int run_trace(const model_options *o)
{
    trace_file t;
    char message[256];
    if (model_trace_open(&t, o->trace_path, message, sizeof message) != 0) {
        cli_error(command, "%s", message);
        model_trace_close(&t);
        return CLI_EXIT_ERROR;
    }
    model_print_config(&o->config);
    uint64_t cycles = t.cycles < (uint64_t)o->cycles ? t.cycles : (uint64_t)o->cycles;
    printf("trace: %s, n = %u, %llu of %llu cycles (general boxes: 24 bytes per box sent)\n",
           o->trace_path, t.n, (unsigned long long)cycles, (unsigned long long)t.cycles);
    bpx_box *boxes = malloc(sizeof(bpx_box) * t.n);
    bpx_model_config config = o->config;
    clock_printer printer = {o->clocks};
    if (o->clocks > 0) {
        config.trace = model_print_clock;
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
        if (model_trace_read(&t, boxes, message, sizeof message) != 0) {
            cli_error(command, "%s: cycle %llu: %s", o->trace_path, (unsigned long long)c, message);
            code = CLI_EXIT_ERROR;
        } else if (bpx_model_run_boxes(model, boxes, t.n, &r) != BPX_OK) {
            cli_error(command, "%s: cycle %llu: %s", o->trace_path, (unsigned long long)c,
                      bpx_model_error(model)->message);
            code = CLI_EXIT_ERROR;
        } else {
            model_report_add(&sum, &r);
        }
        printer.left = 0;
    }
    if (code == CLI_EXIT_OK) {
        printf("\n");
        model_print_report(&sum, &o->config);
    }
    bpx_model_destroy(model);
    free(boxes);
    model_trace_close(&t);
    return code;
}

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
    int code = model_parse_args(argc, argv, &o);
    if (code != CLI_EXIT_OK)
        return code;
    if (o.schedule)
        return run_schedule(&o);
    if (o.paper) {
        if (!o.cycles_given)
            o.cycles = DEFAULT_PAPER_CYCLES;
        return model_run_paper(&o);
    }
    if (o.trace_path)
        return run_trace(&o);
    return run_scene(&o);
}
