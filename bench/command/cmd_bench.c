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
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "bench_cmd.h"
#include "peers.h"

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

static void print_help(void)
{
    printf("usage: bpx bench [--quick] [--out DIR] [--backend NAME,...] [--sizes N,...]\n"
           "                 [--scene uniform,heavy,resting] [--step D] [--table2] [--threads T]\n"
           "                 [--seconds S] [--cycles C] [--all-simd] [--seed S] [--csv FILE]\n"
           "                 [--device P:D] [--profile]\n"
           "\n"
           "Times every bpx backend and every peer library built in (Bullet, Box2D, FCL:\n"
           "see `bpx backends`) side by side, in two parts:\n"
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
           "  --device P:D  OpenCL platform and device of the opencl rows (as `bpx devices`)\n"
           "  --profile   instead of both parts: per backend (--backend; default grid,sap,auto),\n"
           "              size (default 1000000) and scene (default uniform), each stage's\n"
           "              time, bytes read and written and GB/s, beside the memory floor\n"
           "              (bpx_memfloor's sequential copy, gather and scatter, measured in the\n"
           "              same run on --threads threads) and each stage's ratio to its floor;\n"
           "              peak memory per box; the cycle with the profile off, for its cost\n");
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
    int code = bench_cmd_parse_args(argc, argv, &o);
    if (code != CLI_EXIT_OK)
        return code;
    bool run_table2 = o.table2 || !o.sizes_given, scale = o.sizes_given || !o.table2;
    if (o.profile) // the stage tables alone
        run_table2 = scale = false;
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

    if (code == CLI_EXIT_OK && !o.profile) {
        bench_print_machine(o.threads);
        bench_printf("peers:");
        for (int p = 0; p < bench_peer_count(); p++)
            bench_printf("%s %s (%s)", p ? ";" : "", bench_peer_get(p)->name,
                         bench_peer_get(p)->detail);
        bench_printf("%s%s\n\n", bench_peer_count() ? "" : " none: ",
                     bench_peer_count() ? "" : bench_peers_unavailable());
    }
    if (code == CLI_EXIT_OK && o.profile) { // --profile: the stage tables alone
        if (!o.sizes_given)
            o.size_count = 1, o.sizes[0] = 1000000;
        if (bench_cmd_run_profile(&o) != 0)
            code = CLI_EXIT_ERROR;
    }
    if (code == CLI_EXIT_OK && run_table2) {
        bench_table2_options t2 = {o.threads, table2_cycles, o.seed, bench_cmd_wanted,
                                   &o,        table2_csv};
        int rc = bench_table2(&t2);
        if (rc < 0)
            code = CLI_EXIT_ERROR;
        st->mismatches += rc > 0 ? rc : 0;
    }
    if (code == CLI_EXIT_OK && scale) {
        if (run_table2)
            bench_printf("\n");
        if (bench_cmd_run_scale(st) != 0 || (o.out_dir && bench_cmd_write_plots(st) != 0))
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
