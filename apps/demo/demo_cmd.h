// bpx demo's options and run totals, shared by its files: demo_options.c (flags),
// demo_report.c (totals, tables, JSON) and cmd_demo.c (the loop).
// SPDX-License-Identifier: MIT

#pragma once

#include <stdio.h>

#include "cli.h"
#include "demo_sim.h"

static const char *const command = "demo";

enum {
    THREADS_MAX = 256,
    DEFAULT_CYCLES = 600,  // 10 s of simulated time at the default 1/60 s step
    DEFAULT_EVERY = 60,    // one picture per simulated second: 10 pictures by default
    TABLE2_CYCLES = 10000, // the paper averaged 10,000 cycles
    PARSE_CONTINUE = -1,
};

#define DEFAULT_OUT "bpx-demo"

typedef struct demo_options {
    demo_params params;
    bpx_backend backend;
    int threads;
    long cycles;
    bool cycles_set;
    const char *out_dir;
    bool out_set;
    int every;
    bool every_set;
    bool window;
    const char *screenshot;
    bool pace;
    const char *record;
    bool json;
    bool table2;
    int width, height;
} demo_options;

// Sums over the cycles of a run, and what the run was.
typedef struct demo_totals {
    uint64_t cycles;
    double broad_ns, narrow_ns, response_ns, physics_ns, display_ns;
    double bpx_update_ns, bpx_compare_ns, bpx_emit_ns;
    double pairs, contacts, impulses, wall_hits;
    double energy_start, energy_end;
    double momentum_start[3], momentum_end[3], wall_impulse[3], momentum_scale;
    double within_15; // fraction of velocity components in [-15, 15] m/s at the end
    double max_penetration, max_speed;
    double wall_s;
    int pictures;
    int width, height;
    double box[3];
} demo_totals;

static inline double per_cycle(double sum, const demo_totals *t)
{
    return t->cycles ? sum / (double)t->cycles : 0.0;
}

// demo_options.c
int demo_cmd_parse_args(int argc, char **argv, demo_options *o); // PARSE_CONTINUE, or the exit code
// demo_report.c
void demo_cmd_start_totals(const demo_sim *sim, demo_totals *t);
void demo_cmd_accumulate(demo_totals *t, const demo_step *s);
void demo_cmd_finish_totals(const demo_sim *sim, demo_totals *t);
void demo_cmd_print_json(FILE *f, const demo_options *o, const demo_sim *sim, const demo_totals *t,
                         const char *picture_dir);
void demo_cmd_print_tables(const demo_options *o, const demo_sim *sim, const demo_totals *t,
                           const char *picture_dir);
