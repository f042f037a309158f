// bpx bench --table2: the paper's Table 2 on the paper's scenario, next to the paper's figures.
// SPDX-License-Identifier: MIT
//
// For n = 50, 100, ..., 500 the demo's simulation (apps/demo/demo_sim.h, `bpx demo`'s defaults)
// is run for C cycles and its centres recorded; then every CPU backend replays the same cycles
// the paper's way (extents loaded once, centres each cycle: bpx_world_update_centres +
// bpx_world_collide, timed together). The first cycle is reported apart ("cold": sorts from
// scratch, like SOLID's "incl sort"); mean, median and p99 are over the others.
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_table2.h"
#include "cli.h"
#include "demo_sim.h"

// Table 2 of Woulfe et al. 2007, ms per cycle (Pentium 4, 1.8 GHz; FPGA at 108 MHz on PCI).
static const struct {
    uint32_t n;
    double fpga_m4, fpga_m8, solid_incl, solid_excl, collisions;
} paper[] = {
    {50, 0.242, 0.216, 0.043, 0.042, 7.47},    {100, 0.289, 0.276, 0.146, 0.139, 12.588},
    {150, 0.332, 0.289, 0.195, 0.163, 20.413}, {200, 0.356, 0.312, 0.318, 0.218, 26.703},
    {250, 0.419, 0.348, 0.597, 0.353, 35.628}, {300, 0.471, 0.368, 0.914, 0.418, 44.61},
    {350, 0.5, 0.394, 1.431, 0.501, 51.416},   {400, 0.569, 0.425, 2.708, 0.575, 60.053},
    {450, 0.631, 0.464, 4.92, 0.645, 64.427},  {500, 0.731, 0.513, 8.325, 0.754, 76.079},
};
enum { ROWS = sizeof paper / sizeof paper[0] };

typedef struct variant {
    bpx_backend backend;
    int threads;
} variant;

// Records `cycles` cycles of the scenario: centres[c * 3n ...] as float, minima once.
static int record(uint32_t n, int cycles, uint64_t seed, float *minima, float *centres,
                  double *pairs)
{
    demo_params params = demo_default_params();
    params.sphere_count = n;
    params.seed = seed;
    demo_sim *sim;
    demo_error err;
    if (demo_sim_create(&params, NULL, &sim, &err) != 0) {
        fprintf(stderr, "bpx bench: %s\n", err.message);
        return -1;
    }
    for (size_t k = 0; k < 3 * (size_t)n; k++)
        minima[k] = (float)-params.radius;
    double sum = 0;
    for (int c = 0; c < cycles; c++) {
        const double *pos = demo_sim_positions(sim);
        for (size_t k = 0; k < 3 * (size_t)n; k++)
            centres[(size_t)c * 3 * n + k] = (float)pos[k];
        if (demo_sim_step(sim, NULL, &err) != 0) {
            fprintf(stderr, "bpx bench: %s\n", err.message);
            demo_sim_destroy(sim);
            return -1;
        }
        size_t count;
        demo_sim_pairs(sim, &count);
        sum += (double)count;
    }
    *pairs = sum / cycles;
    demo_sim_destroy(sim);
    return 0;
}

// Times one variant over the recorded cycles: cold first cycle, then mean/median/p99 in us.
static int replay(const variant *v, uint32_t n, int cycles, const float *minima,
                  const float *centres, double *samples, double out[4])
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = v->backend;
    def.worker_count = v->threads;
    bpx_world *w;
    if (bpx_world_create(&def, &w) != BPX_OK || bpx_world_load_extents(w, minima, n) != BPX_OK) {
        fprintf(stderr, "bpx bench: cannot set up %s\n", bpx_backend_name(v->backend));
        bpx_world_destroy(w);
        return -1;
    }
    for (int c = 0; c < cycles; c++) {
        double start = cli_now_s();
        bpx_status status = bpx_world_update_centres(w, centres + (size_t)c * 3 * n);
        if (status == BPX_OK)
            status = bpx_world_collide(w);
        samples[c] = (cli_now_s() - start) * 1e6;
        if (status != BPX_OK) {
            fprintf(stderr, "bpx bench: %s\n", bpx_world_error(w)->message);
            bpx_world_destroy(w);
            return -1;
        }
    }
    bpx_world_destroy(w);
    double sum = 0;
    for (int c = 1; c < cycles; c++)
        sum += samples[c];
    out[0] = samples[0];
    out[1] = sum / (cycles - 1);
    qsort(samples + 1, (size_t)cycles - 1, sizeof(double), cli_compare_double);
    out[2] = samples[1 + (cycles - 1) / 2];
    out[3] = samples[1 + (int)ceil(0.99 * (cycles - 1)) - 1];
    return 0;
}

int bench_table2(int threads, int cycles, uint64_t seed)
{
    if (cycles < 2)
        cycles = 2;
    variant variants[] = {
        {BPX_BACKEND_BRUTE, 1}, {BPX_BACKEND_BRUTE, threads}, {BPX_BACKEND_PRUNE, 1},
        {BPX_BACKEND_GRID, 1},  {BPX_BACKEND_AUTO, 1},
    };
    enum { VARIANTS = sizeof variants / sizeof variants[0] };
    uint32_t most = paper[ROWS - 1].n;
    float *minima = malloc(sizeof(float) * 3 * most);
    float *centres = malloc(sizeof(float) * 3 * most * (size_t)cycles);
    double *samples = malloc(sizeof(double) * (size_t)cycles);
    double result[ROWS][VARIANTS][4], pairs[ROWS];
    int code = minima && centres && samples ? 0 : -1;
    for (int r = 0; r < ROWS && code == 0; r++) {
        uint32_t n = paper[r].n;
        code = record(n, cycles, seed, minima, centres, &pairs[r]);
        for (int v = 0; v < VARIANTS && code == 0; v++)
            code = replay(&variants[v], n, cycles, minima, centres, samples, result[r][v]);
        fprintf(stderr, "\rbpx bench: table 2, n = %u done", n);
    }
    fprintf(stderr, "\n");
    if (code == 0) {
        printf("Table 2 on the paper's scenario (`bpx demo` defaults, seed %llu): %d cycles per n,\n"
               "the paper's two-phase interface (extents once, centres each cycle). bpx columns:\n"
               "mean us per cycle after the first; cold = the first cycle alone (sorts from\n"
               "scratch, the paper's \"incl sort\"). Paper columns: ms per cycle on a 1.8 GHz\n"
               "Pentium 4 (SOLID) and its PCI FPGA, communication included.\n\n",
               (unsigned long long)seed, cycles);
        printf("| n | pairs/cycle bpx / paper | brute 1 thr | brute %d thr | prune (cold) | grid | "
               "auto | best bpx median us | paper FPGA m=8 ms | paper SOLID excl ms | paper FPGA / "
               "best bpx |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
               threads);
        for (int r = 0; r < ROWS; r++) {
            double best = INFINITY;
            for (int v = 0; v < VARIANTS; v++)
                best = fmin(best, result[r][v][2]);
            printf("| %u | %.1f / %.1f | %.2f | %.2f | %.2f (%.1f) | %.2f | %.2f | %.2f | %.3f | "
                   "%.3f | %.0fx |\n",
                   paper[r].n, pairs[r], paper[r].collisions, result[r][0][1], result[r][1][1],
                   result[r][2][1], result[r][2][0], result[r][3][1], result[r][4][1], best,
                   paper[r].fpga_m8, paper[r].solid_excl, paper[r].fpga_m8 * 1e3 / best);
        }
    } else {
        fprintf(stderr, "bpx bench: table 2 failed\n");
    }
    free(minima);
    free(centres);
    free(samples);
    return code;
}
