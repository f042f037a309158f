// bpx: broad-phase collision detection. SPDX-License-Identifier: MIT
//
// Queries on a world: which boxes overlap a region or a sphere, what a ray hits, what a box
// moving along a segment hits. They see the world's current boxes (everything set, added,
// moved or removed up to the call; removed ids are never returned) and honour filters.
//
// The first query after the boxes changed brings the world's tree up to date: a refit when the
// same objects only moved, a rebuild (Morton order, O(n)) when objects came or went or the
// refitted tree got loose. A world that is never queried never builds one.
//
// Exact definitions. Every query has one result, defined below, computed the same way by every
// build, SIMD width and thread count; the tree only skips boxes that cannot be in it.
//   box region     box b is a hit iff the closed intervals overlap on all three axes (the
//                  predicate of the pairs: touching boxes are hits)
//   sphere         b is a hit iff d2 <= radius * radius, in double precision, where
//                  d2 = sum over axes of g*g, g = max(b.min - c, c - b.max, 0) per axis
//   oriented box   the box {centre + R u : |u_k| <= half_k}, R = rotation (row-major 3x3,
//                  orthonormal: its columns are the box's axes); b is a hit iff none of the 15
//                  axes of the separating-axis test (x, y, z, R's columns, and the 9 cross
//                  products of one with the other) separates them, in double precision, where
//                  an axis separates when |T . L| > r_b + r_q strictly (closed boxes: touching
//                  is a hit), T the difference of the centres, r the half-widths' projections
//                  (b's centre (min + max) / 2 and half-size (max - min) / 2 in double)
//   ray / sweep    a sweep moves box q along t * translation, t in [0, max_fraction]; a ray is
//                  the sweep of the point box [origin, origin]. Per axis, with d the
//                  translation's component (+0.0 and -0.0 are both zero):
//                    d == 0: the axis admits every t iff b.min <= q.max and b.max >= q.min,
//                            else no t;
//                    d != 0: it admits t between t1 = (b.min - q.max) * inv and
//                            t2 = (b.max - q.min) * inv (either order), inv = 1.0 / d,
//                            each step in double precision.
//                  enter = the largest lower end over the axes, exit = the smallest upper end;
//                  b is hit iff max(enter, 0) <= min(exit, max_fraction), at fraction
//                  max(enter, 0) rounded to float. A query that starts overlapping b hits it
//                  at fraction 0. Closest: the hit with the least fraction, ties to the lowest
//                  id. All: every hit, sorted by fraction then id.
// Results of region and sphere queries are sorted by id (fraction 0).
// Any (query.any, every kind): at most one hit, the first the walk of the tree meets: some hit
// when there is one (a line of sight is blocked), not the closest. Which one depends on the
// tree, so it is the same for the same boxes and the same calls, whatever the thread count.
//
// Threads. bpx_world_query and bpx_world_query_batch bring the tree up to date and keep their
// results in the world: one thread at a time, like every call that takes a bpx_world *. After
// bpx_world_prepare_queries, bpx_world_query_shared and bpx_world_query_each read the world
// only (const): any number of threads may run them at once, as long as no call changes the
// world meanwhile (set, add, move, remove, filters, collide, bpx_world_query...).
//
// Bad queries are refused, naming the query (its position in a batch) and the axis:
// NOT_FINITE (a NaN or infinite coordinate, centre, radius, origin, direction or translation;
// NaN max_fraction), MIN_GREATER_THAN_MAX (a query box), INVALID_ARGUMENT (negative radius or
// max_fraction; a zero translation with max_fraction > 0; an unknown kind; negative half
// extents; a rotation that is not orthonormal to 1e-3). max_fraction may be
// +infinity (an unbounded ray). Denormal components are ordinary non-zero values.
#pragma once

#include "types.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct bpx_world bpx_world;

/// Which boxes a query sees: box b is seen iff (category & mask_b) && (category_b & mask),
/// the same rule as between two boxes. bpx_default_query_filter() sees every box whose mask
/// is not zero.
typedef struct bpx_query_filter {
    uint32_t category;
    uint32_t mask;
} bpx_query_filter;

typedef enum bpx_query_kind {
    BPX_QUERY_BOX = 0, ///< boxes overlapping query.box
    BPX_QUERY_SPHERE,  ///< boxes overlapping the sphere (centre, radius)
    BPX_QUERY_RAY,     ///< boxes hit by the ray origin + t * direction, t in [0, max_fraction]
    BPX_QUERY_SWEEP,   ///< boxes hit by box moving by t * direction, t in [0, max_fraction]
    BPX_QUERY_ORIENTED, ///< boxes overlapping a rotated box (centre, half_extents, rotation)
    BPX_QUERY_KIND_COUNT
} bpx_query_kind;

/// One query. Fill kind and the fields it reads; bpx_query_box() and friends do that.
typedef struct bpx_query {
    bpx_query_kind kind;
    /// RAY and SWEEP: true for the closest hit only, false for every hit.
    bool closest;
    /// Every kind: stop at the first hit found (at most one; see "Any" above). Not with closest.
    bool any;
    bpx_query_filter filter;
    bpx_box box;         ///< BOX: the region; SWEEP: the moving box at t = 0
    float centre[3];     ///< SPHERE, ORIENTED
    float radius;        ///< SPHERE
    float half_extents[3]; ///< ORIENTED: half the box's size along each of its axes (>= 0)
    float rotation[9];   ///< ORIENTED: row-major, orthonormal (to 1e-3): world = centre + R u
    float origin[3];     ///< RAY
    float direction[3];  ///< RAY: direction; SWEEP: translation. Need not be unit length: a
                         ///< unit direction makes fractions distances
    float max_fraction;  ///< RAY, SWEEP: the largest t (1 with a segment's vector; +inf allowed)
} bpx_query;

/// One hit: the box's id and, for rays and sweeps, the fraction t of the first contact.
typedef struct bpx_hit {
    uint32_t id;
    float fraction;
} bpx_hit;

/// Filter that sees every box (category and mask all ones).
BPX_API bpx_query_filter bpx_default_query_filter(void);
/// Queries with the default filter.
BPX_API bpx_query bpx_query_box(bpx_box box);
BPX_API bpx_query bpx_query_sphere(const float centre[3], float radius);
BPX_API bpx_query bpx_query_ray(const float origin[3], const float direction[3],
                                float max_fraction, bool closest);
BPX_API bpx_query bpx_query_sweep(bpx_box box, const float translation[3], float max_fraction,
                                  bool closest);
/// A point: the boxes that contain it (a box query of the point, closed intervals).
BPX_API bpx_query bpx_query_point(const float point[3]);
/// A rotated box: centre, half extents along its own axes, rotation (row-major 3x3).
BPX_API bpx_query bpx_query_oriented(const float centre[3], const float half_extents[3],
                                     const float rotation[9]);

/// Runs one query on the calling thread. *count receives the number of hits. If it exceeds
/// capacity, returns CAPACITY and writes nothing to hits; the hits are still readable with
/// bpx_world_query_hits() without running the query again. hits may be NULL with capacity 0.
/// Errors: NULL_ARGUMENT, BAD_STATE (the boxes live on a device: from
/// bpx_opencl_set_boxes_buffer, bpx_opencl_set_centres_buffer or bpx_cuda_set_boxes_device until
/// the next bpx_world_set_boxes, load_extents or update_centres, whose host boxes queries then
/// see), OUT_OF_MEMORY, and the query errors above. On error nothing is written.
BPX_API bpx_status bpx_world_query(bpx_world *world, const bpx_query *query, bpx_hit *hits,
                                   size_t capacity, size_t *count);

/// Runs count queries on the world's workers. Results in CSR form: the hits of query k are
/// hits[offsets[k] .. offsets[k+1]), offsets has count + 1 entries, *total = offsets[count].
/// The same bytes for any worker count. On CAPACITY (total > capacity) offsets and *total are
/// written, hits is not, and bpx_world_query_hits() reads them all. Errors as bpx_world_query,
/// naming the first bad query by its index.
BPX_API bpx_status bpx_world_query_batch(bpx_world *world, const bpx_query *queries,
                                         uint32_t count, size_t *offsets, bpx_hit *hits,
                                         size_t capacity, size_t *total);

/// The hits of the last successful bpx_world_query / bpx_world_query_batch (including one that
/// returned CAPACITY), owned by the world and valid until the next call that changes it or
/// queries it. offsets (may be NULL) receives the CSR offsets (query_count + 1 entries).
BPX_API const bpx_hit *bpx_world_query_hits(const bpx_world *world, const size_t **offsets,
                                            uint32_t *query_count, size_t *total);

/// Brings the query tree up to date with the boxes (a refit or a rebuild, as the first query
/// after a change would), so that bpx_world_query_shared and bpx_world_query_each may run.
/// Errors: NULL_ARGUMENT, BAD_STATE (boxes on a device, as bpx_world_query), OUT_OF_MEMORY.
BPX_API bpx_status bpx_world_prepare_queries(bpx_world *world);

/// One query on a prepared world, reading it only: safe from many threads at once (see Threads
/// above). Results as bpx_world_query. If *count exceeds capacity, returns CAPACITY and writes
/// nothing useful to hits: call again with room for *count. Allocates nothing.
/// Errors: NULL_ARGUMENT, BAD_STATE (the boxes changed since bpx_world_prepare_queries, or it was
/// never called), the query errors above; the detail goes to err (may be NULL), never to the
/// world's bpx_world_error.
BPX_API bpx_status bpx_world_query_shared(const bpx_world *world, const bpx_query *query,
                                          bpx_hit *hits, size_t capacity, size_t *count,
                                          bpx_error *err);

/// Called by bpx_world_query_each for each hit, with the box's user data
/// (bpx_world_set_user_data). Its return steers the walk (Box2D's convention):
///   < 0 (or NaN)  ignore this hit and go on;
///   0             stop: no more hits;
///   > 0           go on; for a ray or sweep, also end the cast at min(this, its current end):
///                 hits entering later are skipped (return hit->fraction to look for closer
///                 ones only, +INFINITY to go on unchanged).
/// It must not change the world: such a call returns BAD_STATE.
typedef float bpx_query_hit_fn(const bpx_hit *hit, uint64_t user_data, void *context);

/// Runs one query on a prepared world, calling fn for each hit in the order the walk of the tree
/// meets them (not sorted: the same order for the same boxes and calls). closest and any must
/// be false: the callback decides. Reads the world only, like bpx_world_query_shared.
/// Errors: NULL_ARGUMENT, BAD_STATE (not prepared; see query_shared), INVALID_ARGUMENT (closest
/// or any set), the query errors above; detail in err (may be NULL).
BPX_API bpx_status bpx_world_query_each(const bpx_world *world, const bpx_query *query,
                                        bpx_query_hit_fn *fn, void *context, bpx_error *err);

/// The tree's state, for benchmarks and tests: builds from scratch, refits, nodes, and the
/// nanoseconds of the last build or refit.
typedef struct bpx_query_stats {
    uint64_t builds;
    uint64_t refits;
    uint32_t nodes;
    uint32_t boxes;
    uint64_t last_update_ns;
} bpx_query_stats;
BPX_API bpx_query_stats bpx_world_query_stats(const bpx_world *world);

#ifdef __cplusplus
}
#endif
