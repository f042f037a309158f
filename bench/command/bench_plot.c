// bpx bench: the plot, time per cycle against n on log-log axes, written as SVG by hand (a few
// dozen elements; no plotting dependency for one picture). Peers are dashed, bpx solid.
// SPDX-License-Identifier: MIT
#include <math.h>
#include <stdio.h>

#include "bench.h"

enum { WIDTH = 860, HEIGHT = 520, LEFT = 70, RIGHT = 230, TOP = 40, BOTTOM = 50 };

static const char *const palette[] = {
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b",
    "#e377c2", "#17becf", "#bcbd22", "#7f7f7f", "#393b79", "#637939",
};

static double map(double v, double lo, double hi, double out_lo, double out_hi)
{
    return out_lo + (log10(v) - lo) / (hi - lo) * (out_hi - out_lo);
}

int bench_plot_svg(const char *path, const char *title, const uint32_t *sizes, int size_count,
                   const bench_series *series, int series_count)
{
    double y_lo = INFINITY, y_hi = -INFINITY;
    for (int s = 0; s < series_count; s++)
        for (int k = 0; k < size_count; k++)
            if (isfinite(series[s].us[k]) && series[s].us[k] > 0) {
                y_lo = fmin(y_lo, floor(log10(series[s].us[k])));
                y_hi = fmax(y_hi, ceil(log10(series[s].us[k])));
            }
    if (!isfinite(y_lo) || size_count < 1)
        y_lo = 0, y_hi = 1;
    if (y_hi <= y_lo)
        y_hi = y_lo + 1;
    double x_lo = floor(log10(sizes[0] > 0 ? sizes[0] : 1));
    double x_hi = ceil(log10(sizes[size_count - 1] > 0 ? sizes[size_count - 1] : 10));
    if (x_hi <= x_lo)
        x_hi = x_lo + 1;
    const double px0 = LEFT, px1 = WIDTH - RIGHT, py0 = HEIGHT - BOTTOM, py1 = TOP;

    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    fprintf(f,
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%d\" height=\"%d\" "
            "font-family=\"sans-serif\" font-size=\"12\">\n"
            "<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n"
            "<text x=\"%d\" y=\"24\" font-size=\"15\">%s</text>\n",
            WIDTH, HEIGHT, LEFT, title);
    // Decade grid and labels.
    for (double e = y_lo; e <= y_hi + 1e-9; e++) {
        double y = map(pow(10, e), y_lo, y_hi, py0, py1);
        fprintf(f,
                "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"#ddd\"/>\n"
                "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"end\">%g</text>\n",
                px0, y, px1, y, px0 - 6, y + 4, pow(10, e));
    }
    for (double e = x_lo; e <= x_hi + 1e-9; e++) {
        double x = map(pow(10, e), x_lo, x_hi, px0, px1);
        fprintf(f,
                "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"#ddd\"/>\n"
                "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"middle\">%g</text>\n",
                x, py0, x, py1, x, py0 + 18, pow(10, e));
    }
    fprintf(f,
            "<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"none\" "
            "stroke=\"#444\"/>\n"
            "<text x=\"%.1f\" y=\"%d\" text-anchor=\"middle\">boxes n</text>\n"
            "<text transform=\"translate(18,%.1f) rotate(-90)\" text-anchor=\"middle\">"
            "mean us per cycle</text>\n",
            px0, py1, px1 - px0, py0 - py1, (px0 + px1) / 2, HEIGHT - 12, (py0 + py1) / 2);

    for (int s = 0; s < series_count; s++) {
        const char *colour = palette[s % (int)(sizeof palette / sizeof palette[0])];
        const char *dash = series[s].peer ? " stroke-dasharray=\"6 4\"" : "";
        fprintf(f, "<polyline fill=\"none\" stroke=\"%s\" stroke-width=\"2\"%s points=\"", colour,
                dash);
        for (int k = 0; k < size_count; k++)
            if (isfinite(series[s].us[k]) && series[s].us[k] > 0)
                fprintf(f, "%.1f,%.1f ", map(sizes[k], x_lo, x_hi, px0, px1),
                        map(series[s].us[k], y_lo, y_hi, py0, py1));
        fprintf(f, "\"/>\n");
        for (int k = 0; k < size_count; k++)
            if (isfinite(series[s].us[k]) && series[s].us[k] > 0)
                fprintf(f, "<circle cx=\"%.1f\" cy=\"%.1f\" r=\"3\" fill=\"%s\"/>\n",
                        map(sizes[k], x_lo, x_hi, px0, px1),
                        map(series[s].us[k], y_lo, y_hi, py0, py1), colour);
        double ly = TOP + 10 + 18.0 * s;
        fprintf(f,
                "<line x1=\"%d\" y1=\"%.1f\" x2=\"%d\" y2=\"%.1f\" stroke=\"%s\" "
                "stroke-width=\"2\"%s/>\n<text x=\"%d\" y=\"%.1f\">%s</text>\n",
                WIDTH - RIGHT + 15, ly, WIDTH - RIGHT + 45, ly, colour, dash, WIDTH - RIGHT + 52,
                ly + 4, series[s].name);
    }
    fprintf(f, "</svg>\n");
    return fclose(f) == 0 ? 0 : -1;
}
