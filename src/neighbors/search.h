// What the two searches of bpx_find_neighbors share: the objects read as double boxes, the
// search's state, and the decision on a pair.
#pragma once

#include "bpx/bpx.h"

#include <math.h>

#include "../core/periodic.h" // bpx__soa_boxes
#include "exact.h"

// ---------------------------------------------------------------------------------------------
// The objects, as double boxes whatever the input format

typedef struct source {
    const void *data;
    bpx_input_format format;
    bpx__soa_boxes soa; // BPX__BOXES_SOA
} source;

static inline void object_box(const source *in, uint32_t k, double lo[3], double hi[3])
{
    if (in->format == BPX__BOXES_SOA) {
        for (int a = 0; a < 3; a++) {
            lo[a] = in->soa.lo[a][k];
            hi[a] = in->soa.hi[a][k];
        }
        return;
    }
    switch (in->format) {
    case BPX_BOXES_F32: {
        const bpx_box *b = (const bpx_box *)in->data + k;
        for (int a = 0; a < 3; a++) {
            lo[a] = b->min[a];
            hi[a] = b->max[a];
        }
        return;
    }
    case BPX_BOXES_F64: {
        const bpx_box64 *b = (const bpx_box64 *)in->data + k;
        for (int a = 0; a < 3; a++) {
            lo[a] = b->min[a];
            hi[a] = b->max[a];
        }
        return;
    }
    case BPX_POINTS_F32: {
        const float *p = (const float *)in->data + 3 * (size_t)k;
        for (int a = 0; a < 3; a++)
            lo[a] = hi[a] = p[a];
        return;
    }
    default: {
        const double *p = (const double *)in->data + 3 * (size_t)k;
        for (int a = 0; a < 3; a++)
            lo[a] = hi[a] = p[a];
        return;
    }
    }
}

// ---------------------------------------------------------------------------------------------
// The search's state

typedef struct search {
    const bpx_neighbor_def *def;
    source in;
    uint32_t n;
    double period[3];  // 0 on open axes
    bool periodic;     // any axis
    int32_t (*wrap)[3]; // per object: w (0 on open axes); NULL when nothing is periodic
    // A periodic world's arrays, kept between its cycles (wrap among them), or NULL: the search
    // allocates its own and frees them.
    bpx__search_keep *keep;
    uint32_t ghost_count;
    uint32_t *ghost_owner;    // per image past n: its object
    int32_t (*ghost_shift)[3]; // per image past n: u (<= 0)
    bpx_box *images;          // n + ghost_count float32 boxes, rounded outward
    bpx_error *err;
} search;

// Whether box i and box j shifted by shift periods are within the cutoff, decided on the input
// coordinates; *distance receives the metric's distance. Both searches decide here, so that
// they give the same bits.
// Whether sqrt(g[0]^2 + g[1]^2 + g[2]^2) <= c for gaps g >= 0, and that distance, in double.
// Where the squares could underflow to 0 or overflow, the gaps and c are first scaled by a power
// of two (exact); in between, nothing is scaled, so the bits are those of the plain sums.
static inline bool bpx__euclidean_within(const double g[3], double c, double *distance)
{
    double largest = g[0] > g[1] ? g[0] : g[1];
    largest = g[2] > largest ? g[2] : largest;
    if (largest > c)
        return false;
    if (largest == 0 || (largest > 0x1p-450 && largest < 0x1p450)) {
        double squares = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
        if (!(squares <= c * c))
            return false;
        *distance = sqrt(squares);
        return true;
    }
    int e = ilogb(largest);
    double x = ldexp(g[0], -e), y = ldexp(g[1], -e), z = ldexp(g[2], -e), r = ldexp(c, -e);
    double squares = x * x + y * y + z * z; // largest is in [1, 2) now
    if (!(squares <= r * r))
        return false;
    *distance = ldexp(sqrt(squares), e);
    return true;
}

// Whether box i and box j shifted by shift periods are within the cutoff, decided on the input
// coordinates; *distance receives the metric's distance. Both searches decide here (or, for
// points, in the same arithmetic), so that they give the same bits.
static inline bool bpx__within(const search *s, const double lo_i[3], const double hi_i[3],
                               const double lo_j[3], const double hi_j[3],
                               const int32_t shift[3], double *distance)
{
    double c = s->def->cutoff;
    double gap_max = -INFINITY, gaps[3];
    for (int a = 0; a < 3; a++) {
        // The shift in two parts, p_hi + p_lo == shift * L exactly.
        double p_hi = (double)shift[a] * s->period[a];
        double p_lo = fma((double)shift[a], s->period[a], -p_hi);
        if (s->def->metric == BPX_METRIC_BOX) {
            // j's image min - hi_i <= c and lo_i - j's image max <= c, as real numbers.
            double j_above[5] = {c, hi_i[a], -lo_j[a], -p_hi, -p_lo};
            double j_below[5] = {c, hi_j[a], p_hi, p_lo, -lo_i[a]};
            if (bpx__exact_sign(j_above, 5) < 0 || bpx__exact_sign(j_below, 5) < 0)
                return false;
        }
        double lo_image = lo_j[a] + p_hi, hi_image = hi_j[a] + p_hi;
        double above = lo_image - hi_i[a], below = lo_i[a] - hi_image;
        double gap = above > below ? above : below; // no NaN here: fmax's call is not needed
        gap_max = gap > gap_max ? gap : gap_max;
        gaps[a] = gap > 0 ? gap : 0;
    }
    if (s->def->metric == BPX_METRIC_EUCLIDEAN)
        return bpx__euclidean_within(gaps, c, distance);
    *distance = gap_max > 0 ? gap_max : 0;
    return true;
}

/// Grows the result's arrays to hold at least `needed` pairs; false when memory is short.
bool bpx__neighbors_reserve(bpx_neighbor_list *list, size_t needed, bool want_distances);

/// The cell-list search for points: every point's neighbours in (i, j) order, straight into
/// the list, no comparator. BPX_ERR_BAD_STATE (and nothing done) when the cell does not allow
/// it: a periodic axis shorter than 3 cells of the cutoff.
bpx_status bpx__neighbors_cells(const search *s, bpx_neighbor_list *list);

/// The cell-list search for points in a triclinic cell (def->cell; triclinic.c): its own checks
/// of the cell, the format, the metric and the points, then every pair in (i, j, shift) order.
bpx_status bpx__neighbors_triclinic(const bpx_neighbor_def *def, const void *data, uint32_t n,
                                    bpx_neighbor_list *list, bpx_error *err);
