// bpx bench's options and the scale part's state, shared by the command's files:
// bench_options.c (flags, which variants run), bench_scale.c (random scenes at scale) and
// cmd_bench.c (the run). SPDX-License-Identifier: MIT

#pragma once

#include "bench.h"

enum { MAX_NAMES = 32, SCENES = 3 };

// uniform: sizes 0.5..1.5, moved up to 0.05 per axis and frame; heavy: a heavy tail of sizes,
// the same motion; resting: uniform sizes moved 50 times less (a scene mostly at rest).
extern const char *const bench_scene_names[SCENES];
extern const float bench_scene_steps[SCENES];

typedef struct bench_options {
    uint32_t sizes[BENCH_MAX_SIZES];
    int size_count;
    bool sizes_given, table2, quick, all_simd, profile, scenes_given;
    bool scenes[SCENES];
    int threads;
    double seconds;     // time budget per variant and size
    double step;        // --step: motion per axis and frame for every scene (0: the scene's own)
    int max_cycles;     // timed cycles at most (scale); cycles per n (table 2)
    bool cycles_given;
    uint64_t seed;
    const char *csv_path, *out_dir;
    const char *names[MAX_NAMES]; // --backend: bpx backends and peers by name; none = all
    int name_count;
    int opencl_platform, opencl_device; // --device P:D, as bpx_world_def (from 1; 0 = best)
} bench_options;

// The opencl rows again, as Table 2 of the paper: where a cycle's device time goes.
enum { MAX_LINK_ROWS = 2 * BENCH_MAX_SIZES * SCENES };

typedef struct link_row {
    const char *scene;
    uint32_t n;
    bool centres;
    bench_result r;
} link_row;

// Per scene and size: the best bpx and the fastest peer, for the summary.
typedef struct scale_summary {
    char best[BENCH_NAME_SIZE], peer[BENCH_NAME_SIZE];
    double best_us, peer_us;
} scale_summary;

typedef struct scale_state {
    const bench_options *o;
    FILE *csv;
    bench_series series[SCENES][BENCH_MAX_VARIANTS];
    int series_count[SCENES];
    link_row links[MAX_LINK_ROWS];
    int link_count;
    int mismatches;
    scale_summary summary[SCENES][BENCH_MAX_SIZES];
} scale_state;

// One scale scene: its boxes at cycle 0, each with its own constant velocity (up to `step` per
// axis and cycle), bouncing off the walls of the scene's bounding box; and the exact pair count
// of every cycle, computed as the variants get there (bench_truth).
typedef struct scale_scene {
    float *minima, *centres, *velocity;
    bench_motion motion;
    bench_truth truth;
    bench_frames frames;
} scale_scene;

// bench_options.c
int bench_cmd_parse_args(int argc, char **argv, bench_options *o);
bool bench_cmd_wanted(const bench_variant *v, const void *context); // context: the bench_options
int bench_cmd_list_variants(const bench_options *o, uint32_t n, bench_variant *out);
// bench_scale.c
int bench_cmd_make_scene(int scene, uint32_t n, uint64_t seed, double step, int cycles,
                         scale_scene *s); // 0, or -1 out of memory
void bench_cmd_free_scene(scale_scene *s);
int bench_cmd_run_scale(scale_state *st);
// bench_profile.c: --profile
int bench_cmd_run_profile(const bench_options *o);
int bench_cmd_write_plots(const scale_state *st);
