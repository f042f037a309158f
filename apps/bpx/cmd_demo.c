// bpx demo: the paper's test scenario (Woulfe et al. 2007, section 5): spheres in a box, the
// central loop broad phase -> narrow phase -> collision response -> physics -> display, timed per
// stage; pictures as PNG files and/or a live window; statistics; an AABB trace on request.
// SPDX-License-Identifier: MIT
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "bpx_trace.h"
#include "cli.h"
#include "demo_png.h"
#include "demo_render.h"
#include "demo_sim.h"
#include "demo_window.h"

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

// The paper's Table 2, "collisions" column: mean per cycle, n = 50, 100, ..., 500.
static const double paper_collisions[10] = {7.47,  12.588, 20.413, 26.703, 35.628,
                                            44.61, 51.416, 60.053, 64.427, 76.079};

static void print_help(void)
{
    printf("usage: bpx demo [--spheres N] [--cycles C] [--backend B] [--threads T]\n"
           "                [--out DIR] [--every K] [--window] [--screenshot FILE] [--no-pace]\n"
           "                [--record FILE] [--json] [--table2] [scenario options]\n"
           "\n"
           "Runs the test program of Woulfe, Dingliana & Manzke (2007), section 5: spheres of\n"
           "radius 25 m in a closed box 400 m high whose width and depth leave 10 m between the\n"
           "spheres at the start; every sphere starts with its own random velocity in\n"
           "(-40,-40,-40)..(40,40,40) m/s; spheres bounce off each other and the inner walls.\n"
           "Each cycle runs, in order and timed: 1 broad phase (bpx: extents loaded once, centres\n"
           "each cycle), 2 narrow phase (exact sphere tests of bpx's pairs), 3 collision response\n"
           "(momentum-conserving impulses, walls included), 4 physics (fixed step), 5 display.\n"
           "At the end it prints the statistics (or JSON with --json).\n"
           "\n"
           "With no options: 500 spheres, %d cycles of 1/60 s (10 s simulated), a PNG picture\n"
           "every %d cycles into ./" DEFAULT_OUT "/ with stats.json beside them.\n"
           "\n"
           "run:\n"
           "  --spheres N      spheres, 1..1000000 (default 500)\n"
           "  --cycles C       cycles to run (default %d; 0 with --window: until it is closed)\n"
           "  --backend NAME   bpx backend for the broad phase:",
           DEFAULT_CYCLES, DEFAULT_EVERY, DEFAULT_CYCLES);
    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        const char *name = bpx_backend_name((bpx_backend)b);
        printf("%s %s%s", b == 0 ? "" : ",", name ? name : "?",
               b == BPX_BACKEND_AUTO ? " (default)" : "");
    }
    printf(
        "\n"
        "  --threads T      bpx worker threads, 1..%d (default 1)\n"
        "  --record FILE    write every cycle's boxes to an AABB trace (docs/demo.md)\n"
        "  --json           print the statistics as JSON instead of tables\n"
        "  --table2         run n = 50, 100, ..., 500 headless (default %d cycles each, as the\n"
        "                   paper) and compare mean pairs per cycle with the paper's Table 2\n"
        "\n"
        "display:\n"
        "  --out DIR        directory for the pictures and stats.json (default " DEFAULT_OUT ")\n"
        "  --every K        a PNG picture every K cycles; 0: none (default %d)\n"
        "  --size WxH       picture and window size in pixels (default 640x480)\n"
        "  --window         show the simulation live in a window (SDL2); no PNG files unless\n"
        "                   --out or --every is given. Escape or Q closes it\n"
        "  --screenshot F   with --window: save the last frame as SDL drew it to PNG file F\n"
        "  --no-pace        with --window: run as fast as possible, not in real time\n"
        "\n"
        "scenario (where the paper is silent; docs/demo.md explains each default):\n"
        "  --dt S           time step in seconds, a number or a fraction like 1/60 (default 1/60)\n"
        "  --restitution E  0..1; 1 is elastic (default 1)\n"
        "  --mass M         kg per sphere (default 1, so momentum equals velocity)\n"
        "  --layers L       horizontal layers of the initial grid (default 1)\n"
        "  --gap M          gap between neighbouring spheres at the start, m (default 10)\n"
        "  --wall-gap M     gap between the outer spheres and the walls at the start (default 10)\n"
        "  --radius M       sphere radius, m (default 25)\n"
        "  --height M       inner height of the box, m (default 400)\n"
        "  --speed V        initial velocity components in [-V, V] m/s (default 40)\n"
        "  --seed S         seed of the initial velocities (default 1)\n"
        "\n"
        "Exit status: 0 success, 1 runtime error, 2 usage error.\n",
        THREADS_MAX, TABLE2_CYCLES, DEFAULT_EVERY);
}

// A finite number, or a fraction "a/b" of two finite numbers.
static bool parse_number(const char *text, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(text, &end);
    if (end == text || errno != 0)
        return false;
    if (*end == '/') {
        const char *den_text = end + 1;
        double den = strtod(den_text, &end);
        if (end == den_text || den == 0)
            return false;
        v /= den;
    }
    if (*end != '\0' || !isfinite(v))
        return false;
    *out = v;
    return true;
}

static bool parse_size(const char *text, int *w, int *h)
{
    char *end;
    long a = strtol(text, &end, 10);
    if (end == text || (*end != 'x' && *end != 'X'))
        return false;
    const char *second = end + 1;
    long b = strtol(second, &end, 10);
    if (end == second || *end != '\0' || a < 16 || b < 16 || a > 8192 || b > 8192)
        return false;
    *w = (int)a;
    *h = (int)b;
    return true;
}

// Flags that take a number: name, where it goes, and its range.
typedef struct number_flag {
    const char *flag;
    double *target;
    double min, max;
    bool min_open; // (min, max] rather than [min, max]
} number_flag;

static int parse_args(int argc, char **argv, demo_options *o)
{
    number_flag numbers[] = {
        {"--dt", &o->params.dt, 0, 10, true},
        {"--restitution", &o->params.restitution, 0, 1, false},
        {"--mass", &o->params.mass, 0, 1e12, true},
        {"--gap", &o->params.gap, 0, 1e6, false},
        {"--wall-gap", &o->params.wall_gap, 0, 1e6, false},
        {"--radius", &o->params.radius, 0, 1e6, true},
        {"--height", &o->params.height, 0, 1e7, true},
        {"--speed", &o->params.max_speed, 0, 1e5, false},
    };
    for (int k = 1; k < argc; k++) {
        const char *arg = argv[k];
        const char *value = NULL;
        cli_match m;
        if (cli_is_help(arg)) {
            print_help();
            return CLI_EXIT_OK;
        }
        if (cli_is_flag(arg, "--window")) {
            o->window = true;
            continue;
        }
        if (cli_is_flag(arg, "--json")) {
            o->json = true;
            continue;
        }
        if (cli_is_flag(arg, "--no-pace")) {
            o->pace = false;
            continue;
        }
        if (cli_is_flag(arg, "--table2")) {
            o->table2 = true;
            continue;
        }
        bool matched = false;
        for (size_t f = 0; f < sizeof numbers / sizeof numbers[0] && !matched; f++) {
            const number_flag *nf = &numbers[f];
            if ((m = cli_flag_value(argc, argv, &k, nf->flag, &value)) == CLI_NO_MATCH)
                continue;
            matched = true;
            double v = 0;
            if (m == CLI_MISSING_VALUE || !parse_number(value, &v) ||
                (nf->min_open ? !(v > nf->min) : !(v >= nf->min)) || v > nf->max)
                return cli_usage_error(command, "%s wants a number in %s%g, %g]", nf->flag,
                                       nf->min_open ? "(" : "[", nf->min, nf->max);
            *nf->target = v;
        }
        if (matched)
            continue;
        int integer = 0;
        if ((m = cli_flag_value(argc, argv, &k, "--spheres", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || !cli_parse_int(value, 1, 1000000, &integer))
                return cli_usage_error(command, "--spheres wants a count in 1..1000000");
            o->params.sphere_count = (uint32_t)integer;
        } else if ((m = cli_flag_value(argc, argv, &k, "--cycles", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || !cli_parse_int(value, 0, 1000000000, &integer))
                return cli_usage_error(command, "--cycles wants a count in 0..1000000000");
            o->cycles = integer;
            o->cycles_set = true;
        } else if ((m = cli_flag_value(argc, argv, &k, "--backend", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE)
                return cli_usage_error(command, "--backend wants a name");
            int code = cli_parse_backend(command, value, &o->backend);
            if (code != CLI_EXIT_OK)
                return code;
        } else if ((m = cli_flag_value(argc, argv, &k, "--threads", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || !cli_parse_int(value, 1, THREADS_MAX, &o->threads))
                return cli_usage_error(command, "--threads wants 1..%d", THREADS_MAX);
        } else if ((m = cli_flag_value(argc, argv, &k, "--out", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || value[0] == '\0')
                return cli_usage_error(command, "--out wants a directory");
            o->out_dir = value;
            o->out_set = true;
        } else if ((m = cli_flag_value(argc, argv, &k, "--every", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || !cli_parse_int(value, 0, 1000000000, &o->every))
                return cli_usage_error(command, "--every wants a count of cycles (0: none)");
            o->every_set = true;
        } else if ((m = cli_flag_value(argc, argv, &k, "--size", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || !parse_size(value, &o->width, &o->height))
                return cli_usage_error(command, "--size wants WxH, 16..8192 each, like 640x480");
        } else if ((m = cli_flag_value(argc, argv, &k, "--screenshot", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || value[0] == '\0')
                return cli_usage_error(command, "--screenshot wants a file name");
            o->screenshot = value;
        } else if ((m = cli_flag_value(argc, argv, &k, "--record", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || value[0] == '\0')
                return cli_usage_error(command, "--record wants a file name");
            o->record = value;
        } else if ((m = cli_flag_value(argc, argv, &k, "--layers", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || !cli_parse_int(value, 1, 100000, &integer))
                return cli_usage_error(command, "--layers wants 1..100000");
            o->params.layers = (uint32_t)integer;
        } else if ((m = cli_flag_value(argc, argv, &k, "--seed", &value)) != CLI_NO_MATCH) {
            char *end = NULL;
            errno = 0;
            o->params.seed = m == CLI_MATCH ? strtoull(value, &end, 10) : 0;
            if (m == CLI_MISSING_VALUE || end == value || *end != '\0' || errno != 0 ||
                value[0] == '-')
                return cli_usage_error(command, "--seed wants an unsigned integer");
        } else {
            return cli_usage_error(command, "unknown argument \"%s\"", arg);
        }
    }
    if (o->screenshot && !o->window)
        return cli_usage_error(command, "--screenshot needs --window");
    if (o->cycles == 0 && !o->window)
        return cli_usage_error(command, "--cycles 0 (run until closed) needs --window");
    if (o->table2 && (o->window || o->record))
        return cli_usage_error(command, "--table2 runs headless: no --window or --record");
    demo_error err;
    if (!o->table2 && !demo_params_check(&o->params, &err))
        return cli_usage_error(command, "%s", err.message);
    return PARSE_CONTINUE;
}

// mkdir -p: creates dir and its missing parents.
static int make_dirs(const char *dir)
{
    char path[4096];
    size_t len = strlen(dir);
    if (len == 0 || len >= sizeof path)
        return -1;
    memcpy(path, dir, len + 1);
    for (size_t k = 1; k <= len; k++) {
        if (path[k] != '/' && path[k] != '\0')
            continue;
        char saved = path[k];
        path[k] = '\0';
        if (mkdir(path, 0777) != 0 && errno != EEXIST)
            return -1;
        path[k] = saved;
    }
    struct stat st;
    return stat(dir, &st) == 0 && S_ISDIR(st.st_mode) ? 0 : -1;
}

static void sleep_until_ns(uint64_t target)
{
    uint64_t now = demo_now_ns();
    if (target <= now)
        return;
    uint64_t wait = target - now;
    struct timespec ts = {(time_t)(wait / 1000000000u), (long)(wait % 1000000000u)};
    nanosleep(&ts, NULL);
}

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

static double momentum_drift(const demo_totals *t)
{
    double sum = 0;
    for (int a = 0; a < 3; a++) {
        double d = t->momentum_end[a] - t->momentum_start[a] - t->wall_impulse[a];
        sum += d * d;
    }
    return sqrt(sum);
}

static double per_cycle(double sum, const demo_totals *t)
{
    return t->cycles ? sum / (double)t->cycles : 0.0;
}

static void momentum_scale_of(const demo_sim *sim, demo_totals *t)
{
    // The sum of |m v_i|: the size momentum rounding is relative to.
    const double *v = demo_sim_velocities(sim);
    double sum = 0;
    for (uint32_t i = 0; i < demo_sim_count(sim); i++)
        sum +=
            sqrt(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
    t->momentum_scale = sum * demo_sim_params(sim)->mass;
}

static void finish_totals(const demo_sim *sim, demo_totals *t)
{
    t->energy_end = demo_sim_kinetic_energy(sim);
    demo_sim_momentum(sim, t->momentum_end);
    demo_sim_wall_impulse(sim, t->wall_impulse);
    t->max_penetration = demo_sim_max_penetration(sim);
    t->max_speed = demo_sim_max_speed(sim);
    const double *v = demo_sim_velocities(sim);
    size_t n3 = 3 * (size_t)demo_sim_count(sim), inside = 0;
    for (size_t k = 0; k < n3; k++)
        inside += fabs(v[k]) <= 15.0;
    t->within_15 = n3 ? (double)inside / (double)n3 : 0;
}

static void accumulate(demo_totals *t, const demo_step *s)
{
    t->cycles++;
    t->broad_ns += (double)s->broad_ns;
    t->narrow_ns += (double)s->narrow_ns;
    t->response_ns += (double)s->response_ns;
    t->physics_ns += (double)s->physics_ns;
    t->bpx_update_ns += (double)s->bpx.update_ns;
    t->bpx_compare_ns += (double)s->bpx.compare_ns;
    t->bpx_emit_ns += (double)s->bpx.emit_ns;
    t->pairs += (double)s->pairs;
    t->contacts += (double)s->contacts;
    t->impulses += (double)s->impulses;
    t->wall_hits += (double)s->wall_hits;
}

static const char *simd_label(const demo_sim *sim)
{
    return demo_sim_backend(sim) == BPX_BACKEND_BRUTE ? bpx_simd_name(demo_sim_simd(sim)) : "-";
}

static void print_json(FILE *f, const demo_options *o, const demo_sim *sim, const demo_totals *t,
                       const char *picture_dir)
{
    const demo_params *p = demo_sim_params(sim);
    fprintf(f,
            "{\n"
            "  \"spheres\": %u,\n"
            "  \"radius_m\": %.17g,\n"
            "  \"box_m\": [%.17g, %.17g, %.17g],\n"
            "  \"dt_s\": %.17g,\n"
            "  \"restitution\": %.17g,\n"
            "  \"mass_kg\": %.17g,\n"
            "  \"layers\": %u,\n"
            "  \"seed\": %llu,\n"
            "  \"backend\": \"%s\",\n"
            "  \"simd\": \"%s\",\n"
            "  \"threads\": %d,\n"
            "  \"cycles\": %llu,\n"
            "  \"simulated_s\": %.9g,\n"
            "  \"wall_s\": %.6g,\n",
            p->sphere_count, p->radius, t->box[0], t->box[1], t->box[2], p->dt, p->restitution,
            p->mass, p->layers, (unsigned long long)p->seed,
            bpx_backend_name(demo_sim_backend(sim)), simd_label(sim), o->threads,
            (unsigned long long)t->cycles, (double)t->cycles * p->dt, t->wall_s);
    fprintf(f,
            "  \"stage_ms_per_cycle\": {\"broad\": %.6g, \"narrow\": %.6g, \"response\": %.6g, "
            "\"physics\": %.6g, \"display\": %.6g},\n"
            "  \"broad_phase_ms_per_cycle\": %.6g,\n"
            "  \"bpx_ms_per_cycle\": {\"update\": %.6g, \"compare\": %.6g, \"emit\": %.6g},\n"
            "  \"pairs_per_cycle\": %.6g,\n"
            "  \"contacts_per_cycle\": %.6g,\n"
            "  \"impulses_per_cycle\": %.6g,\n"
            "  \"wall_hits_per_cycle\": %.6g,\n",
            per_cycle(t->broad_ns, t) * 1e-6, per_cycle(t->narrow_ns, t) * 1e-6,
            per_cycle(t->response_ns, t) * 1e-6, per_cycle(t->physics_ns, t) * 1e-6,
            per_cycle(t->display_ns, t) * 1e-6, per_cycle(t->broad_ns, t) * 1e-6,
            per_cycle(t->bpx_update_ns, t) * 1e-6, per_cycle(t->bpx_compare_ns, t) * 1e-6,
            per_cycle(t->bpx_emit_ns, t) * 1e-6, per_cycle(t->pairs, t), per_cycle(t->contacts, t),
            per_cycle(t->impulses, t), per_cycle(t->wall_hits, t));
    fprintf(f,
            "  \"kinetic_energy_J\": {\"start\": %.17g, \"end\": %.17g, \"drift_relative\": "
            "%.6g},\n"
            "  \"momentum_kg_m_s\": {\"start\": [%.17g, %.17g, %.17g], \"end\": [%.17g, %.17g, "
            "%.17g], \"wall_impulse\": [%.17g, %.17g, %.17g], \"drift\": %.6g, "
            "\"drift_relative\": %.6g},\n"
            "  \"max_penetration_m\": %.6g,\n"
            "  \"max_speed_m_s\": %.6g,\n"
            "  \"velocity_components_within_15_m_s\": %.6g,\n"
            "  \"pictures\": %d,\n"
            "  \"picture_dir\": ",
            t->energy_start, t->energy_end,
            t->energy_start > 0 ? (t->energy_end - t->energy_start) / t->energy_start : 0.0,
            t->momentum_start[0], t->momentum_start[1], t->momentum_start[2], t->momentum_end[0],
            t->momentum_end[1], t->momentum_end[2], t->wall_impulse[0], t->wall_impulse[1],
            t->wall_impulse[2], momentum_drift(t),
            t->momentum_scale > 0 ? momentum_drift(t) / t->momentum_scale : 0.0, t->max_penetration,
            t->max_speed, t->within_15, t->pictures);
    // Paths are printed as JSON strings; escape what JSON requires.
    const char *strings[2] = {picture_dir, o->record};
    for (int s = 0; s < 2; s++) {
        if (s == 1)
            fprintf(f, ",\n  \"trace\": ");
        if (!strings[s]) {
            fprintf(f, "null");
            continue;
        }
        fputc('"', f);
        for (const char *c = strings[s]; *c; c++) {
            if (*c == '"' || *c == '\\')
                fprintf(f, "\\%c", *c);
            else if ((unsigned char)*c < 0x20)
                fprintf(f, "\\u%04x", (unsigned char)*c);
            else
                fputc(*c, f);
        }
        fputc('"', f);
    }
    fprintf(f, "\n}\n");
}

static void print_tables(const demo_options *o, const demo_sim *sim, const demo_totals *t,
                         const char *picture_dir)
{
    const demo_params *p = demo_sim_params(sim);
    printf("bpx demo: %u spheres of radius %g m in a %g x %g x %g m box (W x H x D); %llu cycles "
           "of %.6g s (%.3g s simulated) in %.2f s\n",
           p->sphere_count, p->radius, t->box[0], t->box[1], t->box[2],
           (unsigned long long)t->cycles, p->dt, (double)t->cycles * p->dt, t->wall_s);
    printf("broad phase: bpx backend %s (simd %s), %d thread%s; restitution %g, mass %g kg, "
           "seed %llu\n\n",
           bpx_backend_name(demo_sim_backend(sim)), simd_label(sim), o->threads,
           o->threads == 1 ? "" : "s", p->restitution, p->mass, (unsigned long long)p->seed);
    double stages[5] = {t->broad_ns, t->narrow_ns, t->response_ns, t->physics_ns, t->display_ns};
    const char *names[5] = {"1. broad phase (bpx)", "2. narrow phase", "3. collision response",
                            "4. physics", "5. display"};
    double total = 0;
    for (int s = 0; s < 5; s++)
        total += stages[s];
    printf("| stage | mean ms per cycle | share |\n|---|---:|---:|\n");
    for (int s = 0; s < 5; s++)
        printf("| %s | %.4f | %.1f %% |\n", names[s], per_cycle(stages[s], t) * 1e-6,
               total > 0 ? 100.0 * stages[s] / total : 0.0);
    printf("| all five | %.4f | 100 %% |\n\n", per_cycle(total, t) * 1e-6);

    printf("| statistic | value |\n|---|---|\n");
    printf("| cycles | %llu |\n", (unsigned long long)t->cycles);
    printf("| mean broad-phase time per cycle | %.4f ms (bpx: updater %.4f, comparator %.4f, "
           "emitter %.4f) |\n",
           per_cycle(t->broad_ns, t) * 1e-6, per_cycle(t->bpx_update_ns, t) * 1e-6,
           per_cycle(t->bpx_compare_ns, t) * 1e-6, per_cycle(t->bpx_emit_ns, t) * 1e-6);
    printf("| mean overlapping AABB pairs per cycle (broad phase) | %.3f |\n",
           per_cycle(t->pairs, t));
    printf("| mean sphere contacts per cycle (narrow phase) | %.3f |\n", per_cycle(t->contacts, t));
    printf("| mean impulses per cycle | %.3f between spheres, %.3f at walls |\n",
           per_cycle(t->impulses, t), per_cycle(t->wall_hits, t));
    printf("| kinetic energy | %.6g J at the start, %.6g J at the end: drift %+.3g (relative) |\n",
           t->energy_start, t->energy_end,
           t->energy_start > 0 ? (t->energy_end - t->energy_start) / t->energy_start : 0.0);
    printf("| momentum drift, \\|p(end) - p(start) - wall impulses\\| | %.3g kg m/s (%.3g "
           "relative to the sum of \\|m v\\|) |\n",
           momentum_drift(t), t->momentum_scale > 0 ? momentum_drift(t) / t->momentum_scale : 0);
    printf("| largest sphere overlap, largest speed | %.3g m, %.4g m/s |\n", t->max_penetration,
           t->max_speed);
    printf("| velocity components within +-15 m/s at the end | %.1f %% |\n", 100.0 * t->within_15);
    if (picture_dir && demo_png_available())
        printf("| pictures | %d PNG files, %dx%d, in %s/ (and stats.json) |\n", t->pictures,
               t->width, t->height, picture_dir);
    else if (picture_dir)
        printf("| pictures | none: this build has no libpng (stats.json is in %s/) |\n",
               picture_dir);
    if (o->record)
        printf("| trace | %s: %llu cycles of %u boxes, %llu bytes |\n", o->record,
               (unsigned long long)t->cycles, p->sphere_count,
               (unsigned long long)(BPX_TRACE_HEADER_BYTES +
                                    t->cycles * (uint64_t)p->sphere_count * BPX_TRACE_BOX_BYTES));
}

static bpx_world_def world_def_of(const demo_options *o)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = o->backend;
    def.worker_count = o->threads;
    return def;
}

static void start_totals(const demo_sim *sim, demo_totals *t)
{
    memset(t, 0, sizeof *t);
    t->energy_start = demo_sim_kinetic_energy(sim);
    demo_sim_momentum(sim, t->momentum_start);
    momentum_scale_of(sim, t);
    demo_sim_box_size(sim, t->box);
}

// --table2: n = 50 .. 500 headless, mean pairs per cycle next to the paper's collisions.
static int run_table2(const demo_options *o)
{
    long cycles = o->cycles_set ? o->cycles : TABLE2_CYCLES;
    if (cycles < 1)
        return cli_usage_error(command, "--table2 needs at least one cycle");
    bpx_world_def def = world_def_of(o);
    if (o->json)
        printf("[\n");
    else
        printf("| n | box W x D (m) | mean AABB pairs per cycle (bpx) | paper's \"collisions\" | "
               "ratio | mean sphere contacts per cycle | broad phase ms per cycle |\n"
               "|---:|---|---:|---:|---:|---:|---:|\n");
    for (int row = 0; row < 10; row++) {
        demo_params p = o->params;
        p.sphere_count = 50u * (uint32_t)(row + 1);
        demo_error err;
        demo_sim *sim;
        if (demo_sim_create(&p, &def, &sim, &err) != 0) {
            cli_error(command, "%s", err.message);
            return CLI_EXIT_ERROR;
        }
        demo_totals t;
        start_totals(sim, &t);
        for (long c = 0; c < cycles; c++) {
            demo_step step;
            if (demo_sim_step(sim, &step, &err) != 0) {
                cli_error(command, "%s", err.message);
                demo_sim_destroy(sim);
                return CLI_EXIT_ERROR;
            }
            accumulate(&t, &step);
        }
        double pairs = per_cycle(t.pairs, &t);
        if (o->json)
            printf("  {\"n\": %u, \"box_m\": [%g, %g, %g], \"cycles\": %ld, \"pairs_per_cycle\": "
                   "%.6g, \"paper_collisions\": %g, \"ratio\": %.4g, \"contacts_per_cycle\": "
                   "%.6g, \"broad_phase_ms_per_cycle\": %.6g}%s\n",
                   p.sphere_count, t.box[0], t.box[1], t.box[2], cycles, pairs,
                   paper_collisions[row], pairs / paper_collisions[row], per_cycle(t.contacts, &t),
                   per_cycle(t.broad_ns, &t) * 1e-6, row < 9 ? "," : "");
        else
            printf("| %u | %g x %g | %.2f | %.3f | %.2f | %.2f | %.4f |\n", p.sphere_count,
                   t.box[0], t.box[2], pairs, paper_collisions[row], pairs / paper_collisions[row],
                   per_cycle(t.contacts, &t), per_cycle(t.broad_ns, &t) * 1e-6);
        fflush(stdout);
        demo_sim_destroy(sim);
    }
    if (o->json)
        printf("]\n");
    else
        printf("\n%ld cycles of %.6g s per row, seed %llu, bpx backend %s, %d thread(s).\n", cycles,
               o->params.dt, (unsigned long long)o->params.seed, bpx_backend_name(o->backend),
               o->threads);
    return CLI_EXIT_OK;
}

// Everything a run owns, released in one place.
typedef struct demo_run {
    demo_sim *sim;
    demo_renderer *renderer;
    demo_window *window;
    bpx_trace_writer *trace;
    bpx_box *boxes;
    unsigned char *capture;
    char *frame_path;
} demo_run;

static int release(demo_run *run, int code)
{
    if (run->trace) {
        bpx_trace_error terr;
        if (bpx_trace_writer_close(run->trace, &terr) != BPX_TRACE_OK && code == CLI_EXIT_OK) {
            cli_error(command, "%s", terr.message);
            code = CLI_EXIT_ERROR;
        }
        run->trace = NULL;
    }
    demo_window_close(run->window);
    demo_renderer_destroy(run->renderer);
    demo_sim_destroy(run->sim);
    free(run->boxes);
    free(run->capture);
    free(run->frame_path);
    return code;
}

static void overlay(demo_renderer *renderer, const demo_sim *sim, const demo_step *s,
                    const demo_totals *t, bool timings)
{
    char lines[3][160];
    const demo_params *p = demo_sim_params(sim);
    snprintf(lines[0], sizeof lines[0], "bpx demo  n=%u  cycle %llu  t=%.2f s  backend %s",
             p->sphere_count, (unsigned long long)demo_sim_cycle(sim),
             (double)demo_sim_cycle(sim) * p->dt, bpx_backend_name(demo_sim_backend(sim)));
    snprintf(lines[1], sizeof lines[1], "pairs %llu (mean %.1f/cycle)  contacts %llu  walls %llu",
             (unsigned long long)s->pairs, per_cycle(t->pairs, t), (unsigned long long)s->contacts,
             (unsigned long long)s->wall_hits);
    snprintf(lines[2], sizeof lines[2],
             "ms: broad %.3f  narrow %.3f  response %.3f  physics %.3f  display %.2f",
             (double)s->broad_ns * 1e-6, (double)s->narrow_ns * 1e-6, (double)s->response_ns * 1e-6,
             (double)s->physics_ns * 1e-6,
             t->cycles > 1 ? t->display_ns / (double)(t->cycles - 1) * 1e-6 : 0.0);
    const char *text[3] = {lines[0], lines[1], lines[2]};
    demo_renderer_overlay(renderer, text, timings ? 3 : 2);
}

int cmd_demo(int argc, char **argv)
{
    demo_options o = {
        .params = demo_default_params(),
        .backend = BPX_BACKEND_AUTO,
        .threads = 1,
        .cycles = DEFAULT_CYCLES,
        .out_dir = DEFAULT_OUT,
        .every = DEFAULT_EVERY,
        .pace = true,
        .width = 640,
        .height = 480,
    };
    int code = parse_args(argc, argv, &o);
    if (code != PARSE_CONTINUE)
        return code;
    if (o.table2)
        return run_table2(&o);

    demo_run run = {0};
    demo_error err;
    bpx_world_def def = world_def_of(&o);
    if (demo_sim_create(&o.params, &def, &run.sim, &err) != 0) {
        cli_error(command, "%s", err.message);
        return CLI_EXIT_ERROR;
    }
    const demo_params *p = demo_sim_params(run.sim);
    uint32_t n = p->sphere_count;

    // Pictures: headless by default; with --window only when asked for. The directory gets
    // stats.json even when this build cannot write PNG files.
    bool use_out = o.every > 0 && (!o.window || o.out_set || o.every_set);
    bool pictures = use_out;
    if (pictures && !demo_png_available()) {
        fprintf(stderr, "bpx demo: this bpx was built without libpng: no pictures are written "
                        "(install libpng-dev and rebuild)\n");
        pictures = false;
    }
    if (use_out && make_dirs(o.out_dir) != 0) {
        cli_error(command, "cannot create the directory %s: %s", o.out_dir, strerror(errno));
        return release(&run, CLI_EXIT_ERROR);
    }
    if (o.window && !demo_window_available()) {
        cli_error(command, "--window is not available: this bpx was built without SDL2 "
                           "(install libsdl2-dev, configure and build again)");
        return release(&run, CLI_EXIT_ERROR);
    }
    if (pictures || o.window) {
        double box[3];
        demo_sim_box_size(run.sim, box);
        if (demo_renderer_create(o.width, o.height, box, &run.renderer, &err) != 0) {
            cli_error(command, "%s", err.message);
            return release(&run, CLI_EXIT_ERROR);
        }
    }
    size_t path_cap = strlen(o.out_dir) + 64;
    run.frame_path = malloc(path_cap);
    run.boxes = malloc((size_t)n * sizeof *run.boxes);
    if (o.screenshot)
        run.capture = malloc((size_t)o.width * o.height * 3);
    if (!run.frame_path || !run.boxes || (o.screenshot && !run.capture)) {
        cli_error(command, "out of memory");
        return release(&run, CLI_EXIT_ERROR);
    }
    if (o.record) {
        bpx_trace_error terr;
        if (bpx_trace_writer_open(o.record, n, &run.trace, &terr) != BPX_TRACE_OK) {
            cli_error(command, "%s", terr.message);
            return release(&run, CLI_EXIT_ERROR);
        }
    }
    if (o.window) {
        if (demo_window_open(o.width, o.height, "bpx demo: spheres in a box", &run.window, &err) !=
            0) {
            cli_error(command, "%s", err.message);
            return release(&run, CLI_EXIT_ERROR);
        }
        fprintf(stderr, "bpx demo: window %dx%d, SDL video driver %s, renderer %s\n", o.width,
                o.height, demo_window_driver(run.window), demo_window_renderer(run.window));
    }

    demo_totals t;
    start_totals(run.sim, &t);
    t.width = o.width;
    t.height = o.height;
    bool captured = false;
    uint64_t start_ns = demo_now_ns();
    for (long c = 0; o.cycles == 0 || c < o.cycles; c++) {
        demo_step step;
        if (demo_sim_step(run.sim, &step, &err) != 0) {
            cli_error(command, "cycle %ld: %s", c, err.message);
            return release(&run, CLI_EXIT_ERROR);
        }
        accumulate(&t, &step);
        if (run.trace) {
            bpx_trace_error terr;
            demo_sim_boxes(run.sim, run.boxes);
            if (bpx_trace_write_cycle(run.trace, run.boxes, &terr) != BPX_TRACE_OK) {
                cli_error(command, "%s", terr.message);
                return release(&run, CLI_EXIT_ERROR);
            }
        }

        // 5. Display: render once, then the PNG file and/or the window.
        uint64_t d0 = demo_now_ns();
        bool last = o.cycles != 0 && c + 1 == o.cycles;
        bool picture = pictures && (c + 1) % o.every == 0;
        if (picture || run.window) {
            demo_renderer_draw(run.renderer, demo_sim_positions(run.sim), n, p->radius);
            overlay(run.renderer, run.sim, &step, &t, run.window != NULL);
        }
        if (picture) {
            snprintf(run.frame_path, path_cap, "%s/frame_%06ld.png", o.out_dir, c + 1);
            if (demo_png_write(run.frame_path, demo_renderer_pixels(run.renderer), o.width,
                               o.height, &err) != 0) {
                cli_error(command, "%s", err.message);
                return release(&run, CLI_EXIT_ERROR);
            }
            t.pictures++;
        }
        bool closing = false;
        if (run.window) {
            // Without a known last cycle (--cycles 0), keep the latest frame for --screenshot.
            unsigned char *capture = run.capture && (last || o.cycles == 0) ? run.capture : NULL;
            if (demo_window_show(run.window, demo_renderer_pixels(run.renderer), capture, &err) !=
                0) {
                cli_error(command, "%s", err.message);
                return release(&run, CLI_EXIT_ERROR);
            }
            captured = captured || capture != NULL;
            closing = demo_window_should_close(run.window);
        }
        t.display_ns += (double)(demo_now_ns() - d0);
        if (closing)
            break;
        if (run.window && o.pace)
            sleep_until_ns(start_ns + (uint64_t)((double)(c + 1) * p->dt * 1e9));
    }
    t.wall_s = (double)(demo_now_ns() - start_ns) * 1e-9;
    finish_totals(run.sim, &t);

    if (o.screenshot) {
        if (!captured) {
            cli_error(command, "no frame was shown, so there is no screenshot");
            return release(&run, CLI_EXIT_ERROR);
        }
        if (demo_png_write(o.screenshot, run.capture, o.width, o.height, &err) != 0) {
            cli_error(command, "%s", err.message);
            return release(&run, CLI_EXIT_ERROR);
        }
    }
    if (run.trace) {
        // Close the trace first: its header's cycle count is final before we report it.
        bpx_trace_error terr;
        bpx_trace_status closed = bpx_trace_writer_close(run.trace, &terr);
        run.trace = NULL;
        if (closed != BPX_TRACE_OK) {
            cli_error(command, "%s", terr.message);
            return release(&run, CLI_EXIT_ERROR);
        }
    }
    const char *picture_dir = use_out ? o.out_dir : NULL;
    if (o.json)
        print_json(stdout, &o, run.sim, &t, picture_dir);
    else
        print_tables(&o, run.sim, &t, picture_dir);
    if (use_out) {
        snprintf(run.frame_path, path_cap, "%s/stats.json", o.out_dir);
        FILE *f = fopen(run.frame_path, "w");
        if (f)
            print_json(f, &o, run.sim, &t, picture_dir);
        if (!f || fclose(f) != 0) {
            cli_error(command, "cannot write %s", run.frame_path);
            return release(&run, CLI_EXIT_ERROR);
        }
    }
    return release(&run, CLI_EXIT_OK);
}
