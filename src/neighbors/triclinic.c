// Triclinic cells for the neighbour list of points (bpx_neighbor_def.cell): a cell list in
// fractional coordinates. The orthorhombic cell list (cells.c) is not touched by any of this.
//
// A point x has fractional coordinates s = x G, G = H^-1, H the cell with the lattice vectors
// as rows. On a periodic axis s_a is wrapped into [0, 1) (w_a = floor(s_a)) and binned into
// n_a bins; on an open axis the bins cover the points' range of s_a. Two points within the
// cutoff r differ in s_a by at most r |G column a| = r / d_a, d_a the distance between the
// cell's faces across a (volume / |b x c| for a). Bins are at least that wide (plus a slack for
// rounding) where the cell allows it, so each point's neighbours lie in the 27 bins around its
// own; where a face distance is shorter than the cutoff there is one bin on that axis and the
// search reaches R_a = ceil(r / d_a) bins (periods) each way. A visited bin b + delta is bin
// (b + delta) mod n_a of the cell moved by t_a = floor((b + delta) / n_a) periods: distinct
// deltas are distinct (bin, t), so no (i, j, shift) is found twice however thin the cell, and
// the shift is t + w_i - w_j (ASE's S: x_j + S H - x_i). Each candidate passes a quick test in
// double on wrapped Cartesian coordinates (the distance against the cutoff widened past every
// rounding, see plan) before the decision: |x_j + S H - x_i| <= r on the input coordinates in
// double, one fixed order of operations (triclinic_within), so any thread count, and the brute
// force in test/test_neighbors.c, give the same bits.
#include <float.h>
#include <stdlib.h>
#include <string.h>

#include "../core/alloc.h"
#include "../core/validate.h"
#include "../parallel/pool.h"
#include "search.h"

// Bins per axis at most (and in all at most about two per point, as in cells.c).
#define MAX_BINS_PER_AXIS (1 << 20)
// |s_a| on a periodic axis below this: wraps and shifts are int32 with room for their sums.
#define MAX_FRACTION 0x1p29
// Coordinates and the cutoff below this (as the orthorhombic search), cell entries below
// MAX_ENTRY and above its inverse: S H stays far from overflow with |S| < 2^31.
#define MAX_COORDINATE 0x1p1000
#define MAX_ENTRY 0x1p960
// Cells closer to singular than this are refused: ||H|| ||G|| (infinity norms) at most 2^24.
#define MAX_CONDITION 0x1p24
// The search reaches at most this many periods each way on an axis, and this many bins
// (with their images) around a bin in all.
#define MAX_REACH (1 << 20)
#define MAX_VISITS (1 << 24)

typedef struct tgrid {
    double H[3][3];  // the cell as given, rows a, b, c
    double R[3][3];  // the cell the bins are laid in: U H, reduced (reduce), rounded
    int32_t U[3][3]; // R's rows in H's: a shift S' in R is S' U in H
    bool reduced;    // U is not the identity
    double G[3][3];  // R^-1: s_a = x_0 G[0][a] + x_1 G[1][a] + x_2 G[2][a]
    bool periodic[3];
    int count[3];      // bins per axis
    int reach[3];      // bins searched each way (R_a)
    double origin[3];  // in s: the least on an open axis, 0 on a periodic one
    double inverse[3]; // bins per unit of s
    double cutoff;
    double reach2; // the quick test's bound on the squared distance, in double
} tgrid;

// One point in bin order: its coordinates as given, which it is, and its wrap.
typedef struct tslot {
    double x[3];
    uint32_t id;
    int32_t wrap[3];
} tslot;

typedef struct thit {
    uint32_t j;
    int32_t shift[3];
    double distance;
} thit;

// A run of consecutive slots (bins next to each other along a on one row, no face crossed),
// the periods t they are moved by, and t H.
typedef struct trun {
    uint32_t begin, end;
    int32_t t[3];
    double offset[3];
} trun;

typedef struct tsearch {
    const bpx_neighbor_def *def;
    const void *data;
    uint32_t n;
    bpx_error *err;
    tgrid g;
} tsearch;

static void point_of(const tsearch *s, uint32_t k, double x[3])
{
    if (s->def->format == BPX_POINTS_F64)
        memcpy(x, (const double *)s->data + 3 * (size_t)k, 3 * sizeof(double));
    else
        for (int a = 0; a < 3; a++)
            x[a] = ((const float *)s->data)[3 * (size_t)k + a];
}

static inline void fractional(const tgrid *g, const double x[3], double s[3])
{
    for (int a = 0; a < 3; a++)
        s[a] = x[0] * g->G[0][a] + x[1] * g->G[1][a] + x[2] * g->G[2][a];
}

// |x_j + S H - x_i| <= cutoff in double, the distance into *distance: the decision, one order
// of operations (S_0 a + S_1 b + S_2 c, then x_j +, then - x_i), the orthorhombic search's
// bits when the cell is diagonal (the zeros add nothing).
static inline bool triclinic_within(const tgrid *g, const double xi[3], const double xj[3],
                                    const int32_t S[3], double *distance)
{
    double gaps[3];
    for (int c = 0; c < 3; c++) {
        double p =
            (double)S[0] * g->H[0][c] + (double)S[1] * g->H[1][c] + (double)S[2] * g->H[2][c];
        double image = xj[c] + p;
        double gap = image - xi[c];
        gaps[c] = gap < 0 ? -gap : gap;
    }
    return bpx__euclidean_within(gaps, g->cutoff, distance);
}

static void cross(const double u[3], const double v[3], double out[3])
{
    out[0] = u[1] * v[2] - u[2] * v[1];
    out[1] = u[2] * v[0] - u[0] * v[2];
    out[2] = u[0] * v[1] - u[1] * v[0];
}

// M^-1 into G (G[c][a]: column a is (b x c) / det for a, etc.), computed on M scaled by a power
// of two (exact) so that the products neither overflow nor underflow. False when singular;
// *det is a . (b x c) of M scaled by 2^-*scale, *condition ||M|| ||M^-1|| (infinity norms),
// *residual max |M G - I| plus a bound on its own rounding.
static bool invert_cell(const double M[3][3], double G[3][3], double *det, int *scale,
                        double *condition, double *residual)
{
    double largest = 0;
    for (int a = 0; a < 3; a++)
        for (int c = 0; c < 3; c++)
            largest = fmax(largest, fabs(M[a][c]));
    int e = ilogb(largest);
    double Ms[3][3], cof[3][3];
    for (int a = 0; a < 3; a++)
        for (int c = 0; c < 3; c++)
            Ms[a][c] = ldexp(M[a][c], -e);
    cross(Ms[1], Ms[2], cof[0]); // b x c: G's column 0 times det
    cross(Ms[2], Ms[0], cof[1]);
    cross(Ms[0], Ms[1], cof[2]);
    *det = Ms[0][0] * cof[0][0] + Ms[0][1] * cof[0][1] + Ms[0][2] * cof[0][2];
    *scale = e;
    if (!(*det != 0) || !isfinite(*det))
        return false;
    double Gs[3][3], m_norm = 0, g_norm = 0;
    for (int c = 0; c < 3; c++)
        for (int a = 0; a < 3; a++)
            Gs[c][a] = cof[a][c] / *det;
    for (int r = 0; r < 3; r++) {
        double mr = 0, gr = 0;
        for (int c = 0; c < 3; c++) {
            mr += fabs(Ms[r][c]);
            gr += fabs(Gs[r][c]);
        }
        m_norm = fmax(m_norm, mr);
        g_norm = fmax(g_norm, gr);
    }
    *condition = m_norm * g_norm;
    double most = 0;
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            double p = Ms[a][0] * Gs[0][b] + Ms[a][1] * Gs[1][b] + Ms[a][2] * Gs[2][b];
            most = fmax(most, fabs(p - (a == b)));
        }
    *residual = most + *condition * 0x1p-50;
    for (int c = 0; c < 3; c++)
        for (int a = 0; a < 3; a++)
            G[c][a] = ldexp(Gs[c][a], -e);
    return true;
}

static double dot(const double u[3], const double v[3])
{
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
}

// The cell the bins are laid in: the periodic vectors reduced pairwise (Lagrange-Gauss: b minus
// the multiple of a that makes it shortest, while any gets shorter), R = U H with U integer and
// unimodular, rows of open axes left alone. A sheared cell's bins are then about cubes again;
// the lattice, and so the pairs, are the same. R is rounded; the search measures it against
// U H (reduce's *mismatch) and the decision uses H itself.
static void reduce(tgrid *g, double *mismatch)
{
    memcpy(g->R, g->H, sizeof g->R);
    memset(g->U, 0, sizeof g->U);
    for (int a = 0; a < 3; a++)
        g->U[a][a] = 1;
    for (int pass = 0; pass < 200; pass++) {
        bool changed = false;
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) {
                if (a == b || !g->periodic[a] || !g->periodic[b])
                    continue;
                double aa = dot(g->R[a], g->R[a]), k = round(dot(g->R[b], g->R[a]) / aa);
                if (k == 0 || !(fabs(k) < 0x1p20))
                    continue;
                double shorter[3];
                for (int c = 0; c < 3; c++)
                    shorter[c] = g->R[b][c] - k * g->R[a][c];
                int64_t u[3];
                bool fits = true;
                for (int c = 0; c < 3; c++) {
                    u[c] = g->U[b][c] - (int64_t)k * g->U[a][c];
                    fits &= u[c] > -(1 << 20) && u[c] < (1 << 20);
                }
                if (!fits || !(dot(shorter, shorter) < dot(g->R[b], g->R[b]) * (1 - 0x1p-20)))
                    continue;
                for (int c = 0; c < 3; c++) {
                    g->U[b][c] = (int32_t)u[c];
                    // from U and H, not the running R: one rounding per product and sum
                    g->R[b][c] = (double)u[0] * g->H[0][c] + (double)u[1] * g->H[1][c] +
                                 (double)u[2] * g->H[2][c];
                }
                changed = true;
            }
        if (!changed)
            break;
    }
    g->reduced = false;
    double most = 0;
    for (int a = 0; a < 3; a++)
        for (int c = 0; c < 3; c++) {
            g->reduced |= g->U[a][c] != (a == c);
            most = fmax(most, fabs((double)g->U[a][c]));
        }
    // |R - U H| per entry: two roundings of at most 2^-53 of 3 most |H| each
    double h_most = 0;
    for (int a = 0; a < 3; a++)
        for (int c = 0; c < 3; c++)
            h_most = fmax(h_most, fabs(g->H[a][c]));
    *mismatch = g->reduced ? 0x1p-50 * 3 * most * h_most : 0;
}

// The cell's checks, its reduced form and that form's inverse. *residual: max |(U H) G - I|,
// plus a bound on its own rounding.
static bpx_status check_cell(const tsearch *s, tgrid *g, double *residual)
{
    const bpx_neighbor_def *def = s->def;
    double largest = 0;
    for (int a = 0; a < 3; a++)
        for (int c = 0; c < 3; c++) {
            double v = def->cell[a][c];
            if (!(fabs(v) < MAX_ENTRY))
                return bpx__error(s->err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, a,
                                  "cell[%d][%d] = %g: a triclinic cell's entries must be finite "
                                  "and below 2^960 in magnitude",
                                  a, c, v);
            g->H[a][c] = v;
            largest = fmax(largest, fabs(v));
        }
    if (largest < 1 / MAX_ENTRY)
        return bpx__error(s->err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "the triclinic cell's largest entry, %g, is below 2^-960", largest);
    double det, condition;
    int scale;
    if (!invert_cell(g->H, g->G, &det, &scale, &condition, residual))
        return bpx__error(s->err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "the triclinic cell is singular: its lattice vectors a, b, c are "
                          "linearly dependent (a . (b x c) = %g)",
                          ldexp(det, 3 * scale));
    if (!(condition <= MAX_CONDITION))
        return bpx__error(s->err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "the triclinic cell is too close to singular: condition number %g "
                          "(||H|| ||H^-1||, infinity norm) is past 2^24; its face distances are "
                          "tiny against its vectors",
                          condition);
    double mismatch;
    reduce(g, &mismatch);
    if (!g->reduced)
        return BPX_OK;
    if (!invert_cell(g->R, g->G, &det, &scale, &condition, residual)) { // (cannot: U unimodular)
        memcpy(g->R, g->H, sizeof g->R);
        g->reduced = false;
        return invert_cell(g->H, g->G, &det, &scale, &condition, residual)
                   ? BPX_OK
                   : bpx__error(s->err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                                "the triclinic cell is singular");
    }
    // (U H) G - I = (R G - I) - (R - U H) G
    double g_norm = 0;
    for (int c = 0; c < 3; c++)
        g_norm = fmax(g_norm, fabs(g->G[c][0]) + fabs(g->G[c][1]) + fabs(g->G[c][2]));
    *residual += 3 * mismatch * g_norm;
    return BPX_OK;
}

// The checks of the points, and the bins. Every bound on rounding below is 2^6 or more times
// the error it covers (a few roundings of 2^-53 each, summed over the terms' magnitudes).
static bpx_status plan(tsearch *s)
{
    tgrid *g = &s->g;
    const bpx_neighbor_def *def = s->def;
    double residual = 0;
    for (int a = 0; a < 3; a++)
        g->periodic[a] = !def->cell_open[a];
    bpx_status status = check_cell(s, g, &residual);
    if (status != BPX_OK)
        return status;
    g->cutoff = def->cutoff;
    double least[3] = {INFINITY, INFINITY, INFINITY}, most[3] = {-INFINITY, -INFINITY, -INFINITY};
    double x_most = 0, s_most[3] = {0, 0, 0};
    for (uint32_t k = 0; k < s->n; k++) {
        double x[3], f[3];
        point_of(s, k, x);
        for (int c = 0; c < 3; c++) {
            if (!isfinite(x[c]))
                return bpx__error(s->err, BPX_ERR_NOT_FINITE, k, c,
                                  "point %u: its coordinate on axis %c is not finite", k, "xyz"[c]);
            if (!(fabs(x[c]) < MAX_COORDINATE))
                return bpx__error(s->err, BPX_ERR_INVALID_ARGUMENT, k, c,
                                  "point %u: its coordinate on axis %c is beyond +-2^1000", k,
                                  "xyz"[c]);
            x_most = fmax(x_most, fabs(x[c]));
        }
        fractional(g, x, f);
        for (int a = 0; a < 3; a++) {
            if (!(fabs(f[a]) < (g->periodic[a] ? MAX_FRACTION : INFINITY)))
                return bpx__error(s->err, BPX_ERR_TOO_MANY_BOXES, k, a,
                                  "point %u lies more than 2^29 cells from the origin along the "
                                  "lattice vector %c (fractional coordinate %g)",
                                  k, "abc"[a], f[a]);
            least[a] = fmin(least[a], f[a]);
            most[a] = fmax(most[a], f[a]);
            s_most[a] = fmax(s_most[a], fabs(f[a]));
        }
    }
    // |S'_b| bound over the pairs that can be decided (shifts in R): the wraps (|s| + 1 each)
    // and the periods searched (r / d_b + 2; the slack added below stays under 1/16). In H,
    // S = S' U: up to u_sum times that.
    double h_sum = 0, r_sum = 0, u_sum = 1, col[3], g_sum[3], periodic_most = 0, reach_most = 0;
    for (int c = 0; c < 3; c++) {
        h_sum = fmax(h_sum, fabs(g->H[0][c]) + fabs(g->H[1][c]) + fabs(g->H[2][c]));
        r_sum = fmax(r_sum, fabs(g->R[0][c]) + fabs(g->R[1][c]) + fabs(g->R[2][c]));
        u_sum = fmax(u_sum, fabs((double)g->U[0][c]) + fabs((double)g->U[1][c]) +
                                fabs((double)g->U[2][c]));
    }
    for (int a = 0; a < 3; a++) {
        col[a] = sqrt(g->G[0][a] * g->G[0][a] + g->G[1][a] * g->G[1][a] + g->G[2][a] * g->G[2][a]);
        g_sum[a] = fabs(g->G[0][a]) + fabs(g->G[1][a]) + fabs(g->G[2][a]);
        if (g->periodic[a]) {
            periodic_most = fmax(periodic_most, s_most[a]);
            reach_most = fmax(reach_most, g->cutoff * col[a]);
        }
    }
    if (!(reach_most < MAX_REACH))
        return bpx__error(s->err, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "the cutoff %g reaches past 2^20 of the cell's face distances",
                          g->cutoff);
    double shift_most = 2 * periodic_most + 4 + 2 * reach_most;
    if (!(shift_most * u_sum < 0x1p30))
        return bpx__error(s->err, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "the points lie too many cells from the origin for this sheared a cell "
                          "(shifts would pass 2^30)");
    // |x|, |S H| in the decision's sums
    double magnitude = x_most + h_sum * shift_most * u_sum + g->cutoff;
    double enough = 2.0 * s->n + 64, bins = 1, reach_fraction[3];
    for (int a = 0; a < 3; a++) {
        // The rounding of s (x G), of the image's s (s_j + S (H G) for s_j + S), of the
        // decision in Cartesian (a true distance past the cutoff decided within), in s.
        double slack = 0x1p-44 * (x_most * g_sum[a] + magnitude * col[a] + 1 + s_most[a]) +
                       16 * residual * shift_most;
        if (!(slack < 0x1p-4))
            return bpx__error(s->err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, a,
                              "the triclinic cell is too close to singular for points this far "
                              "from the origin (fractional coordinates up to %g): rounding "
                              "would blur the cell's bins",
                              periodic_most);
        double r = g->cutoff * col[a] * (1 + 0x1p-40) + slack;
        reach_fraction[a] = r;
        if (g->periodic[a]) {
            g->origin[a] = 0;
            g->count[a] = r >= 1 ? 1 : (int)fmin(floor(1 / r), MAX_BINS_PER_AXIS);
            g->inverse[a] = g->count[a];
        } else {
            double extent = most[a] - least[a];
            g->origin[a] = s->n ? least[a] : 0;
            g->inverse[a] = fmin(1 / r, (MAX_BINS_PER_AXIS - 1) / fmax(extent, DBL_MIN));
            g->count[a] = s->n ? (int)floor(extent * g->inverse[a]) + 1 : 1;
        }
        bins *= g->count[a];
    }
    // Too many bins for the points: halve the longest axis until there are not.
    while (bins > enough) {
        int a = 0;
        for (int b = 1; b < 3; b++)
            if (g->count[b] > g->count[a])
                a = b;
        int fewer = g->periodic[a] ? g->count[a] / 2
                                   : (int)floor((most[a] - least[a]) * g->inverse[a] / 2) + 1;
        if (fewer >= g->count[a] || fewer < 1)
            break;
        bins = bins / g->count[a] * fewer;
        g->count[a] = fewer;
        g->inverse[a] = g->periodic[a] ? fewer : g->inverse[a] / 2;
    }
    double visits = 1;
    int reach_bins = 0;
    for (int a = 0; a < 3; a++) {
        // Bins reached each way: the fraction reached times the bins per unit, less 2^-48 of
        // it (bins exactly 1 / r wide reach 1, not 2 by a rounding; the slack is far larger).
        double reach = ceil(reach_fraction[a] * g->inverse[a] * (1 - 0x1p-48));
        g->reach[a] = g->periodic[a] ? (int)fmax(reach, 1) : 1;
        reach_bins = g->reach[a] > reach_bins ? g->reach[a] : reach_bins;
        visits *= 2.0 * g->reach[a] + 1;
    }
    if (visits > MAX_VISITS)
        return bpx__error(s->err, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "the cutoff %g reaches %.0f bins and their images around each bin "
                          "(more than 2^24): the cell is far thinner than the cutoff",
                          g->cutoff, visits);
    // The quick test: wrapped coordinates (|x - w R| up to x_most + r_sum (|s| + 1)) plus t R
    // (|t| up to R + 1), against the decision's sums: both within 2^-50 of the magnitudes
    // (and R within 2^-50 of U H).
    double quick = x_most + r_sum * (2 * periodic_most + reach_bins + 4) + magnitude;
    double reach = g->cutoff + 0x1p-40 * (quick + g->cutoff);
    // (At least 2^-1000: squares that underflow pass, and the decision decides them.)
    g->reach2 = fmax(nextafter(reach * reach, INFINITY), 0x1p-1000);
    return BPX_OK;
}

// Point k's bin on each axis, its wrap, and its wrapped Cartesian coordinates.
static void locate(const tsearch *s, uint32_t k, int bin[3], double x[3], int32_t wrap[3],
                   double wrapped[3])
{
    const tgrid *g = &s->g;
    double f[3];
    point_of(s, k, x);
    fractional(g, x, f);
    for (int a = 0; a < 3; a++) {
        if (!g->periodic[a]) {
            wrap[a] = 0;
            int c = (int)floor((f[a] - g->origin[a]) * g->inverse[a]);
            bin[a] = c < 0 ? 0 : (c >= g->count[a] ? g->count[a] - 1 : c);
            continue;
        }
        double w = floor(f[a]);
        int c = (int)floor((f[a] - w) * g->inverse[a]);
        // f - w rounds up to 1 for an f just below an integer: the same point a period over.
        if (c >= g->count[a]) {
            c -= g->count[a];
            w += 1;
        } else if (c < 0) {
            c += g->count[a];
            w -= 1;
        }
        wrap[a] = (int32_t)w;
        bin[a] = c;
    }
    for (int c = 0; c < 3; c++)
        wrapped[c] = x[c] - ((double)wrap[0] * g->R[0][c] + (double)wrap[1] * g->R[1][c] +
                             (double)wrap[2] * g->R[2][c]);
}

static int floor_div(int v, int n)
{
    return v >= 0 ? v / n : -((-v + n - 1) / n);
}

// The most runs around a bin: each row (delta y, delta z) split where x crosses a face.
static size_t max_runs(const tgrid *g)
{
    size_t pieces = (size_t)(2 * g->reach[0] + 1) / (size_t)g->count[0] + 2;
    return (size_t)(2 * g->reach[1] + 1) * (size_t)(2 * g->reach[2] + 1) * pieces;
}

// The runs covering the bins within reach of bin (x, y, z) and their images, each once.
static size_t runs_around(const tgrid *g, const uint32_t *start, const int bin[3], trun *out)
{
    size_t count = 0;
    for (int dz = -g->reach[2]; dz <= g->reach[2]; dz++)
        for (int dy = -g->reach[1]; dy <= g->reach[1]; dy++) {
            int row[3] = {0, bin[1] + dy, bin[2] + dz};
            int32_t t[3] = {0, 0, 0};
            bool inside = true;
            for (int a = 1; a < 3; a++) {
                if (!g->periodic[a]) {
                    inside &= row[a] >= 0 && row[a] < g->count[a];
                    continue;
                }
                t[a] = floor_div(row[a], g->count[a]);
                row[a] -= t[a] * g->count[a];
            }
            if (!inside)
                continue;
            size_t row_start = ((size_t)row[2] * g->count[1] + row[1]) * g->count[0];
            int lo = bin[0] - g->reach[0], hi = bin[0] + g->reach[0];
            if (!g->periodic[0]) {
                lo = lo < 0 ? 0 : lo;
                hi = hi >= g->count[0] ? g->count[0] - 1 : hi;
            }
            for (int x = lo; x <= hi;) {
                // One piece: the bins of one period t_x, x .. last.
                int tx = g->periodic[0] ? floor_div(x, g->count[0]) : 0;
                int last = (tx + 1) * g->count[0] - 1;
                last = last < hi ? last : hi;
                int from = x - tx * g->count[0], to = last - tx * g->count[0];
                trun r = {start[row_start + from],
                          start[row_start + to + 1],
                          {tx, t[1], t[2]},
                          {0, 0, 0}};
                if (r.begin < r.end) {
                    for (int c = 0; c < 3; c++)
                        r.offset[c] = (double)r.t[0] * g->R[0][c] + (double)r.t[1] * g->R[1][c] +
                                      (double)r.t[2] * g->R[2][c];
                    out[count++] = r;
                }
                x = last + 1;
            }
        }
    return count;
}

// The points in bin order: wrapped Cartesian coordinates for the quick test (structure of
// arrays), the slots for the decision.
typedef struct tpoints {
    double *wrapped[3];
    tslot *slots;
} tpoints;

// A share's room for one point's hits, grown as needed.
typedef struct hit_room {
    thit *hits;
    uint64_t *keys;
    size_t capacity;
} hit_room;

static bool room_for(hit_room *h, size_t needed)
{
    if (needed <= h->capacity)
        return true;
    size_t grown = h->capacity ? 2 * h->capacity : 256;
    while (grown < needed)
        grown *= 2;
    thit *hits = bpx__alloc(grown * sizeof *hits);
    uint64_t *keys = bpx__alloc(grown * sizeof *keys);
    if (!hits || !keys) {
        bpx__free(hits, grown * sizeof *hits);
        bpx__free(keys, grown * sizeof *keys);
        return false;
    }
    if (h->capacity)
        memcpy(hits, h->hits, h->capacity * sizeof *hits);
    bpx__free(h->hits, h->capacity * sizeof *h->hits);
    bpx__free(h->keys, h->capacity * sizeof *h->keys);
    h->hits = hits;
    h->keys = keys;
    h->capacity = grown;
    return true;
}

// Whether S is "positive": its first non-zero component > 0 (a point and its own image).
static inline bool positive(const int32_t S[3])
{
    return S[0] ? S[0] > 0 : S[1] ? S[1] > 0 : S[2] > 0;
}

// Point m's (a slot) hits among the runs' points j >= i into h; their count, or SIZE_MAX when
// memory ran out.
static size_t search_point(const tsearch *s, const tpoints *p, uint32_t m, const trun *runs,
                           size_t run_count, double *near, uint32_t *passed, hit_room *h)
{
    const tgrid *g = &s->g;
    const tslot *i = &p->slots[m];
    const double *X = p->wrapped[0], *Y = p->wrapped[1], *Z = p->wrapped[2];
    double limit = g->reach2;
    size_t count = 0;
    for (size_t r = 0; r < run_count; r++) {
        double o[3];
        for (int c = 0; c < 3; c++)
            o[c] = runs[r].offset[c] - p->wrapped[c][m];
        uint32_t begin = runs[r].begin, length = runs[r].end - runs[r].begin;
        for (uint32_t q = 0; q < length; q++) {
            double dx = X[begin + q] + o[0], dy = Y[begin + q] + o[1], dz = Z[begin + q] + o[2];
            near[q] = dx * dx + dy * dy + dz * dz;
        }
        uint32_t passed_count = 0;
        for (uint32_t q = 0; q < length; q++) {
            bool pass = near[q] <= limit;
            passed[passed_count] = q;
            passed_count += pass;
        }
        if (!room_for(h, count + passed_count))
            return SIZE_MAX;
        for (uint32_t q = 0; q < passed_count; q++) {
            const tslot *j = &p->slots[begin + passed[q]];
            if (j->id < i->id)
                continue;
            thit hit = {.j = j->id};
            for (int a = 0; a < 3; a++)
                hit.shift[a] = runs[r].t[a] + i->wrap[a] - j->wrap[a];
            if (g->reduced) { // S = S' U: in the cell as given
                int32_t S[3];
                for (int b = 0; b < 3; b++)
                    S[b] = hit.shift[0] * g->U[0][b] + hit.shift[1] * g->U[1][b] +
                           hit.shift[2] * g->U[2][b];
                memcpy(hit.shift, S, sizeof S);
            }
            if (j->id == i->id && !positive(hit.shift))
                continue;
            if (triclinic_within(g, i->x, j->x, hit.shift, &hit.distance))
                h->hits[count++] = hit;
        }
    }
    return count;
}

static int compare_shift(const int32_t a[3], const int32_t b[3])
{
    for (int x = 0; x < 3; x++)
        if (a[x] != b[x])
            return a[x] < b[x] ? -1 : 1;
    return 0;
}

static int compare_hits(const void *pa, const void *pb)
{
    const thit *a = pa, *b = pb;
    if (a->j != b->j)
        return a->j < b->j ? -1 : 1;
    return compare_shift(a->shift, b->shift);
}

// Appends point i's hits, sorted by (j, shift), to the list.
static bool append(const tsearch *s, hit_room *h, size_t count, uint32_t i, bpx_neighbor_list *list)
{
    thit *hits = h->hits;
    uint64_t *keys = h->keys;
    if (count > 64) { // many images: a real sort
        qsort(hits, count, sizeof *hits, compare_hits);
        for (size_t a = 0; a < count; a++)
            keys[a] = a;
    } else {
        // (j, position) keys, insertion sort; then the images of one j by shift.
        for (size_t a = 0; a < count; a++) {
            uint64_t key = (uint64_t)hits[a].j << 32 | a;
            size_t b = a;
            for (; b > 0 && keys[b - 1] > key; b--)
                keys[b] = keys[b - 1];
            keys[b] = key;
        }
        for (size_t a = 1; a < count; a++) {
            uint64_t key = keys[a];
            const thit *x = &hits[(uint32_t)key];
            size_t b = a;
            for (; b > 0; b--) {
                const thit *y = &hits[(uint32_t)keys[b - 1]];
                if (y->j != x->j || compare_shift(y->shift, x->shift) <= 0)
                    break;
                keys[b] = keys[b - 1];
            }
            keys[b] = key;
        }
    }
    bool want = s->def->want_distances;
    if (!bpx__neighbors_reserve(list, list->count + count, want))
        return false;
    for (size_t a = 0; a < count; a++) {
        const thit *x = &hits[(uint32_t)keys[a]];
        bpx_image_pair *p = &list->pairs[list->count + a];
        p->i = i;
        p->j = x->j;
        memcpy(p->shift, x->shift, sizeof p->shift);
        if (want)
            list->distances[list->count + a] = x->distance;
    }
    list->count += count;
    return true;
}

typedef struct tshare {
    bpx_neighbor_list found;
    bpx_status status;
} tshare;

typedef struct tjob {
    const tsearch *s;
    const uint32_t *start;
    const tpoints *points;
    size_t run_capacity;   // runs around one bin
    size_t point_capacity; // most points in one row of bins
    double pairs_per_point;
    int share_count;
    tshare *shares;
    size_t *first;
    uint32_t *counts;
    uint16_t *owner;
} tjob;

static void search_share(int begin, int end, int worker, void *context)
{
    (void)worker;
    const tjob *job = context;
    const tsearch *s = job->s;
    const tgrid *g = &s->g;
    size_t rows = (size_t)g->count[1] * g->count[2];
    trun *runs = bpx__alloc(job->run_capacity * sizeof *runs);
    double *near = bpx__alloc(job->point_capacity * sizeof *near);
    uint32_t *passed = bpx__alloc(job->point_capacity * sizeof *passed);
    hit_room room = {0};
    for (int k = begin; k < end; k++) {
        tshare *sh = &job->shares[k];
        if (!runs || !near || !passed || !room_for(&room, 64)) {
            sh->status = BPX_ERR_OUT_OF_MEMORY;
            continue;
        }
        size_t row_begin = rows * (size_t)k / job->share_count;
        size_t row_end = rows * (size_t)(k + 1) / job->share_count;
        size_t points = job->start[row_end * g->count[0]] - job->start[row_begin * g->count[0]];
        double expected = points * job->pairs_per_point * 1.1 + 256;
        if (!bpx__neighbors_reserve(&sh->found, (size_t)fmin(expected, 1e9),
                                    s->def->want_distances)) {
            sh->status = BPX_ERR_OUT_OF_MEMORY;
            continue;
        }
        for (size_t row = row_begin; row < row_end; row++) {
            int bin[3] = {0, (int)(row % g->count[1]), (int)(row / g->count[1])};
            for (bin[0] = 0; bin[0] < g->count[0]; bin[0]++) {
                size_t index = row * g->count[0] + bin[0];
                if (job->start[index] == job->start[index + 1])
                    continue;
                size_t run_count = runs_around(g, job->start, bin, runs);
                for (uint32_t m = job->start[index]; m < job->start[index + 1]; m++) {
                    size_t count =
                        search_point(s, job->points, m, runs, run_count, near, passed, &room);
                    uint32_t id = job->points->slots[m].id;
                    if (count == SIZE_MAX) {
                        sh->status = BPX_ERR_OUT_OF_MEMORY;
                        goto next_share;
                    }
                    job->first[id] = sh->found.count;
                    job->counts[id] = (uint32_t)count;
                    job->owner[id] = (uint16_t)k;
                    if (!append(s, &room, count, id, &sh->found)) {
                        sh->status = BPX_ERR_OUT_OF_MEMORY;
                        goto next_share;
                    }
                }
            }
        }
    next_share:;
    }
    bpx__free(runs, job->run_capacity * sizeof *runs);
    bpx__free(near, job->point_capacity * sizeof *near);
    bpx__free(passed, job->point_capacity * sizeof *passed);
    bpx__free(room.hits, room.capacity * sizeof *room.hits);
    bpx__free(room.keys, room.capacity * sizeof *room.keys);
}

static bpx_status no_memory(const tsearch *s)
{
    return bpx__error(s->err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                      "no memory for the bins of %u points", s->n);
}

bpx_status bpx__neighbors_triclinic(const bpx_neighbor_def *def, const void *data, uint32_t n,
                                    bpx_neighbor_list *list, bpx_error *err)
{
    if ((def->format != BPX_POINTS_F32 && def->format != BPX_POINTS_F64) ||
        def->metric != BPX_METRIC_EUCLIDEAN)
        return bpx__error(err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "a triclinic cell takes points (BPX_POINTS_F32 or _F64) and the "
                          "Euclidean metric; format %d, metric %d given",
                          (int)def->format, (int)def->metric);
    for (int a = 0; a < 3; a++)
        if (def->period[a] != 0)
            return bpx__error(err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, a,
                              "period[%d] = %g with a triclinic cell: give one or the other "
                              "(the cell's open axes are cell_open)",
                              a, def->period[a]);
    tsearch s = {.def = def, .data = data, .n = n, .err = err};
    bpx_status status = plan(&s);
    if (status != BPX_OK || n == 0)
        return status;
    const tgrid *g = &s.g;
    size_t bins = (size_t)g->count[0] * g->count[1] * g->count[2];
    size_t rows = (size_t)g->count[1] * g->count[2];
    int workers = def->worker_count > 1 ? def->worker_count : 1;
    int share_count = workers == 1 ? 1 : (int)(rows < 8u * workers ? rows : 8u * workers);
    uint32_t *start = bpx__alloc((bins + 1) * sizeof *start);
    uint32_t *home = bpx__alloc((size_t)n * sizeof *home);
    tslot *slots = bpx__alloc((size_t)n * sizeof *slots);
    double *wrapped = bpx__alloc(3 * (size_t)n * sizeof *wrapped);
    size_t *first = bpx__alloc((size_t)n * sizeof *first);
    uint32_t *counts = bpx__alloc((size_t)n * sizeof *counts);
    uint16_t *owner = bpx__alloc((size_t)n * sizeof *owner);
    tshare *shares = bpx__alloc((size_t)share_count * sizeof *shares);
    bpx_pool *pool = NULL;
    if (shares)
        memset(shares, 0, (size_t)share_count * sizeof *shares);
    if (!start || !home || !slots || !wrapped || !first || !counts || !owner || !shares) {
        status = no_memory(&s);
        goto done;
    }
    memset(start, 0, (bins + 1) * sizeof *start);
    for (uint32_t k = 0; k < n; k++) {
        int bin[3];
        double x[3], w[3];
        int32_t wrap[3];
        locate(&s, k, bin, x, wrap, w);
        home[k] = (uint32_t)(((size_t)bin[2] * g->count[1] + bin[1]) * g->count[0] + bin[0]);
        start[home[k] + 1]++;
    }
    for (size_t c = 0; c < bins; c++)
        start[c + 1] += start[c];
    size_t row_most = 0;
    for (size_t r = 0; r < rows; r++) {
        size_t in_row = start[(r + 1) * g->count[0]] - start[r * g->count[0]];
        row_most = in_row > row_most ? in_row : row_most;
    }
    tpoints points = {{wrapped, wrapped + n, wrapped + 2 * (size_t)n}, slots};
    for (uint32_t k = 0; k < n; k++) {
        int bin[3];
        double w[3];
        uint32_t at = start[home[k]]++;
        tslot *to = &slots[at];
        locate(&s, k, bin, to->x, to->wrap, w);
        to->id = k;
        for (int c = 0; c < 3; c++)
            points.wrapped[c][at] = w[c];
    }
    for (size_t c = bins; c > 0; c--)
        start[c] = start[c - 1];
    start[0] = 0;
    // Pairs per point were the points uniform over the cell (its volume, open axes over the
    // points' range), at most 64: the lists' first size.
    double volume = fabs(g->H[0][0] * (g->H[1][1] * g->H[2][2] - g->H[1][2] * g->H[2][1]) -
                         g->H[0][1] * (g->H[1][0] * g->H[2][2] - g->H[1][2] * g->H[2][0]) +
                         g->H[0][2] * (g->H[1][0] * g->H[2][1] - g->H[1][1] * g->H[2][0]));
    for (int a = 0; a < 3; a++)
        if (!g->periodic[a])
            volume *= g->count[a] / g->inverse[a];
    double c3 = def->cutoff * def->cutoff * def->cutoff;
    double per_point = 0.5 * n * 4.18879 * c3 / fmax(volume, DBL_MIN);
    tjob job = {&s,
                start,
                &points,
                max_runs(g),
                row_most ? row_most : 1,
                per_point < 64 ? per_point : 64,
                share_count,
                shares,
                first,
                counts,
                owner};
    bpx_executor executor = {.worker_count = 1};
    if (workers > 1) {
        if (!(pool = bpx__pool_create(workers - 1, -1))) {
            status = bpx__error(err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                                "no memory or threads for %d workers", workers);
            goto done;
        }
        executor = (bpx_executor){.pool = pool, .worker_count = workers};
    }
    bpx__parallel_for(&executor, search_share, share_count, &job);
    for (int k = 0; k < share_count; k++)
        if (shares[k].status != BPX_OK) {
            status = no_memory(&s);
            goto done;
        }
    size_t total = 0;
    for (int k = 0; k < share_count; k++)
        total += shares[k].found.count;
    bool want = def->want_distances;
    if (total && !bpx__neighbors_reserve(list, total, want)) {
        status = no_memory(&s);
        goto done;
    }
    for (uint32_t i = 0; i < n; i++) {
        if (counts[i] == 0)
            continue;
        const bpx_neighbor_list *from = &shares[owner[i]].found;
        memcpy(list->pairs + list->count, from->pairs + first[i], counts[i] * sizeof *list->pairs);
        if (want)
            memcpy(list->distances + list->count, from->distances + first[i],
                   counts[i] * sizeof *list->distances);
        list->count += counts[i];
    }
done:
    bpx__pool_destroy(pool);
    bpx__free(start, (bins + 1) * sizeof *start);
    bpx__free(home, (size_t)n * sizeof *home);
    bpx__free(slots, (size_t)n * sizeof *slots);
    bpx__free(wrapped, 3 * (size_t)n * sizeof *wrapped);
    bpx__free(first, (size_t)n * sizeof *first);
    bpx__free(counts, (size_t)n * sizeof *counts);
    bpx__free(owner, (size_t)n * sizeof *owner);
    if (shares)
        for (int k = 0; k < share_count; k++)
            bpx_neighbor_list_free(&shares[k].found);
    bpx__free(shares, (size_t)share_count * sizeof *shares);
    if (status != BPX_OK)
        bpx_neighbor_list_free(list);
    return status;
}
