// bpx: broad-phase collision detection. SPDX-License-Identifier: MIT
//
// Pairs for scientific codes: periodic boundaries, pairs within a distance, float64 input
// answered exactly. One call finds, for boxes or points, every pair whose distance is within a
// cutoff, over every periodic image, with the image's integer shift:
//
//   bpx_neighbor_def def = bpx_default_neighbor_def();
//   def.format = BPX_POINTS_F64;
//   def.period[0] = def.period[1] = def.period[2] = 10.0; // a periodic cubic cell
//   def.cutoff = 1.2;
//   def.metric = BPX_METRIC_EUCLIDEAN;
//   def.want_distances = true;
//   bpx_neighbor_list list;
//   if (bpx_find_neighbors(&def, xyz, n, &list, &err) == BPX_OK) { ... }
//   bpx_neighbor_list_free(&list);
//
// How: points with the auto backend go to a cell list (cells as wide as the cutoff, each point
// against the points of the 27 cells around it, in cell order, on the workers). Everything else
// (boxes, another backend, a periodic axis shorter than 3 cutoffs) goes through a backend: the
// objects are wrapped into the cell, grown by cutoff / 2 and rounded outward to float32 (so no
// pair is ever missed), objects that reach past the cell's upper faces get images below its
// lower faces, and the backend finds the candidate pairs among them; each candidate is kept once
// (the image pair whose shifts are 0 or less, with one of them 0 on every periodic axis). Both
// decide each pair on the input coordinates in double, the same way (docs/neighbors.md).
// Points in a triclinic cell (bpx_neighbor_def.cell) take a cell list of their own, binned in
// fractional coordinates of the cell reduced to near-cubes (docs/neighbors.md, "Triclinic cells").
#pragma once

#include "types.h"

#ifdef __cplusplus
extern "C" {
#endif

/// A box in double precision, (min x, min y, min z, max x, max y, max z) in memory. Closed, like
/// bpx_box; valid when finite with min <= max per axis.
typedef struct bpx_box64 {
    double min[3];
    double max[3];
} bpx_box64;

/// What the array given to bpx_find_neighbors holds, for n objects.
typedef enum bpx_input_format {
    BPX_BOXES_F32 = 0, ///< n bpx_box
    BPX_BOXES_F64,     ///< n bpx_box64
    BPX_POINTS_F32,    ///< 3n floats, x y z per point (a point is a box with min == max)
    BPX_POINTS_F64,    ///< 3n doubles
} bpx_input_format;

/// How the distance between two boxes is measured. With g_a = the gap between their intervals
/// on axis a (max(b.min - a.max, a.min - b.max); negative when they overlap on that axis):
typedef enum bpx_metric {
    /// max over the axes of g_a: a pair is reported when the boxes grown by cutoff / 2 on every
    /// side overlap (cutoff 0: Algorithm 1's closed-interval test). Decided exactly, as real
    /// numbers, on the input coordinates: no rounding can add or drop a pair.
    BPX_METRIC_BOX = 0,
    /// sqrt(sum over the axes of max(g_a, 0)^2): the Euclidean distance between the boxes, for
    /// points the distance between them. Evaluated in double (as every neighbour-list library
    /// does), so a pair at the cutoff to within double rounding may fall either way.
    BPX_METRIC_EUCLIDEAN,
} bpx_metric;

/// How bpx_find_neighbors searches. Get one from bpx_default_neighbor_def().
typedef struct bpx_neighbor_def {
    bpx_input_format format; ///< default BPX_BOXES_F32
    /// Period per axis: > 0 makes the axis periodic with that period (an orthorhombic cell; its
    /// origin does not matter: objects need not be inside it, and the shifts are relative to
    /// the coordinates as given); 0 leaves the axis open. Default 0, 0, 0.
    double period[3];
    /// Pairs whose distance is <= cutoff are reported; finite, >= 0. Default 0.
    double cutoff;
    bpx_metric metric; ///< default BPX_METRIC_BOX
    /// Fill bpx_neighbor_list.distances (the metric's distance of each pair). Default false.
    bool want_distances;
    /// Comparator for the candidates (default BPX_BACKEND_AUTO: the cell list for points, the
    /// auto backend for boxes) and the threads of either search (as bpx_world_def.worker_count;
    /// the output does not depend on it).
    bpx_backend backend;
    int worker_count;
    /// A triclinic cell, for points: its lattice vectors as rows, a = cell[0], b = cell[1],
    /// c = cell[2] (ASE's convention). All zero (the default): no triclinic cell, period[]
    /// decides. When any entry is non-zero: period must be 0, 0, 0, the format
    /// BPX_POINTS_F32 or BPX_POINTS_F64 and the metric BPX_METRIC_EUCLIDEAN; the cell must be
    /// finite, every entry below 2^960 in magnitude, not singular (condition number up to
    /// 2^24); either handedness. Each axis (fractional coordinate along a, b, c) is periodic
    /// unless cell_open says otherwise; an open axis still needs its vector (any vector that
    /// keeps the cell non-singular; it sets no period). The pair (i, j, shift) then stands for
    /// the vector x_j + shift[0] a + shift[1] b + shift[2] c - x_i; its length is the distance.
    /// Searched by a cell list in fractional coordinates whatever `backend` says (the backend
    /// is not used); worker_count as above. docs/neighbors.md, "Triclinic cells".
    double cell[3][3];
    bool cell_open[3]; ///< per lattice vector: not periodic (with a triclinic cell). Default false
} bpx_neighbor_def;

/// One pair: box i and the image of box j shifted by shift[a] * period[a] on each axis (shift 0
/// on open axes); with a triclinic cell, point i and point j moved by shift[0] a + shift[1] b +
/// shift[2] c (ASE's S: vector = x_j - x_i + shift . cell). Reported with i < j, or i == j (a
/// box and its own image, when a box and the cutoff span a period) with the shift's first
/// non-zero component positive; (j, i, -shift) is
/// the same pair and is not reported again. A pair of boxes that meet in several images is
/// reported once per image.
typedef struct bpx_image_pair {
    uint32_t i;
    uint32_t j;
    int32_t shift[3];
} bpx_image_pair;

/// The result: pairs sorted by (i, j, shift), the same bytes for every backend and thread count.
typedef struct bpx_neighbor_list {
    size_t count;
    bpx_image_pair *pairs;
    double *distances; ///< count values when def.want_distances, else NULL
    size_t capacity;   ///< what the arrays were allocated for (bpx_neighbor_list_free reads it)
} bpx_neighbor_list;

BPX_API bpx_neighbor_def bpx_default_neighbor_def(void);

/// Every pair of the n objects in data (laid out as def->format says) within def->cutoff, over
/// every periodic image. On success *list owns its arrays (free them with
/// bpx_neighbor_list_free); on error it is empty and err (may be NULL) names what and where.
/// Errors: NULL_ARGUMENT; INVALID_ARGUMENT (a period or the cutoff NaN, infinite or negative, an
/// unknown format or metric, a worker count out of range; a triclinic cell that is not finite,
/// singular or nearly so, or given with boxes, the box metric or a period); NOT_FINITE /
/// MIN_GREATER_THAN_MAX naming the object; TOO_MANY_BOXES (n, or the objects with their
/// images, past BPX_MAX_BOXES; an object more than 2^29 periods from the origin, or spanning that many; with
/// a triclinic cell, a point more than 2^29 cells from the origin, or a cutoff that reaches more
/// than 2^20 face distances or 2^24 images of the cell's bins);
/// OUT_OF_MEMORY; BACKEND_UNAVAILABLE; TOO_MANY_PAIRS as the backend reports it.
BPX_API bpx_status bpx_find_neighbors(const bpx_neighbor_def *def, const void *data, uint32_t n,
                                      bpx_neighbor_list *list, bpx_error *err);

/// Frees the list's arrays and empties it. NULL and an empty list are allowed.
BPX_API void bpx_neighbor_list_free(bpx_neighbor_list *list);

/// bpx_find_pairs for float64 boxes, exact: the pairs whose boxes overlap as real numbers
/// (closed intervals), where rounding them to float32 would pair boxes 1 ulp apart. Same
/// contract as bpx_find_pairs (CAPACITY when count > capacity).
BPX_API bpx_status bpx_find_pairs_f64(const bpx_box64 *boxes, uint32_t n, bpx_backend backend,
                                      bpx_pair *out, size_t capacity, size_t *count,
                                      bpx_error *err);

#ifdef __cplusplus
}
#endif
