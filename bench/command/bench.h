// bpx bench: what cmd_bench.c (random scenes at scale), bench_table2.c (the paper's scenario),
// bench_run.c (timing one variant) and bench_plot.c (the SVG) share.
// SPDX-License-Identifier: MIT
#pragma once

#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#include <bpx/bpx.h>

#include "cli.h"

enum { BENCH_MAX_VARIANTS = 48, BENCH_MAX_SIZES = 16, BENCH_NAME_SIZE = 48 };

// One row of a table: a bpx backend at a SIMD width and thread count, or a peer library.
typedef struct bench_variant {
    int peer;           // index into bench/peers/peers.h, or -1 for a bpx backend
    bpx_backend backend;
    bpx_simd simd;
    int threads;
    bool centres;       // bpx: the paper's two-phase updater (extents once, centres per cycle)
    int opencl_method;  // opencl: BPX_OPENCL_AUTO, or a path forced (the crossover's rows)
} bench_variant;

// "prune 2t", "brute avx512 1t", "opencl centres", "opencl tree", "bullet-dbvt".
void bench_variant_name(const bench_variant *v, char *out, size_t size);

// Boxes that move on their own: each keeps its size and a velocity (per cycle) and bounces off
// walls; made cycle by cycle outside the timed region, so motion never repeats or jumps back.
// Boxes are centre + minimum and centre - minimum, the library's own updater, so the paper's
// two-phase interface (centres each cycle) sees exactly the same boxes as set_boxes.
typedef struct bench_motion {
    uint32_t n;
    const float *minima;   // 3n origin-centred minima (minus the half extents)
    const float *centres;  // 3n centres at cycle 0
    const float *velocity; // 3n moves per cycle at cycle 0
    float lo[3], hi[3];    // the walls: every box stays inside
} bench_motion;

// One replay of a motion.
typedef struct bench_mover {
    const bench_motion *motion;
    float *centres, *velocity;
    bpx_box *boxes;
    int cycle;
} bench_mover;
int bench_mover_init(bench_mover *m, const bench_motion *motion); // 0, or -1 out of memory
void bench_mover_step(bench_mover *m);                            // to the next cycle
void bench_mover_free(bench_mover *m);

// The exact pair count of each cycle of a motion, computed once (auto backend, untimed) as far
// as some variant has gone.
typedef struct bench_truth {
    bench_mover mover;
    bpx_world *world;
    uint64_t *counts;
    int done, capacity;
} bench_truth;
int bench_truth_init(bench_truth *t, const bench_motion *motion, int capacity);
int bench_truth_count(bench_truth *t, int cycle, uint64_t *count); // 0, or -1
void bench_truth_free(bench_truth *t);

// The cycles a variant plays: a motion (scale scenes) or recorded frames in the two-phase form
// (Table 2: minima once, centres per frame, played once).
typedef struct bench_frames {
    uint32_t n;
    const bench_motion *motion; // or NULL
    bench_truth *truth;         // exact counts of the motion's cycles
    int count;                  // recorded frames
    const float *minima;        // 3n origin-centred minima
    const float *centres;       // count * 3n centres
    const uint64_t *pairs;      // exact pair count per recorded frame
    float bounds_min[3], bounds_max[3]; // contain every box of every cycle (quantising peers)
} bench_frames;

typedef struct bench_budget {
    double seconds; // timed cycles stop after this much time (motion)
    int max_cycles;
    int warmup;     // untimed cycles after the cold one (motion)
    double warmup_seconds; // warm-up stops early past this much time (slow variants)
} bench_budget;

typedef struct bench_result {
    int cycles;                         // timed
    double cold_us;                     // the first cycle of a fresh world or peer
    double mean_us, median_us, p99_us, min_us;
    double pairs;                       // mean reported per timed cycle
    double exact_pairs;                 // peers: mean pairs whose exact boxes overlap
    int mismatches;                     // cycles whose exact pairs differ from frames->pairs
    unsigned ran;                       // bpx: 1 << the backends the timed cycles ran (auto)
    int rebuilt;                        // sap: timed cycles that rebuilt instead of mending
    double rebuilt_us, mended_us;       // sap: mean us of those, and of the mended ones
    double in_us, out_us, device_us;    // opencl: device-clock means per timed cycle
    double bytes_in, bytes_out;
} bench_result;

// Times one variant: bench_open, bench_step for budget->seconds, bench_close. Returns 0, or
// prints the error and returns -1.
int bench_run(const bench_variant *v, const bench_frames *frames, const bench_budget *budget,
              bench_result *out);

// The same in steps, so that the variants of one row can take turns, BENCH_ROUNDS of them
// (machine noise that drifts over seconds then falls on all of them alike): bench_open makes
// the world or peer and plays the cold cycle and the warm-up; each bench_step plays timed
// cycles, at most `cycles` of them, for about `seconds` (at least one in the first; none once
// the budget's seconds are spent; recorded frames: `cycles` of them, seconds aside);
// bench_close gives the result and frees the session, bench_abandon frees it. The functions
// that return int return 0, or print the error and return -1.
enum { BENCH_ROUNDS = 5 };
typedef struct bench_session bench_session;
int bench_open(const bench_variant *v, const bench_frames *frames, const bench_budget *budget,
               bench_session **out);
int bench_step(bench_session *s, double seconds, int cycles);
void bench_close(bench_session *s, bench_result *out);
void bench_abandon(bench_session *s);

// The bench's Markdown goes to stdout and, with --out, to DIR/bench.md as well.
void bench_set_markdown_copy(FILE *file);
void bench_printf(const char *fmt, ...) CLI_PRINTF(1, 2);

// A progress line on stderr when it is a terminal (erased by bench_progress(NULL)).
void bench_progress(const char *fmt, ...) CLI_PRINTF(1, 2);

// The machine line: CPU model, CPUs, widest SIMD, threads, bpx version.
void bench_print_machine(int threads);

// One series of the plot: a variant's mean us per cycle per size (NAN where it did not run).
typedef struct bench_series {
    char name[BENCH_NAME_SIZE];
    bool peer;
    double us[BENCH_MAX_SIZES];
} bench_series;

// Writes a log-log SVG of time per cycle against n. Returns 0, or -1 if the file can't be written.
int bench_plot_svg(const char *path, const char *title, const uint32_t *sizes, int size_count,
                   const bench_series *series, int series_count);

// --table2: the paper's Table 2 on the paper's scenario; CSV rows to csv if not NULL.
typedef struct bench_table2_options {
    int threads;
    int cycles;
    uint64_t seed;
    bool (*wanted)(const bench_variant *v, const void *context); // the --backend filter
    const void *wanted_context;
    FILE *csv;
} bench_table2_options;
int bench_table2(const bench_table2_options *o);
