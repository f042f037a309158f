// bpx bench, part 1: the paper's Table 2 on the paper's scenario, next to the paper's figures.
// SPDX-License-Identifier: MIT
//
// For n = 50, 100, ..., 500 the demo's simulation (apps/demo/demo_sim.h, `bpx demo`'s defaults)
// runs for C cycles and its centres and pair counts are recorded; then every variant replays the
// same cycles: bpx backends the paper's way (extents loaded once, centres each cycle:
// bpx_world_update_centres + bpx_world_collide, timed together), peers with the same boxes. The
// first cycle is reported apart ("cold": sorts from scratch, the paper's "incl sort"); mean,
// median and p99 are over the others.
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"
#include "demo_sim.h"
#include "peers.h"

// Table 2 of Woulfe et al. 2007, ms per cycle (Pentium 4, 1.8 GHz; FPGA at 108 MHz on PCI).
static const struct {
    uint32_t n;
    double fpga_m4, fpga_m8, solid_incl, solid_excl, comm_share_m8, collisions;
} paper[] = {
    {50, 0.242, 0.216, 0.043, 0.042, 82.1, 7.47},
    {100, 0.289, 0.276, 0.146, 0.139, 70.5, 12.588},
    {150, 0.332, 0.289, 0.195, 0.163, 68.7, 20.413},
    {200, 0.356, 0.312, 0.318, 0.218, 66.7, 26.703},
    {250, 0.419, 0.348, 0.597, 0.353, 62.6, 35.628},
    {300, 0.471, 0.368, 0.914, 0.418, 61.1, 44.61},
    {350, 0.5, 0.394, 1.431, 0.501, 59.7, 51.416},
    {400, 0.569, 0.425, 2.708, 0.575, 58.8, 60.053},
    {450, 0.631, 0.464, 4.92, 0.645, 54.6, 64.427},
    {500, 0.731, 0.513, 8.325, 0.754, 52.7, 76.079},
};
enum { ROWS = sizeof paper / sizeof paper[0] };

// Records `cycles` cycles of the scenario: centres (cycles * 3n floats), minima once, the
// simulation's pair count per cycle, and bounds containing every box.
static int record(uint32_t n, int cycles, uint64_t seed, float *minima, float *centres,
                  uint64_t *pairs, bench_frames *frames)
{
    demo_params params = demo_default_params();
    params.sphere_count = n;
    params.seed = seed;
    demo_sim *sim;
    demo_error err;
    if (demo_sim_create(&params, NULL, &sim, &err) != 0) {
        cli_error("bench", "%s", err.message);
        return -1;
    }
    float r = (float)params.radius;
    for (size_t k = 0; k < 3 * (size_t)n; k++)
        minima[k] = -r;
    *frames = (bench_frames){
        .n = n, .count = cycles, .minima = minima, .centres = centres, .pairs = pairs};
    for (int a = 0; a < 3; a++)
        frames->bounds_min[a] = INFINITY, frames->bounds_max[a] = -INFINITY;
    for (int c = 0; c < cycles; c++) {
        const double *pos = demo_sim_positions(sim);
        for (size_t k = 0; k < 3 * (size_t)n; k++) {
            float x = (float)pos[k];
            centres[(size_t)c * 3 * n + k] = x;
            frames->bounds_min[k % 3] = fminf(frames->bounds_min[k % 3], x - r);
            frames->bounds_max[k % 3] = fmaxf(frames->bounds_max[k % 3], x + r);
        }
        if (demo_sim_step(sim, NULL, &err) != 0) {
            cli_error("bench", "%s", err.message);
            demo_sim_destroy(sim);
            return -1;
        }
        size_t count;
        demo_sim_pairs(sim, &count);
        pairs[c] = count;
    }
    demo_sim_destroy(sim);
    return 0;
}

static int list_variants(const bench_table2_options *o, bench_variant *out)
{
    // The CPU backends the paper's way (centres each cycle); brute also on every thread.
    static const bpx_backend cpu[] = {BPX_BACKEND_BRUTE, BPX_BACKEND_PRUNE, BPX_BACKEND_SAP,
                                      BPX_BACKEND_GRID, BPX_BACKEND_AUTO};
    bench_variant all[BENCH_MAX_VARIANTS];
    int count = 0;
    for (size_t k = 0; k < sizeof cpu / sizeof cpu[0]; k++) {
        all[count++] = (bench_variant){-1, cpu[k], BPX_SIMD_AUTO, 1, true, 0};
        if (cpu[k] == BPX_BACKEND_BRUTE && o->threads > 1)
            all[count++] = (bench_variant){-1, cpu[k], BPX_SIMD_AUTO, o->threads, true, 0};
    }
    if (bpx_backend_query(BPX_BACKEND_OPENCL).available)
        all[count++] = (bench_variant){-1, BPX_BACKEND_OPENCL, BPX_SIMD_AUTO, 1, true, 0};
    if (bpx_backend_query(BPX_BACKEND_CUDA).available)
        all[count++] = (bench_variant){-1, BPX_BACKEND_CUDA, BPX_SIMD_AUTO, 1, true, 0};
    // The chip's RTL, simulated: the paper's design the paper's way (n <= 500 fits its RAMs).
    if (bpx_backend_query(BPX_BACKEND_RTL).available)
        all[count++] = (bench_variant){-1, BPX_BACKEND_RTL, BPX_SIMD_AUTO, 1, true, 0};
    for (int p = 0; p < bench_peer_count() && count < BENCH_MAX_VARIANTS; p++)
        all[count++] = (bench_variant){p, BPX_BACKEND_AUTO, BPX_SIMD_AUTO, 1, false, 0};
    int kept = 0;
    for (int k = 0; k < count; k++)
        if (!o->wanted || o->wanted(&all[k], o->wanted_context))
            out[kept++] = all[k];
    return kept;
}

static void print_ms_ratio(double over, double under)
{
    if (over > 0 && under > 0 && isfinite(over) && isfinite(under))
        bench_printf(" %.1fx |", over / under);
    else
        bench_printf(" - |");
}

// Returns -1 on error, else the number of cycles whose pair count was wrong (0 when all agree).
int bench_table2(const bench_table2_options *o)
{
    int cycles = o->cycles < 2 ? 2 : o->cycles;
    bench_variant variants[BENCH_MAX_VARIANTS];
    int count = list_variants(o, variants);
    uint32_t most = paper[ROWS - 1].n;
    float *minima = malloc(sizeof(float) * 3 * most);
    float *centres = malloc(sizeof(float) * 3 * most * (size_t)cycles);
    uint64_t *pairs = malloc(sizeof(uint64_t) * (size_t)cycles);
    bench_result(*results)[BENCH_MAX_VARIANTS] = calloc(ROWS, sizeof *results);
    double sim_pairs[ROWS] = {0};
    int code = minima && centres && pairs && results ? 0 : -1;
    for (int r = 0; r < ROWS && code == 0; r++) {
        uint32_t n = paper[r].n;
        bench_frames frames;
        bench_progress("bpx bench: table 2, n = %u: recording the scenario", n);
        code = record(n, cycles, o->seed, minima, centres, pairs, &frames);
        for (int c = 0; c < cycles && code == 0; c++)
            sim_pairs[r] += (double)pairs[c] / cycles;
        // Every variant's first (cold) cycle, then the rest in BENCH_ROUNDS turns, each round
        // starting one variant later, as the scale rows do.
        bench_budget budget = {INFINITY, cycles, 0, 0};
        bench_session *sessions[BENCH_MAX_VARIANTS] = {0};
        for (int v = 0; v < count && code == 0; v++) {
            char name[BENCH_NAME_SIZE];
            bench_variant_name(&variants[v], name, sizeof name);
            bench_progress("bpx bench: table 2, n = %u: %s (%d/%d)", n, name, v + 1, count);
            code = bench_open(&variants[v], &frames, &budget, &sessions[v]);
        }
        int turn = (cycles - 1 + BENCH_ROUNDS - 1) / BENCH_ROUNDS;
        for (int round = 0; round < BENCH_ROUNDS && code == 0; round++) {
            bench_progress("bpx bench: table 2, n = %u: round %d/%d", n, round + 1, BENCH_ROUNDS);
            for (int k = 0; k < count && code == 0; k++)
                code = bench_step(sessions[(k + round) % count], INFINITY, turn);
        }
        for (int v = 0; v < count; v++) {
            if (code == 0)
                bench_close(sessions[v], &results[r][v]);
            else
                bench_abandon(sessions[v]);
        }
    }
    bench_progress(NULL);
    int wrong = 0;
    if (code == 0) {
        bench_printf(
            "Table 2 on the paper's scenario (`bpx demo` defaults, seed %llu): %d cycles per n,\n"
            "bpx through the paper's two-phase interface (extents once, centres each cycle),\n"
            "peers given the same boxes; after the first cycle, the variants play the rest in\n"
            "%d turns, in rotation. us per cycle after the first; cold = the first cycle\n"
            "alone (sorts from scratch, the paper's \"incl sort\"). Paper: ms per cycle on a\n"
            "1.8 GHz Pentium 4 (SOLID 3.5.6's sweep and prune) and its PCI FPGA, communication\n"
            "included.\n\n",
            (unsigned long long)o->seed, cycles, BENCH_ROUNDS);
        bench_printf(
            "| n | pairs/cycle bpx / paper | best bpx | mean us | median us | p99 us | "
            "cold us | sap mean (cold) us, cycles rebuilt | fastest peer | mean us | best vs sap | "
            "best "
            "vs fastest peer | paper FPGA m=4 / m=8 ms | paper SOLID incl / excl ms | "
            "paper FPGA m=8 / best bpx |\n"
            "|---:|---:|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|\n");
        for (int r = 0; r < ROWS; r++) {
            int best = -1, peer = -1, sap = -1;
            for (int v = 0; v < count; v++) {
                const bench_variant *var = &variants[v];
                double mean = results[r][v].mean_us;
                wrong += results[r][v].mismatches;
                if (var->peer >= 0 && (peer < 0 || mean < results[r][peer].mean_us))
                    peer = v;
                if (var->peer < 0 && (best < 0 || mean < results[r][best].mean_us))
                    best = v;
                if (var->peer < 0 && var->backend == BPX_BACKEND_SAP)
                    sap = v;
            }
            char best_name[BENCH_NAME_SIZE] = "-", peer_name[BENCH_NAME_SIZE] = "-";
            const bench_result none = {
                .mean_us = NAN, .median_us = NAN, .p99_us = NAN, .cold_us = NAN};
            const bench_result *b = best >= 0 ? &results[r][best] : &none;
            const bench_result *p = peer >= 0 ? &results[r][peer] : &none;
            const bench_result *s = sap >= 0 ? &results[r][sap] : &none;
            if (best >= 0)
                bench_variant_name(&variants[best], best_name, sizeof best_name);
            if (peer >= 0)
                bench_variant_name(&variants[peer], peer_name, sizeof peer_name);
            bench_printf("| %u | %.1f / %.1f | %s | %.2f | %.2f | %.2f | %.2f |", paper[r].n,
                         sim_pairs[r], paper[r].collisions, best_name, b->mean_us, b->median_us,
                         b->p99_us, b->cold_us);
            if (sap >= 0) // a run without sap (--backend) has no sap column to fill
                bench_printf(" %.2f (%.1f), %d |", s->mean_us, s->cold_us, s->rebuilt);
            else
                bench_printf(" - |");
            if (peer >= 0)
                bench_printf(" %s | %.2f |", peer_name, p->mean_us);
            else
                bench_printf(" - | - |");
            print_ms_ratio(s->mean_us, b->mean_us);
            print_ms_ratio(p->mean_us, b->mean_us);
            bench_printf(" %.3f / %.3f | %.3f / %.3f |", paper[r].fpga_m4, paper[r].fpga_m8,
                         paper[r].solid_incl, paper[r].solid_excl);
            print_ms_ratio(paper[r].fpga_m8 * 1e3, b->mean_us);
            bench_printf("\n");
        }

        bench_printf("\nMean us per cycle of every variant (cold first cycle excluded):\n\n| n |");
        for (int v = 0; v < count; v++) {
            char name[BENCH_NAME_SIZE];
            bench_variant_name(&variants[v], name, sizeof name);
            bench_printf(" %s |", name);
        }
        bench_printf("\n|---:|");
        for (int v = 0; v < count; v++)
            bench_printf("---:|");
        bench_printf("\n");
        for (int r = 0; r < ROWS; r++) {
            bench_printf("| %u |", paper[r].n);
            for (int v = 0; v < count; v++)
                bench_printf(results[r][v].mismatches ? " **%.2f wrong** |" : " %.2f |",
                             results[r][v].mean_us);
            bench_printf("\n");
        }

        for (int v = 0; v < count; v++)
            if (variants[v].peer < 0 && (variants[v].backend == BPX_BACKEND_OPENCL ||
                                         variants[v].backend == BPX_BACKEND_CUDA)) {
                bench_printf("\n%s (%s): "
                             "communication share of its device time, against the paper's "
                             "m = 8:\n\n| n | mean us | in us | out us | kernels us | share | "
                             "paper share |\n|---:|---:|---:|---:|---:|---:|---:|\n",
                             bpx_backend_name(variants[v].backend),
                             variants[v].backend == BPX_BACKEND_CUDA
                                 ? "centres over the link, the paper's updater in the "
                                   "comparator's launch"
                                 : "centres over the link, the paper's updater");
                for (int r = 0; r < ROWS; r++) {
                    const bench_result *x = &results[r][v];
                    double link = x->in_us + x->out_us, total = link + x->device_us;
                    bench_printf("| %u | %.2f | %.2f | %.2f | %.2f | %.1f %% | %.1f %% |\n",
                                 paper[r].n, x->mean_us, x->in_us, x->out_us, x->device_us,
                                 total > 0 ? 100 * link / total : 0.0, paper[r].comm_share_m8);
                }
            }
        if (o->csv) {
            fprintf(o->csv, "n,variant,threads,cycles,pairs_reported,pairs_exact,cold_us,mean_us,"
                            "median_us,p99_us,min_us,wrong_cycles,paper_fpga_m8_ms,"
                            "paper_solid_excl_ms\n");
            for (int r = 0; r < ROWS; r++)
                for (int v = 0; v < count; v++) {
                    char name[BENCH_NAME_SIZE];
                    bench_variant_name(&variants[v], name, sizeof name);
                    const bench_result *x = &results[r][v];
                    fprintf(o->csv, "%u,%s,%d,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%d,%.3f,%.3f\n",
                            paper[r].n, name, variants[v].threads, x->cycles, x->pairs,
                            x->exact_pairs, x->cold_us, x->mean_us, x->median_us, x->p99_us,
                            x->min_us, x->mismatches, paper[r].fpga_m8, paper[r].solid_excl);
                }
        }
    } else if (minima && centres && pairs && results) {
        cli_error("bench", "table 2 failed");
    } else {
        cli_error("bench", "out of memory for %d cycles of table 2", cycles);
    }
    free(minima);
    free(centres);
    free(pairs);
    free(results);
    return code == 0 ? wrong : -1;
}
