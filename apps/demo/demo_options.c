// bpx demo's flags: the help text and the parser. SPDX-License-Identifier: MIT

#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "demo_cmd.h"

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

int demo_cmd_parse_args(int argc, char **argv, demo_options *o)
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
