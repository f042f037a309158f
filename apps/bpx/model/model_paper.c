// bpx model --paper: the model beside Table 2 of the paper, with the link's setup cost fitted
// to its communication column. SPDX-License-Identifier: MIT

#include <string.h>

#include "model_cmd.h"

// ---------------------------------------------------------------------------------------------
// ---------------------------------------------------------------------------------------------
// Table 2 of the paper: the FPGA columns, the communication column and collisions per cycle.

typedef struct paper_row {
    uint32_t n;
    double fpga_ms[2]; // m = 4, m = 8
    double comm_ms;
    double share[2]; // communication share, %, m = 4, m = 8
    double collisions;
} paper_row;

static const paper_row table2[PAPER_ROWS] = {
    {50, {0.242, 0.216}, 0.178, {73.542, 82.096}, 7.47},
    {100, {0.289, 0.276}, 0.194, {67.304, 70.478}, 12.588},
    {150, {0.332, 0.289}, 0.199, {59.825, 68.701}, 20.413},
    {200, {0.356, 0.312}, 0.208, {58.418, 66.653}, 26.703},
    {250, {0.419, 0.348}, 0.218, {51.958, 62.578}, 35.628},
    {300, {0.471, 0.368}, 0.225, {47.772, 61.064}, 44.61},
    {350, {0.5, 0.394}, 0.235, {47.094, 59.709}, 51.416},
    {400, {0.569, 0.425}, 0.25, {43.935, 58.822}, 60.053},
    {450, {0.631, 0.464}, 0.253, {40.183, 54.594}, 64.427},
    {500, {0.731, 0.513}, 0.27, {37.001, 52.743}, 76.079},
};

static const int paper_m[2] = {4, 8};

// ---------------------------------------------------------------------------------------------
// ---------------------------------------------------------------------------------------------
// --paper

typedef struct paper_result {
    double collisions;
    double chip_ns[2];
    double chip_clocks[2];
    double fixed_ns;  // link time without the DMA setup cost
    double transfers; // DMA transfers per cycle
    double bytes;     // bytes over the link per cycle
    double registers_ns;
} paper_result;

// Least squares fit of y = a + b x.
static void fit_line(const double *x, const double *y, int count, double *a, double *b)
{
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (int k = 0; k < count; k++) {
        sx += x[k];
        sy += y[k];
        sxx += x[k] * x[k];
        sxy += x[k] * y[k];
    }
    double det = count * sxx - sx * sx;
    *b = det != 0 ? (count * sxy - sx * sy) / det : 0;
    *a = (sy - *b * sx) / count;
}

int model_run_paper(const model_options *o)
{
    paper_result res[PAPER_ROWS];
    bpx_model_config configs[2] = {o->config, o->config};
    for (int k = 0; k < 2; k++)
        configs[k].m = paper_m[k];
    const double setup = o->config.link.setup_ns;
    printf("bpx model --paper: the paper's scene for n = 50..500, m = 4 and m = 8, %d measured "
           "cycles after %d warm-up cycles each, seed %llu\n",
           o->cycles, o->warmup, (unsigned long long)o->seed);
    model_print_config(&configs[0]);
    fflush(stdout);
    int mismatches = 0;
    for (int row = 0; row < PAPER_ROWS; row++) {
        report_sum sums[2] = {{0}};
        int code = model_run_spheres(o, table2[row].n, configs, 2, sums, &mismatches, false);
        if (code != CLI_EXIT_OK)
            return code;
        paper_result *p = &res[row];
        p->collisions = mean(&sums[0], sums[0].collisions);
        for (int k = 0; k < 2; k++) {
            p->chip_ns[k] = mean(&sums[k], sums[k].chip_ns);
            p->chip_clocks[k] = mean(&sums[k], sums[k].chip);
        }
        // The link's cost does not depend on m: the same data cross it.
        p->transfers = mean(&sums[0], sums[0].dma);
        p->fixed_ns = mean(&sums[0], sums[0].transfer_ns) - setup * p->transfers;
        p->bytes = mean(&sums[0], sums[0].bytes_down + sums[0].bytes_up);
        p->registers_ns = mean(&sums[0], sums[0].registers) * o->config.link.register_ns;
    }

    // The setup cost per DMA transfer that best fits Table 2's communication column (least
    // squares), with the bandwidth and register cost as configured.
    double num = 0, den = 0;
    for (int row = 0; row < PAPER_ROWS; row++) {
        num += res[row].transfers * (table2[row].comm_ms * 1e6 - res[row].fixed_ns);
        den += res[row].transfers * res[row].transfers;
    }
    double fitted = den > 0 ? num / den : 0;
    if (fitted < 0)
        fitted = 0;

    printf("\nlink setup cost fitted to Table 2's communication column: %.1f us per DMA "
           "transfer (configured: %.1f us)\n\n",
           fitted * 1e-3, setup * 1e-3);
    printf("| n | collisions/cycle model / paper | communication ms model / paper "
           "| m = 4 ms model / paper | m = 8 ms model / paper "
           "| comm. share m = 4 %% model / paper | comm. share m = 8 %% model / paper |\n"
           "|---:|---:|---:|---:|---:|---:|---:|\n");
    double comm[PAPER_ROWS], total[PAPER_ROWS][2];
    for (int row = 0; row < PAPER_ROWS; row++) {
        const paper_result *p = &res[row];
        const paper_row *t = &table2[row];
        comm[row] = p->fixed_ns + p->transfers * fitted;
        for (int k = 0; k < 2; k++)
            total[row][k] = p->chip_ns[k] + comm[row];
        printf("| %u | %.2f / %.2f | %.3f / %.3f | %.3f / %.3f | %.3f / %.3f | %.1f / %.1f "
               "| %.1f / %.1f |\n",
               t->n, p->collisions, t->collisions, comm[row] * 1e-6, t->comm_ms,
               total[row][0] * 1e-6, t->fpga_ms[0], total[row][1] * 1e-6, t->fpga_ms[1],
               100 * comm[row] / total[row][0], t->share[0], 100 * comm[row] / total[row][1],
               t->share[1]);
    }

    printf("\nThe chip's part: the model's clocks per cycle (update + compare + emit) at %.1f "
           "MHz, next to the paper's FPGA time less its communication time.\n\n",
           o->config.clock_hz * 1e-6);
    printf("| n | m = 4 clocks | m = 4 chip ms model / paper | paper / model "
           "| m = 8 clocks | m = 8 chip ms model / paper | paper / model |\n"
           "|---:|---:|---:|---:|---:|---:|---:|\n");
    double x[2][PAPER_ROWS], y[2][PAPER_ROWS];
    for (int row = 0; row < PAPER_ROWS; row++) {
        printf("| %u |", table2[row].n);
        for (int k = 0; k < 2; k++) {
            double paper_chip = (table2[row].fpga_ms[k] - table2[row].comm_ms) * 1e6;
            x[k][row] = res[row].chip_clocks[k];
            y[k][row] = paper_chip;
            printf(" %.0f | %.4f / %.4f | %.2f |", res[row].chip_clocks[k],
                   res[row].chip_ns[k] * 1e-6, paper_chip * 1e-6, paper_chip / res[row].chip_ns[k]);
        }
        printf("\n");
    }

    // What else would have to differ: the link's bandwidth (a two-parameter fit of the
    // communication column), and the chip's time per clock (a line through the chip column).
    double s11 = 0, s12 = 0, s22 = 0, t1 = 0, t2 = 0;
    for (int row = 0; row < PAPER_ROWS; row++) {
        double k = res[row].transfers, bytes = res[row].bytes;
        double target = table2[row].comm_ms * 1e6 - res[row].registers_ns;
        s11 += k * k;
        s12 += k * bytes;
        s22 += bytes * bytes;
        t1 += k * target;
        t2 += bytes * target;
    }
    double det = s11 * s22 - s12 * s12;
    double setup2 = det != 0 ? (t1 * s22 - t2 * s12) / det : 0;
    double per_byte = det != 0 ? (s11 * t2 - s12 * t1) / det : 0;
    printf("\nWith the bandwidth free too, the communication column fits %.1f us per transfer "
           "and %.1f MB/s (configured %.1f MB/s).\n",
           setup2 * 1e-3, per_byte > 0 ? 1e3 / per_byte : 0, o->config.link.bytes_per_s * 1e-6);
    for (int k = 0; k < 2; k++) {
        double a, b;
        fit_line(x[k], y[k], PAPER_ROWS, &a, &b);
        printf("m = %d: the paper's chip time fits %.1f us + %.2f ns x model clocks (%.1f MHz "
               "effective; the model: %.2f ns per clock at %.1f MHz).\n",
               paper_m[k], a * 1e-3, b, b > 0 ? 1e3 / b : 0, 1e9 / o->config.clock_hz,
               o->config.clock_hz * 1e-6);
    }
    printf("pairs: %s the brute backend's on every measured cycle\n",
           mismatches ? "DIFFERENT FROM" : "identical to");
    return mismatches ? CLI_EXIT_ERROR : CLI_EXIT_OK;
}
