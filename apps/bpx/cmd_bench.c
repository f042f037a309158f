// bpx bench: every backend and every peer library timed side by side on the same boxes, in one
// run: the paper's Table 2 on its own scenario (bench_table2.c), then random scenes at scale.
// SPDX-License-Identifier: MIT
//
// Scale scenes: per size, a random scene at constant density (uniform sizes, a heavy-tailed mix,
// or uniform boxes nearly at rest) moved coherently into a few frames that every variant replays
// in the same ping-pong order (bench_run.c). Speed claims are ratios of means (as the paper's)
// measured in this same run. Every cycle's pair count is checked against the frame's exact
// count; a mismatch makes the run fail.
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "bench.h"
#include "peers.h"
#include "scenes.h"

enum { MAX_NAMES = 32, SCENES = 3 };

// uniform: sizes 0.5..1.5, moved up to 0.05 per axis and frame; heavy: a heavy tail of sizes,
// the same motion; resting: uniform sizes moved 50 times less (a scene mostly at rest).
static const char *const scene_names[SCENES] = {"uniform", "heavy", "resting"};
static const float scene_steps[SCENES] = {0.05f, 0.05f, 0.001f};

typedef struct bench_options {
    uint32_t sizes[BENCH_MAX_SIZES];
    int size_count;
    bool sizes_given, table2, quick, all_simd;
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

static void print_help(void)
{
    printf("usage: bpx bench [--quick] [--out DIR] [--backend NAME,...] [--sizes N,...]\n"
           "                 [--scene uniform,heavy,resting] [--step D] [--table2] [--threads T]\n"
           "                 [--seconds S] [--cycles C] [--all-simd] [--seed S] [--csv FILE]\n"
           "                 [--device P:D]\n"
           "\n"
           "Times every bpx backend and every peer library built in (Bullet, Box2D: see\n"
           "`bpx backends`) side by side, in two parts:\n"
           "  1. Table 2 of the paper on its own scenario (`bpx demo` recorded for n = 50..500,\n"
           "     replayed the paper's two-phase way): mean/median/p99 us per cycle, the cold\n"
           "     first cycle, pairs per cycle, speed-ups against sap and the fastest peer,\n"
           "     next to the paper's FPGA and SOLID figures;\n"
           "  2. random scenes at constant density (uniform sizes, a heavy-tailed mix, and\n"
           "     uniform boxes nearly at rest), coherent motion, n = 1k, 10k, 100k, 1M: the\n"
           "     same columns, a summary of bpx's best against the fastest peer, and a\n"
           "     log-log plot per scene (--out).\n"
           "Every cycle's pair count is checked against the exact count (peers: their pairs\n"
           "whose exact boxes overlap); any mismatch fails the run (exit 1).\n"
           "\n"
           "  --quick     both parts in under a minute (300 cycles; n = 1k, 10k, 100k;\n"
           "              peers to 10k)\n"
           "  --out DIR   write DIR/bench.md, DIR/bench.csv, DIR/table2.csv and the plots\n"
           "              DIR/scale_uniform.svg, DIR/scale_heavy.svg, DIR/scale_resting.svg\n"
           "  --backend   only these (bpx backends and peers, e.g. prune,sap,bullet-dbvt)\n"
           "  --sizes     scale part only, these box counts (default 1000,10000,100000,1000000)\n"
           "  --scene     scale scenes (default uniform,heavy,resting)\n"
           "  --step      motion per axis and frame in every scene (default 0.05; resting\n"
           "              0.001; boxes are ~1 wide)\n"
           "  --table2    Table 2 part only (with --sizes: both)\n"
           "  --threads   worker threads of the threaded rows (default: online CPUs)\n"
           "  --seconds   time budget per variant and size (default 0.5; --quick 0.1)\n"
           "  --cycles    scale: most timed cycles per variant (default 20000);\n"
           "              table 2: cycles per n (default 10000; --quick 300)\n"
           "  --all-simd  also time every narrower SIMD width this CPU has\n"
           "  --seed      scene seed (default 1)\n"
           "  --csv FILE  also write the scale rows as CSV\n"
           "  --device P:D  OpenCL platform and device of the opencl rows (as `bpx devices`)\n");
}

static int parse_list(const char *text, const char **out, int most, char *storage, size_t size)
{
    if (strlen(text) >= size)
        return -1;
    strcpy(storage, text);
    int count = 0;
    for (char *save = NULL, *tok = strtok_r(storage, ",", &save); tok;
         tok = strtok_r(NULL, ",", &save)) {
        if (count == most)
            return -1;
        out[count++] = tok;
    }
    return count;
}

static int parse_sizes(const char *text, bench_options *o)
{
    o->size_count = 0;
    const char *p = text;
    while (*p) {
        char *end;
        errno = 0;
        unsigned long n = strtoul(p, &end, 10);
        if (end == p || errno || n > BPX_MAX_BOXES || o->size_count == BENCH_MAX_SIZES)
            return -1;
        o->sizes[o->size_count++] = (uint32_t)n;
        if (*end == ',')
            end++;
        else if (*end != '\0')
            return -1;
        p = end;
    }
    return o->size_count > 0 ? 0 : -1;
}

static bool known_name(const char *name)
{
    bpx_backend b;
    return bpx_backend_from_name(name, &b) == BPX_OK || bench_peer_find(name) >= 0;
}

static int parse_args(int argc, char **argv, bench_options *o)
{
    static char name_storage[512], scene_storage[64];
    for (int k = 1; k < argc; k++) {
        const char *value = NULL;
        cli_match m;
        if (cli_is_flag(argv[k], "--all-simd")) {
            o->all_simd = true;
        } else if (cli_is_flag(argv[k], "--table2")) {
            o->table2 = true;
        } else if (cli_is_flag(argv[k], "--quick")) {
            o->quick = true;
        } else if ((m = cli_flag_value(argc, argv, &k, "--sizes", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || parse_sizes(value, o) != 0)
                return cli_usage_error("bench", "--sizes wants box counts like 500,10000");
            o->sizes_given = true;
        } else if ((m = cli_flag_value(argc, argv, &k, "--backend", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE ||
                (o->name_count = parse_list(value, o->names, MAX_NAMES, name_storage,
                                            sizeof name_storage)) <= 0)
                return cli_usage_error("bench", "--backend wants names like prune,bullet-dbvt");
            for (int n = 0; n < o->name_count; n++)
                if (!known_name(o->names[n]))
                    return cli_usage_error("bench",
                                           "unknown backend or peer \"%s\" (see bpx backends)",
                                           o->names[n]);
        } else if ((m = cli_flag_value(argc, argv, &k, "--scene", &value)) != CLI_NO_MATCH) {
            const char *list[SCENES + 1];
            int count = m == CLI_MATCH ? parse_list(value, list, SCENES + 1, scene_storage,
                                                    sizeof scene_storage)
                                       : -1;
            memset(o->scenes, 0, sizeof o->scenes);
            for (int s = 0; s < count; s++) {
                int found = -1;
                for (int t = 0; t < SCENES; t++)
                    if (strcmp(list[s], scene_names[t]) == 0)
                        found = t;
                if (found < 0)
                    count = -1;
                else
                    o->scenes[found] = true;
            }
            if (count <= 0)
                return cli_usage_error("bench", "--scene wants uniform, heavy, resting or a list");
        } else if ((m = cli_flag_value(argc, argv, &k, "--threads", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || !cli_parse_int(value, 1, 256, &o->threads))
                return cli_usage_error("bench", "--threads wants 1..256");
        } else if ((m = cli_flag_value(argc, argv, &k, "--cycles", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || !cli_parse_int(value, 1, 100000000, &o->max_cycles))
                return cli_usage_error("bench", "--cycles wants a positive count");
            o->cycles_given = true;
        } else if ((m = cli_flag_value(argc, argv, &k, "--seconds", &value)) != CLI_NO_MATCH) {
            char *end = NULL;
            o->seconds = m == CLI_MATCH ? strtod(value, &end) : 0;
            if (m == CLI_MISSING_VALUE || *end != '\0' || !(o->seconds > 0 && o->seconds < 1e4))
                return cli_usage_error("bench", "--seconds wants a positive number");
        } else if ((m = cli_flag_value(argc, argv, &k, "--step", &value)) != CLI_NO_MATCH) {
            char *end = NULL;
            o->step = m == CLI_MATCH ? strtod(value, &end) : 0;
            if (m == CLI_MISSING_VALUE || *end != '\0' || !(o->step > 0 && o->step < 1e3))
                return cli_usage_error("bench", "--step wants a positive distance");
        } else if ((m = cli_flag_value(argc, argv, &k, "--seed", &value)) != CLI_NO_MATCH) {
            char *end = NULL;
            o->seed = m == CLI_MATCH ? strtoull(value, &end, 10) : 0;
            if (m == CLI_MISSING_VALUE || *end != '\0')
                return cli_usage_error("bench", "--seed wants an unsigned integer");
        } else if ((m = cli_flag_value(argc, argv, &k, "--device", &value)) != CLI_NO_MATCH) {
            int platform = -1, device = -1, used = 0;
            if (m == CLI_MISSING_VALUE ||
                sscanf(value, "%d:%d%n", &platform, &device, &used) != 2 || value[used] != '\0' ||
                platform < 0 || device < 0)
                return cli_usage_error("bench", "--device wants PLATFORM:DEVICE like 0:0");
            o->opencl_platform = platform + 1;
            o->opencl_device = device + 1;
        } else if ((m = cli_flag_value(argc, argv, &k, "--csv", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE)
                return cli_usage_error("bench", "--csv wants a file name");
            o->csv_path = value;
        } else if ((m = cli_flag_value(argc, argv, &k, "--out", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE)
                return cli_usage_error("bench", "--out wants a directory");
            o->out_dir = value;
        } else {
            return cli_usage_error("bench", "unknown argument \"%s\"", argv[k]);
        }
    }
    return CLI_EXIT_OK;
}

static bool wanted(const bench_variant *v, const void *context)
{
    const bench_options *o = context;
    if (o->name_count == 0)
        return true;
    const char *name = v->peer >= 0 ? bench_peer_get(v->peer)->name : bpx_backend_name(v->backend);
    for (int k = 0; k < o->name_count; k++)
        if (strcmp(o->names[k], name) == 0)
            return true;
    return false;
}

// Where a variant stops: quadratic ones where one cycle would take seconds (less with --quick).
static bool fits(const bench_variant *v, uint32_t n, bool quick)
{
    if (v->peer >= 0) {
        const bench_peer_info *info = bench_peer_get(v->peer);
        // --quick: peers to 10k only, well inside their limits (creating Box2D's tree at 100k
        // takes seconds, Bullet's sweep and prune are quadratic to create).
        if (quick)
            return n <= 10000 && n <= info->max_n / 4 && n <= info->slow_n / 4;
        return n <= info->max_n && n <= info->slow_n;
    }
    uint32_t quadratic = quick ? 20000 : 200000;
    switch (v->backend) {
    case BPX_BACKEND_REFERENCE:
        return n <= (quick ? 5000u : 20000u);
    case BPX_BACKEND_BRUTE:
        return n <= quadratic;
    case BPX_BACKEND_OPENCL: // sort and sweep on the device from 4096 boxes (BPX_OPENCL_AUTO)
        return n <= (quick ? quadratic : 1000000u);
    default:
        return true;
    }
}

static int list_variants(const bench_options *o, uint32_t n, bench_variant *out)
{
    bench_variant all[BENCH_MAX_VARIANTS];
    int count = 0;
    all[count++] = (bench_variant){-1, BPX_BACKEND_REFERENCE, BPX_SIMD_AUTO, 1, false};
    bpx_simd best = bpx_simd_best();
    for (int s = BPX_SIMD_COUNT - 1; s > BPX_SIMD_AUTO; s--) {
        if (!bpx_simd_supported((bpx_simd)s) || (!o->all_simd && s != (int)best))
            continue;
        all[count++] = (bench_variant){-1, BPX_BACKEND_BRUTE, (bpx_simd)s, 1, false};
        if (o->threads > 1)
            all[count++] = (bench_variant){-1, BPX_BACKEND_BRUTE, (bpx_simd)s, o->threads, false};
    }
    static const bpx_backend scalable[] = {BPX_BACKEND_PRUNE, BPX_BACKEND_SAP, BPX_BACKEND_GRID,
                                           BPX_BACKEND_AUTO};
    for (size_t k = 0; k < sizeof scalable / sizeof scalable[0]; k++) {
        all[count++] = (bench_variant){-1, scalable[k], BPX_SIMD_AUTO, 1, false};
        if (o->threads > 1)
            all[count++] = (bench_variant){-1, scalable[k], BPX_SIMD_AUTO, o->threads, false};
    }
    // The coprocessor: boxes over the link, then only centres (the paper's updater).
    if (bpx_backend_query(BPX_BACKEND_OPENCL).available) {
        all[count++] = (bench_variant){-1, BPX_BACKEND_OPENCL, BPX_SIMD_AUTO, 1, false};
        all[count++] = (bench_variant){-1, BPX_BACKEND_OPENCL, BPX_SIMD_AUTO, 1, true};
    }
    if (bpx_backend_query(BPX_BACKEND_CUDA).available)
        all[count++] = (bench_variant){-1, BPX_BACKEND_CUDA, BPX_SIMD_AUTO, 1, false};
    for (int p = 0; p < bench_peer_count() && count < BENCH_MAX_VARIANTS; p++)
        all[count++] = (bench_variant){p, BPX_BACKEND_AUTO, BPX_SIMD_AUTO, 1, false};
    int kept = 0;
    for (int k = 0; k < count; k++)
        if (wanted(&all[k], o) && fits(&all[k], n, o->quick))
            out[kept++] = all[k];
    return kept;
}

// One scale scene: its boxes at cycle 0, each with its own constant velocity (up to `step` per
// axis and cycle), bouncing off the walls of the scene's bounding box; and the exact pair count
// of every cycle, computed as the variants get there (bench_truth).
typedef struct scale_scene {
    float *minima, *centres, *velocity;
    bench_motion motion;
    bench_truth truth;
    bench_frames frames;
} scale_scene;

static int make_scene(int scene, uint32_t n, uint64_t seed, double step, int cycles,
                      scale_scene *s)
{
    *s = (scale_scene){0};
    size_t count = n ? n : 1;
    bpx_box *boxes = malloc(sizeof(bpx_box) * count);
    s->minima = malloc(sizeof(float) * 3 * count);
    s->centres = malloc(sizeof(float) * 3 * count);
    s->velocity = malloc(sizeof(float) * 3 * count);
    if (!boxes || !s->minima || !s->centres || !s->velocity) {
        free(boxes);
        return -1;
    }
    if (scene == 1)
        scene_heavy_tailed_density(n, seed, boxes);
    else
        scene_uniform_density(n, 1.0f, seed, boxes);
    float v = step > 0 ? (float)step : scene_steps[scene];
    scene_rng rng;
    scene_rng_seed(&rng, seed ^ 0x9e3779b97f4a7c15ull);
    s->motion = (bench_motion){.n = n, .minima = s->minima, .centres = s->centres,
                               .velocity = s->velocity};
    for (int a = 0; a < 3; a++) {
        s->motion.lo[a] = n ? INFINITY : 0.0f;
        s->motion.hi[a] = n ? -INFINITY : 1.0f;
    }
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            size_t k = 3 * (size_t)i + a;
            float half = (boxes[i].max[a] - boxes[i].min[a]) * 0.5f;
            s->minima[k] = -half;
            s->centres[k] = boxes[i].min[a] + half;
            s->velocity[k] = scene_rng_range(&rng, -v, v);
            s->motion.lo[a] = fminf(s->motion.lo[a], boxes[i].min[a]);
            s->motion.hi[a] = fmaxf(s->motion.hi[a], boxes[i].max[a]);
        }
    free(boxes);
    s->frames = (bench_frames){.n = n, .motion = &s->motion, .truth = &s->truth};
    for (int a = 0; a < 3; a++) {
        // Boxes are centre -+ half extent, which can round an ulp past a wall.
        float pad = (s->motion.hi[a] - s->motion.lo[a]) * 1e-6f + 1e-6f;
        s->frames.bounds_min[a] = s->motion.lo[a] - pad;
        s->frames.bounds_max[a] = s->motion.hi[a] + pad;
    }
    return bench_truth_init(&s->truth, &s->motion, cycles);
}

static void free_scene(scale_scene *s)
{
    bench_truth_free(&s->truth);
    free(s->minima);
    free(s->centres);
    free(s->velocity);
}

// The opencl rows again, as Table 2 of the paper: where a cycle's device time goes.
enum { MAX_LINK_ROWS = 2 * BENCH_MAX_SIZES * SCENES };
typedef struct link_row {
    const char *scene;
    uint32_t n;
    bool centres;
    bench_result r;
} link_row;

static void print_link_table(const link_row *rows, int count)
{
    bpx_backend_info info = bpx_backend_query(BPX_BACKEND_OPENCL);
    bench_printf("\nopencl on %s; device-clock means per cycle (transfers as the device's events "
                 "see them):\n\n"
                 "| scene | n | link | bytes in | bytes out | in us | out us | kernels us | "
                 "communication share | cycle median us |\n"
                 "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|\n",
                 info.detail);
    for (int k = 0; k < count; k++) {
        const bench_result *r = &rows[k].r;
        double link = r->in_us + r->out_us, total = link + r->device_us;
        bench_printf("| %s | %u | %s | %.0f | %.0f | %.2f | %.2f | %.2f | %.1f %% | %.2f |\n",
                     rows[k].scene, rows[k].n, rows[k].centres ? "centres" : "boxes", r->bytes_in, r->bytes_out,
                     r->in_us, r->out_us, r->device_us,
                     total > 0 ? 100.0 * link / total : 0.0, r->median_us);
    }
}

// Speed-up of b over a (a / b), or NAN where either is missing.
static double ratio(double a, double b)
{
    return a > 0 && b > 0 ? a / b : NAN;
}

static void print_ratio(double r)
{
    if (isnan(r))
        bench_printf(" - |");
    else
        bench_printf(" %.1fx |", r);
}

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

static bench_series *series_for(scale_state *st, int scene, const bench_variant *v)
{
    char name[BENCH_NAME_SIZE];
    bench_variant_name(v, name, sizeof name);
    for (int k = 0; k < st->series_count[scene]; k++)
        if (strcmp(st->series[scene][k].name, name) == 0)
            return &st->series[scene][k];
    if (st->series_count[scene] == BENCH_MAX_VARIANTS)
        return NULL;
    bench_series *s = &st->series[scene][st->series_count[scene]++];
    snprintf(s->name, sizeof s->name, "%s", name);
    s->peer = v->peer >= 0;
    for (int k = 0; k < BENCH_MAX_SIZES; k++)
        s->us[k] = NAN;
    return s;
}

// Warm-up: long enough for fat boxes (bpx sap's margin is 1/16 of the box size, Bullet's and
// Box2D's 0.05 and 0.1) to turn over at the scene's speed, so the timed cycles show the steady
// state and not the first cycles after the fat boxes were made, where a box at rest costs
// nothing (at 0.001 per cycle: 150 cycles; sap at 1M averaged 38 ms over 13 cycles after
// creation, 41 ms over 360; bullet-dbvt 68 ms, then 250 ms). Slow variants stop warming up
// after 20 times the timed budget (10 with --quick).
static bench_budget warmup_budget(const bench_options *o, int scene)
{
    double step = o->step > 0 ? o->step : scene_steps[scene];
    double turnover = ceil(0.15 / step);
    int warmup = turnover < 5 ? 5 : turnover > 1000 ? 1000 : (int)turnover;
    return (bench_budget){o->seconds, o->max_cycles, warmup, (o->quick ? 10 : 20) * o->seconds};
}

static int run_size(scale_state *st, int scene, int size_index)
{
    const bench_options *o = st->o;
    uint32_t n = o->sizes[size_index];
    scale_scene sc;
    bench_progress("bpx bench: %s n = %u: exact pairs", scene_names[scene], n);
    bench_budget budget = warmup_budget(o, scene);
    if (make_scene(scene, n, o->seed, o->step, 1 + budget.warmup + budget.max_cycles, &sc) != 0) {
        free_scene(&sc);
        cli_error("bench", "cannot make the %s scene of %u boxes", scene_names[scene], n);
        return -1;
    }
    bench_variant variants[BENCH_MAX_VARIANTS];
    bench_result results[BENCH_MAX_VARIANTS];
    int count = list_variants(o, n, variants);
    int code = 0;
    // Every variant's cold cycle and warm-up, then the timed cycles in BENCH_ROUNDS turns, each
    // round starting one variant later: noise that drifts over seconds (a shared VM) falls on
    // every variant of the row alike, and so stays out of their ratios.
    bench_session *sessions[BENCH_MAX_VARIANTS] = {0};
    for (int v = 0; v < count && code == 0; v++) {
        char name[BENCH_NAME_SIZE];
        bench_variant_name(&variants[v], name, sizeof name);
        bench_progress("bpx bench: %s n = %u: %s (%d/%d)", scene_names[scene], n, name, v + 1,
                       count);
        code = bench_open(&variants[v], &sc.frames, &budget, &sessions[v]);
    }
    for (int round = 0; round < BENCH_ROUNDS && code == 0; round++) {
        bench_progress("bpx bench: %s n = %u: timed round %d/%d", scene_names[scene], n,
                       round + 1, BENCH_ROUNDS);
        for (int k = 0; k < count && code == 0; k++)
            code = bench_step(sessions[(k + round) % count], budget.seconds / BENCH_ROUNDS,
                              INT_MAX);
    }
    for (int v = 0; v < count; v++) {
        if (code == 0)
            bench_close(sessions[v], &results[v]);
        else
            bench_abandon(sessions[v]);
    }
    bench_progress(NULL);
    free_scene(&sc);
    if (code != 0)
        return -1;

    double sap_us = NAN, peer_us = NAN, best_us = INFINITY;
    for (int v = 0; v < count; v++) {
        char name[BENCH_NAME_SIZE];
        bench_variant_name(&variants[v], name, sizeof name);
        double m = results[v].mean_us;
        if (variants[v].peer >= 0 && !(m >= peer_us)) { // the first peer, or a faster one
            peer_us = m;
            snprintf(st->summary[scene][size_index].peer, BENCH_NAME_SIZE, "%s", name);
        }
        if (variants[v].peer < 0 && variants[v].backend != BPX_BACKEND_REFERENCE && m < best_us) {
            best_us = m;
            snprintf(st->summary[scene][size_index].best, BENCH_NAME_SIZE, "%s", name);
        }
        if (variants[v].peer < 0 && variants[v].backend == BPX_BACKEND_SAP &&
            variants[v].threads == 1)
            sap_us = m; // "vs sap": against the one-thread row, as the paper's SOLID
    }
    st->summary[scene][size_index].best_us = best_us;
    st->summary[scene][size_index].peer_us = peer_us;
    for (int v = 0; v < count; v++) {
        const bench_variant *var = &variants[v];
        const bench_result *r = &results[v];
        char name[BENCH_NAME_SIZE], check[64];
        bench_variant_name(var, name, sizeof name);
        if (r->mismatches)
            snprintf(check, sizeof check, "**%d cycles wrong**", r->mismatches);
        else if (var->peer < 0 && var->backend == BPX_BACKEND_SAP)
            snprintf(check, sizeof check, "ok; %d of %d rebuilt", r->rebuilt, r->cycles);
        else if (var->peer < 0 && var->backend == BPX_BACKEND_AUTO) {
            int used = snprintf(check, sizeof check, "ok; ran");
            for (int b = 0; b < BPX_BACKEND_COUNT; b++)
                if (r->ran & (1u << b) && used < (int)sizeof check)
                    used += snprintf(check + used, sizeof check - (size_t)used, " %s",
                                     bpx_backend_name((bpx_backend)b));
        } else if (var->peer >= 0 && r->exact_pairs > 0)
            snprintf(check, sizeof check, "ok (reports %.2fx)", r->pairs / r->exact_pairs);
        else
            snprintf(check, sizeof check, "ok");
        st->mismatches += r->mismatches;
        bench_printf("| %s | %u | %s | %.1f | %.1f | %.2f | %.2f | %.2f |", scene_names[scene], n,
                     name, r->exact_pairs, r->cold_us, r->mean_us, r->median_us, r->p99_us);
        print_ratio(ratio(sap_us, r->mean_us));
        print_ratio(ratio(peer_us, r->mean_us));
        bench_printf(" %s |\n", check);
        bench_series *s = series_for(st, scene, var);
        if (s && var->backend != BPX_BACKEND_REFERENCE)
            s->us[size_index] = r->mean_us;
        if (var->peer < 0 && var->backend == BPX_BACKEND_OPENCL && st->link_count < MAX_LINK_ROWS)
            st->links[st->link_count++] = (link_row){scene_names[scene], n, var->centres, *r};
        if (st->csv)
            fprintf(st->csv, "%s,%u,%s,%s,%d,%d,%.2f,%.2f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%d\n",
                    scene_names[scene], n, name,
                    var->peer >= 0 ? "peer" : bpx_simd_name(var->simd == BPX_SIMD_AUTO
                                                                ? bpx_simd_best()
                                                                : var->simd),
                    var->threads, r->cycles, r->pairs, r->exact_pairs, r->cold_us, r->mean_us,
                    r->median_us, r->p99_us, r->min_us, ratio(sap_us, r->mean_us),
                    ratio(peer_us, r->mean_us), r->mismatches);
    }
    fflush(stdout);
    return 0;
}

static int run_scale(scale_state *st)
{
    const bench_options *o = st->o;
    bench_printf("Random scenes at constant density (about one overlap per box; \"heavy\": 1%%\n"
                 "of boxes 4..8 and 0.01%% 16..32 times the others' size), every box moving at\n"
                 "its own constant velocity (up to %s per axis and cycle, boxes ~1 wide;\n"
                 "\"resting\": %s) and bouncing off the scene's walls. Per variant: cold = first\n"
                 "cycle of a fresh world (peers: their creation with the first cycle's boxes),\n"
                 "then warm-up (0.15 / step cycles, at least 5: fat boxes turn over), then\n"
                 "timed cycles for %.2f s (at least one), in %d turns taken by the row's\n"
                 "variants in rotation (slow drift of a shared machine falls on all alike);\n"
                 "us per cycle (bpx:\n"
                 "set_boxes + collide; peers: move every proxy + their pair update). vs sap / vs\n"
                 "fastest peer: their mean over this row's (means, as the paper's; sap's cycles\n"
                 "are cheap or dear). check: every cycle's pairs against the exact count (peers\n"
                 "report more: fat or quantised boxes).\n\n",
                 o->step > 0 ? "--step" : "0.05", o->step > 0 ? "--step" : "0.001", o->seconds,
                 BENCH_ROUNDS);
    bench_printf("| scene | n | variant | pairs/cycle | cold us | mean us | median us | p99 us | "
                 "vs sap | vs fastest peer | check |\n"
                 "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|\n");
    for (int scene = 0; scene < SCENES; scene++)
        for (int k = 0; o->scenes[scene] && k < o->size_count; k++)
            if (run_size(st, scene, k) != 0)
                return -1;

    bench_printf("\nbpx's best against the fastest peer (means, us per cycle):\n\n"
                 "| scene | n | best bpx | us | fastest peer | us | bpx speed-up |\n"
                 "|---|---:|---|---:|---|---:|---:|\n");
    for (int scene = 0; scene < SCENES; scene++)
        for (int k = 0; o->scenes[scene] && k < o->size_count; k++) {
            const scale_summary *s = &st->summary[scene][k];
            bench_printf("| %s | %u | %s | %.2f | %s |", scene_names[scene], o->sizes[k], s->best,
                         s->best_us, isfinite(s->peer_us) ? s->peer : "-");
            if (isfinite(s->peer_us))
                bench_printf(" %.2f |", s->peer_us);
            else
                bench_printf(" - |");
            print_ratio(ratio(s->peer_us, s->best_us));
            bench_printf("\n");
        }
    if (st->link_count > 0)
        print_link_table(st->links, st->link_count);
    return 0;
}

static int write_plots(const scale_state *st)
{
    const bench_options *o = st->o;
    for (int scene = 0; scene < SCENES; scene++) {
        if (!o->scenes[scene] || o->size_count == 0)
            continue;
        char path[4096], title[160];
        snprintf(path, sizeof path, "%s/scale_%s.svg", o->out_dir, scene_names[scene]);
        snprintf(title, sizeof title,
                 "bpx bench: %s scene, mean time per cycle (dashed: peer libraries)",
                 scene_names[scene]);
        if (bench_plot_svg(path, title, o->sizes, o->size_count, st->series[scene],
                           st->series_count[scene]) != 0) {
            cli_error("bench", "cannot write %s", path);
            return -1;
        }
        fprintf(stderr, "bpx bench: wrote %s\n", path);
    }
    return 0;
}

// mkdir -p: 0, or -1 with errno set.
static int make_dirs(const char *path)
{
    char buffer[4096];
    if (snprintf(buffer, sizeof buffer, "%s", path) >= (int)sizeof buffer) {
        errno = ENAMETOOLONG;
        return -1;
    }
    for (char *p = buffer + 1;; p++) {
        bool end = *p == '\0';
        if (*p == '/' || end) {
            *p = '\0';
            if (mkdir(buffer, 0777) != 0 && errno != EEXIST)
                return -1;
            if (end)
                return 0;
            *p = '/';
        }
    }
}

static FILE *open_out(const bench_options *o, const char *name)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", o->out_dir, name);
    FILE *f = fopen(path, "w");
    if (!f)
        cli_error("bench", "cannot write %s: %s", path, strerror(errno));
    return f;
}

int cmd_bench(int argc, char **argv)
{
    for (int k = 1; k < argc; k++)
        if (cli_is_help(argv[k])) {
            print_help();
            return CLI_EXIT_OK;
        }
    long cpus = sysconf(_SC_NPROCESSORS_ONLN);
    bench_options o = {
        .sizes = {1000, 10000, 100000, 1000000},
        .size_count = 4,
        .scenes = {true, true, true},
        .threads = cpus > 0 ? (int)(cpus < 256 ? cpus : 256) : 1,
        .seconds = 0.5,
        .max_cycles = 20000,
        .seed = 1,
    };
    int code = parse_args(argc, argv, &o);
    if (code != CLI_EXIT_OK)
        return code;
    bool run_table2 = o.table2 || !o.sizes_given, scale = o.sizes_given || !o.table2;
    if (o.quick) {
        if (!o.sizes_given)
            o.size_count = 3;
        if (o.seconds == 0.5)
            o.seconds = 0.1;
    }
    int table2_cycles = o.cycles_given ? o.max_cycles : o.quick ? 300 : 10000;
    if (o.out_dir && make_dirs(o.out_dir) != 0) {
        cli_error("bench", "cannot create %s: %s", o.out_dir, strerror(errno));
        return CLI_EXIT_ERROR;
    }

    FILE *markdown = NULL, *csv = NULL, *table2_csv = NULL;
    if (o.out_dir && !(markdown = open_out(&o, "bench.md")))
        return CLI_EXIT_ERROR;
    bench_set_markdown_copy(markdown);
    if (o.csv_path && !(csv = fopen(o.csv_path, "w")))
        cli_error("bench", "cannot write %s: %s", o.csv_path, strerror(errno));
    else if (!o.csv_path && o.out_dir && scale)
        csv = open_out(&o, "bench.csv");
    if (o.out_dir && run_table2)
        table2_csv = open_out(&o, "table2.csv");
    scale_state *st = calloc(1, sizeof *st);
    if (!st) {
        cli_error("bench", "out of memory");
        return CLI_EXIT_ERROR;
    }
    st->o = &o;
    st->csv = csv;
    if ((o.csv_path && !csv) || (o.out_dir && scale && !csv) ||
        (o.out_dir && run_table2 && !table2_csv))
        code = CLI_EXIT_ERROR;
    if (csv)
        fprintf(csv, "scene,n,variant,simd,threads,cycles,pairs_reported,pairs_exact,cold_us,"
                     "mean_us,median_us,p99_us,min_us,speedup_vs_sap,speedup_vs_fastest_peer,"
                     "wrong_cycles\n");

    if (code == CLI_EXIT_OK) {
        bench_print_machine(o.threads);
        bench_printf("peers:");
        for (int p = 0; p < bench_peer_count(); p++)
            bench_printf("%s %s (%s)", p ? ";" : "", bench_peer_get(p)->name,
                         bench_peer_get(p)->detail);
        bench_printf("%s\n\n", bench_peer_count() ? "" : " none built in (see bench/peers)");
    }
    if (code == CLI_EXIT_OK && run_table2) {
        bench_table2_options t2 = {o.threads, table2_cycles, o.seed, wanted, &o, table2_csv};
        int rc = bench_table2(&t2);
        if (rc < 0)
            code = CLI_EXIT_ERROR;
        st->mismatches += rc > 0 ? rc : 0;
    }
    if (code == CLI_EXIT_OK && scale) {
        if (run_table2)
            bench_printf("\n");
        if (run_scale(st) != 0 || (o.out_dir && write_plots(st) != 0))
            code = CLI_EXIT_ERROR;
    }
    if (code == CLI_EXIT_OK && st->mismatches > 0) {
        cli_error("bench", "%d cycles reported a pair count other than the exact one",
                  st->mismatches);
        code = CLI_EXIT_ERROR;
    }
    FILE *files[] = {markdown, csv, table2_csv};
    for (size_t k = 0; k < sizeof files / sizeof files[0]; k++)
        if (files[k] && fclose(files[k]) != 0) {
            cli_error("bench", "cannot finish writing the output files");
            code = CLI_EXIT_ERROR;
        }
    bench_set_markdown_copy(NULL);
    free(st);
    return code;
}
