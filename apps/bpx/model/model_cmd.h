// bpx model's options and what its files share: model_options.c (flags), model_inputs.c (the
// paper's scene and trace files), model_report.c (reports), model_paper.c (--paper) and
// cmd_model.c (the modes). SPDX-License-Identifier: MIT

#pragma once

#include <stdio.h>

#include <bpx/model.h>

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

// ---------------------------------------------------------------------------------------------
// ---------------------------------------------------------------------------------------------
// The paper's scene: spheres in a box, the demo's simulation (apps/demo/demo_sim.h), so the
// model sees exactly the cycles `bpx demo` runs.

typedef struct spheres {
    uint32_t n;
    demo_sim *sim;
    float *minima;  // 3n: the origin-centred AABB minima, -radius
    float *centres; // 3n: this cycle's centres as sent to the board
} spheres;

// ---------------------------------------------------------------------------------------------
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

// ---------------------------------------------------------------------------------------------
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

static inline double mean(const report_sum *s, double total)
{
    return s->cycles ? total / s->cycles : 0;
}

typedef struct clock_printer {
    int left;
} clock_printer;

// ---------------------------------------------------------------------------------------------
// model_options.c
int model_parse_args(int argc, char **argv, model_options *o);
// model_inputs.c
int model_spheres_init(spheres *s, uint32_t n, uint64_t seed);
int model_spheres_advance(spheres *s, const bpx_pair **pairs, size_t *count);
void model_spheres_free(spheres *s);
int model_trace_open(trace_file *t, const char *path, char *message, size_t size);
int model_trace_read(trace_file *t, bpx_box *boxes, char *message, size_t size);
void model_trace_close(trace_file *t);
// model_report.c
void model_report_add(report_sum *s, const bpx_model_report *r);
void model_print_report(const report_sum *s, const bpx_model_config *c);
void model_print_config(const bpx_model_config *c);
void model_print_clock(const bpx_model_clock *c, void *user);
// cmd_model.c
int model_run_spheres(const model_options *o, uint32_t n, const bpx_model_config *configs,
                      int model_count, report_sum *sums, int *mismatches, bool print_clocks);
// model_paper.c
int model_run_paper(const model_options *o);
