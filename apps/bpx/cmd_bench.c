// bpx bench: times backends side by side on the same boxes, in one run.
// SPDX-License-Identifier: MIT
//
// Method: per scene size, one random scene at constant density (about one overlap per box) moved
// coherently into a few frames that every variant replays in the same order. Each variant gets
// warm-up cycles (buffers grow, threads wake), then timed cycles on a monotonic clock; a cycle is
// what a frame pays: bpx_world_set_boxes + bpx_world_collide. Speed claims are ratios of medians
// measured in this same run.
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "bench_table2.h"
#include "cli.h"
#include "scenes.h"

enum { FRAME_COUNT = 8, MAX_SIZES = 16, MAX_VARIANTS = 32, WARMUP_CYCLES = 5 };

typedef struct bench_variant {
    bpx_backend backend;
    bpx_simd simd;
    int threads;
    bool centres; // opencl: the two-phase updater (centres cross the link, not boxes)
} bench_variant;

typedef struct bench_options {
    uint32_t sizes[MAX_SIZES];
    int size_count;
    int threads;
    double seconds; // time budget per variant and size
    int max_cycles;
    uint64_t seed;
    const char *csv_path;
    bool all_simd;                      // also every narrower SIMD width
    bool table2;                        // the paper's Table 2 instead (bench_table2.c)
    int opencl_platform, opencl_device; // --device P:D, as bpx_world_def (from 1; 0 = best)
} bench_options;

static void print_help(void)
{
    printf("usage: bpx bench [--sizes N,N,...] [--threads T] [--seconds S] [--cycles C]\n"
           "                 [--all-simd] [--seed S] [--csv FILE] [--table2]\n"
           "\n"
           "Times every backend side by side on the same random scenes (constant density,\n"
           "~1 overlap per box, coherent motion) and prints a Markdown table: mean, median,\n"
           "99th-percentile and min microseconds per cycle (set boxes + collide), box-pair\n"
           "tests per second, and the speed-up over the size's first row (reference up to\n"
           "n = 20000, else brute). Quadratic backends are skipped where a cycle takes seconds.\n"
           "--table2 instead replays the paper's scenario (`bpx demo`) for n = 50 .. 500 and\n"
           "prints Table 2's shape next to the paper's figures (--cycles, default 1000).\n"
           "\n"
           "  --sizes     box counts (default 500,10000)\n"
           "  --threads   worker threads of the threaded rows (default: online CPUs)\n"
           "  --seconds   time budget per variant and size (default 0.5)\n"
           "  --cycles    most timed cycles per variant (default 20000)\n"
           "  --all-simd  also time every narrower SIMD width this CPU has\n"
           "  --seed      scene seed (default 1)\n"
           "  --csv FILE  also write the rows as CSV\n"
           "  --device P:D  OpenCL platform and device of the opencl rows (as `bpx devices`)\n"
           "\n"
           "Where the opencl backend is available, its rows follow (simd column: what crosses\n"
           "the link each cycle, \"boxes\" or \"centres\" for the two-phase updater), and a\n"
           "second table gives their device times: transfers in and out, kernels, and the share\n"
           "of communication in them, like Table 2 of the paper.\n");
}

static int parse_sizes(const char *text, bench_options *o)
{
    o->size_count = 0;
    const char *p = text;
    while (*p) {
        char *end;
        unsigned long n = strtoul(p, &end, 10);
        if (end == p || n > 100000000ul || o->size_count == MAX_SIZES)
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

static int parse_args(int argc, char **argv, bench_options *o)
{
    for (int k = 1; k < argc; k++) {
        const char *value = NULL;
        cli_match m;
        if (cli_is_flag(argv[k], "--all-simd")) {
            o->all_simd = true;
        } else if (cli_is_flag(argv[k], "--table2")) {
            o->table2 = true;
        } else if ((m = cli_flag_value(argc, argv, &k, "--sizes", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || parse_sizes(value, o) != 0)
                return cli_usage_error("bench", "--sizes wants box counts like 500,10000");
        } else if ((m = cli_flag_value(argc, argv, &k, "--threads", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || !cli_parse_int(value, 1, 256, &o->threads))
                return cli_usage_error("bench", "--threads wants 1..256");
        } else if ((m = cli_flag_value(argc, argv, &k, "--cycles", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || !cli_parse_int(value, 1, 100000000, &o->max_cycles))
                return cli_usage_error("bench", "--cycles wants a positive count");
        } else if ((m = cli_flag_value(argc, argv, &k, "--seconds", &value)) != CLI_NO_MATCH) {
            char *end = NULL;
            o->seconds = m == CLI_MATCH ? strtod(value, &end) : 0;
            if (m == CLI_MISSING_VALUE || *end != '\0' || !(o->seconds > 0 && o->seconds < 1e4))
                return cli_usage_error("bench", "--seconds wants a positive number");
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
        } else {
            return cli_usage_error("bench", "unknown argument \"%s\"", argv[k]);
        }
    }
    return CLI_EXIT_OK;
}

static void print_machine(const bench_options *o)
{
    char model[256] = "unknown CPU";
    FILE *f = fopen("/proc/cpuinfo", "r");
    if (f) {
        char line[512];
        while (fgets(line, sizeof line, f))
            if (strncmp(line, "model name", 10) == 0) {
                const char *colon = strchr(line, ':');
                if (colon) {
                    snprintf(model, sizeof model, "%s", colon + 2);
                    model[strcspn(model, "\n")] = '\0';
                }
                break;
            }
        fclose(f);
    }
    printf("machine: %s, %ld online CPUs; widest SIMD %s (%d lanes); threads %d; bpx %s\n\n",
           model, sysconf(_SC_NPROCESSORS_ONLN), bpx_simd_name(bpx_simd_best()),
           bpx_simd_lanes(BPX_SIMD_AUTO), o->threads, bpx_version());
}

typedef struct bench_result {
    double mean_us, median_us, p99_us, min_us;
    double pairs; // mean per timed cycle
    uint64_t tests;
    int cycles;
    // opencl: device-clock means per timed cycle (other backends: 0).
    double in_us, out_us, device_us, bytes_in, bytes_out;
} bench_result;

// Runs one variant over the frames. Returns 0, or prints the error and returns -1.
static int run_variant(const bench_variant *v, bpx_box *const frames[FRAME_COUNT], uint32_t n,
                       const bench_options *o, double *samples, bench_result *r)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = v->backend;
    def.simd = v->simd;
    def.worker_count = v->threads;
    def.capacity_hint = n;
    def.opencl_platform = o->opencl_platform;
    def.opencl_device = o->opencl_device;
    bpx_world *world;
    bpx_status status = bpx_world_create(&def, &world);
    if (status != BPX_OK) {
        cli_error("bench", "cannot create %s world: %s", bpx_backend_name(v->backend),
                  bpx_status_string(status));
        return -1;
    }
    // The two-phase updater: each frame's boxes as origin-centred minima (loaded once, from the
    // first frame: motion keeps sizes) and per-frame centres.
    float *centres = NULL;
    if (v->centres) {
        float *minima = malloc(sizeof(float) * 3 * (n ? n : 1));
        centres = malloc(sizeof(float) * 3 * FRAME_COUNT * (n ? n : 1));
        status = minima && centres ? BPX_OK : BPX_ERR_OUT_OF_MEMORY;
        for (int f = 0; f < FRAME_COUNT && status == BPX_OK; f++)
            for (uint32_t i = 0; i < n; i++)
                for (int a = 0; a < 3; a++) {
                    float half = (frames[f][i].max[a] - frames[f][i].min[a]) * 0.5f;
                    centres[((size_t)f * n + i) * 3 + a] = frames[f][i].min[a] + half;
                    if (f == 0)
                        minima[(size_t)i * 3 + a] = -half;
                }
        if (status == BPX_OK)
            status = bpx_world_load_extents(world, minima, n);
        free(minima);
        if (status != BPX_OK) {
            cli_error("bench", "cannot load extents: %s", bpx_status_string(status));
            free(centres);
            bpx_world_destroy(world);
            return -1;
        }
    }
    int cycles = 0;
    double spent = 0, pairs = 0, link[5] = {0};
    for (int c = 0; c < WARMUP_CYCLES + o->max_cycles && spent < o->seconds; c++) {
        double start = cli_now_s();
        status = centres
                     ? bpx_world_update_centres(world, centres + (size_t)(c % FRAME_COUNT) * 3 * n)
                     : bpx_world_set_boxes(world, frames[c % FRAME_COUNT], n);
        if (status == BPX_OK)
            status = bpx_world_collide(world);
        double elapsed = cli_now_s() - start;
        if (status != BPX_OK) {
            cli_error("bench", "%s", bpx_world_error(world)->message);
            bpx_world_destroy(world);
            return -1;
        }
        if (c >= WARMUP_CYCLES) {
            samples[cycles++] = elapsed * 1e6;
            spent += elapsed;
            pairs += (double)bpx_world_stats(world).pair_count;
            bpx_cycle_stats stats = bpx_world_stats(world);
            link[0] += (double)stats.transfer_in_ns * 1e-3;
            link[1] += (double)stats.transfer_out_ns * 1e-3;
            link[2] += (double)stats.device_ns * 1e-3;
            link[3] += (double)stats.bytes_in;
            link[4] += (double)stats.bytes_out;
        }
    }
    bpx_world_destroy(world);
    free(centres);

    double sum = 0;
    for (int c = 0; c < cycles; c++)
        sum += samples[c];
    qsort(samples, (size_t)cycles, sizeof *samples, cli_compare_double);
    *r = (bench_result){
        .mean_us = sum / cycles,
        .median_us = cycles % 2 ? samples[cycles / 2]
                                : 0.5 * (samples[cycles / 2 - 1] + samples[cycles / 2]),
        .p99_us = samples[(int)ceil(0.99 * cycles) - 1],
        .min_us = samples[0],
        .pairs = pairs / cycles,
        .tests = (uint64_t)n * (n > 0 ? n - 1 : 0) / 2,
        .cycles = cycles,
        .in_us = link[0] / cycles,
        .out_us = link[1] / cycles,
        .device_us = link[2] / cycles,
        .bytes_in = link[3] / cycles,
        .bytes_out = link[4] / cycles,
    };
    return 0;
}

// Quadratic backends stop where one cycle would take seconds.
enum { REFERENCE_MAX_N = 20000, BRUTE_MAX_N = 200000, OPENCL_MAX_N = 200000 };

static int list_variants(const bench_options *o, uint32_t n, bench_variant *out)
{
    int count = 0;
    if (n <= REFERENCE_MAX_N)
        out[count++] = (bench_variant){BPX_BACKEND_REFERENCE, BPX_SIMD_AUTO, 1, false};
    bpx_simd best = bpx_simd_best();
    for (int s = BPX_SIMD_COUNT - 1; s > BPX_SIMD_AUTO; s--) {
        if (!bpx_simd_supported((bpx_simd)s) || (!o->all_simd && s != (int)best) ||
            n > BRUTE_MAX_N)
            continue;
        out[count++] = (bench_variant){BPX_BACKEND_BRUTE, (bpx_simd)s, 1, false};
        if (o->threads > 1)
            out[count++] = (bench_variant){BPX_BACKEND_BRUTE, (bpx_simd)s, o->threads, false};
    }
    static const bpx_backend scalable[] = {BPX_BACKEND_PRUNE, BPX_BACKEND_GRID};
    for (size_t k = 0; k < sizeof scalable / sizeof scalable[0]; k++) {
        out[count++] = (bench_variant){scalable[k], BPX_SIMD_AUTO, 1, false};
        if (o->threads > 1)
            out[count++] = (bench_variant){scalable[k], BPX_SIMD_AUTO, o->threads, false};
    }
    // The coprocessor: boxes over the link, then only centres (the paper's updater).
    if (n <= OPENCL_MAX_N && bpx_backend_query(BPX_BACKEND_OPENCL).available) {
        out[count++] = (bench_variant){BPX_BACKEND_OPENCL, BPX_SIMD_AUTO, 1, false};
        out[count++] = (bench_variant){BPX_BACKEND_OPENCL, BPX_SIMD_AUTO, 1, true};
    }
    return count;
}

// The opencl rows again, as Table 2 of the paper: where a cycle's device time goes.
enum { MAX_LINK_ROWS = 2 * MAX_SIZES };
typedef struct link_row {
    uint32_t n;
    bool centres;
    bench_result r;
} link_row;

static void print_link_table(const link_row *rows, int count)
{
    bpx_backend_info info = bpx_backend_query(BPX_BACKEND_OPENCL);
    printf("\nopencl on %s; device-clock means per cycle (transfers as the device's events see "
           "them):\n\n"
           "| n | link | bytes in | bytes out | in us | out us | kernels us | "
           "communication share | cycle median us |\n"
           "|---:|---|---:|---:|---:|---:|---:|---:|---:|\n",
           info.detail);
    for (int k = 0; k < count; k++) {
        const bench_result *r = &rows[k].r;
        double link = r->in_us + r->out_us, total = link + r->device_us;
        printf("| %u | %s | %.0f | %.0f | %.2f | %.2f | %.2f | %.1f %% | %.2f |\n", rows[k].n,
               rows[k].centres ? "centres" : "boxes", r->bytes_in, r->bytes_out, r->in_us,
               r->out_us, r->device_us, total > 0 ? 100.0 * link / total : 0.0, r->median_us);
    }
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
        .sizes = {500, 10000},
        .size_count = 2,
        .threads = cpus > 0 ? (int)(cpus < 256 ? cpus : 256) : 1,
        .seconds = 0.5,
        .max_cycles = 20000,
        .seed = 1,
    };
    int code = parse_args(argc, argv, &o);
    if (code != CLI_EXIT_OK)
        return code;
    if (o.table2) {
        print_machine(&o);
        return bench_table2(o.threads, o.max_cycles == 20000 ? 1000 : o.max_cycles, o.seed) == 0
                   ? CLI_EXIT_OK
                   : CLI_EXIT_ERROR;
    }

    FILE *csv = NULL;
    if (o.csv_path) {
        csv = fopen(o.csv_path, "w");
        if (!csv) {
            cli_error("bench", "cannot write %s", o.csv_path);
            return CLI_EXIT_ERROR;
        }
        fprintf(csv, "n,backend,simd,threads,cycles,pairs,mean_us,median_us,p99_us,min_us,"
                     "gtests_per_s,speedup_vs_first_row\n");
    }
    print_machine(&o);
    printf("| n | backend | simd | threads | pairs/cycle | mean us | median us | p99 us | min us | "
           "G tests/s | vs first row |\n"
           "|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");

    bench_variant variants[MAX_VARIANTS];
    link_row link_rows[MAX_LINK_ROWS];
    int link_count = 0;
    double *samples = malloc(sizeof(double) * ((size_t)o.max_cycles + WARMUP_CYCLES));
    code = samples ? CLI_EXIT_OK : CLI_EXIT_ERROR;
    for (int s = 0; s < o.size_count && code == CLI_EXIT_OK; s++) {
        uint32_t n = o.sizes[s];
        bpx_box *frames[FRAME_COUNT] = {0};
        for (int f = 0; f < FRAME_COUNT; f++)
            if (!(frames[f] = malloc(sizeof(bpx_box) * (n ? n : 1))))
                code = CLI_EXIT_ERROR;
        if (code == CLI_EXIT_OK) {
            scene_uniform_density(n, 1.0f, o.seed, frames[0]);
            scene_rng rng;
            scene_rng_seed(&rng, o.seed ^ 0x9e3779b97f4a7c15ull);
            for (int f = 1; f < FRAME_COUNT; f++) {
                memcpy(frames[f], frames[f - 1], sizeof(bpx_box) * n);
                scene_move(frames[f], n, 0.05f, &rng);
            }
        }
        int variant_count = list_variants(&o, n, variants);
        double reference_median = 0;
        for (int v = 0; v < variant_count && code == CLI_EXIT_OK; v++) {
            bench_result r;
            if (run_variant(&variants[v], frames, n, &o, samples, &r) != 0) {
                code = CLI_EXIT_ERROR;
                break;
            }
            double gtests = r.median_us > 0 ? (double)r.tests / r.median_us * 1e-3 : 0;
            // Against the first variant of this size (reference where it runs, else brute).
            if (v == 0)
                reference_median = r.median_us;
            double speedup = r.median_us > 0 ? reference_median / r.median_us : 0;
            const char *simd = variants[v].backend == BPX_BACKEND_OPENCL
                                   ? (variants[v].centres ? "centres" : "boxes")
                               : variants[v].backend == BPX_BACKEND_REFERENCE
                                   ? "-"
                                   : bpx_simd_name(variants[v].simd == BPX_SIMD_AUTO
                                                       ? bpx_simd_best()
                                                       : variants[v].simd);
            printf("| %u | %s | %s | %d | %.1f | %.2f | %.2f | %.2f | %.2f | %.2f | %.1fx |\n", n,
                   bpx_backend_name(variants[v].backend), simd, variants[v].threads, r.pairs,
                   r.mean_us, r.median_us, r.p99_us, r.min_us, gtests, speedup);
            fflush(stdout);
            if (variants[v].backend == BPX_BACKEND_OPENCL && link_count < MAX_LINK_ROWS)
                link_rows[link_count++] = (link_row){n, variants[v].centres, r};
            if (csv)
                fprintf(csv, "%u,%s,%s,%d,%d,%.2f,%.3f,%.3f,%.3f,%.3f,%.4f,%.3f\n", n,
                        bpx_backend_name(variants[v].backend), simd, variants[v].threads,
                        r.cycles, r.pairs, r.mean_us, r.median_us, r.p99_us,
                        r.min_us, gtests, speedup);
        }
        for (int f = 0; f < FRAME_COUNT; f++)
            free(frames[f]);
    }
    free(samples);
    if (code == CLI_EXIT_OK && link_count > 0)
        print_link_table(link_rows, link_count);
    if (csv && fclose(csv) != 0) {
        cli_error("bench", "cannot write %s", o.csv_path);
        code = CLI_EXIT_ERROR;
    }
    return code;
}
