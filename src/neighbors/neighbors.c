// Periodic images, cutoffs and float64 input on top of any backend (include/bpx/neighbors.h).
//
// Every object is grown by cutoff / 2 and wrapped, per periodic axis, by w periods so that its
// lower face lies in [0, L). Its images are the copies shifted by u periods, u = 0, -1, -2, ...
// while the copy still reaches 0 (u = 0 only, for all but the objects that cross an upper face).
// The comparator finds the overlapping image pairs on float32 boxes rounded outward. An image
// pair (a, b) with shifts (u_a, u_b) stands for the pair of objects at relative shift
// u_b - u_a; of all the image pairs that stand for the same one, exactly one has
// max(u_a, u_b) == 0 on every periodic axis, and only that one is kept. That image pair exists
// whenever the objects truly overlap: with the lower one's image at 0, the other's face is
// within [0, L) and the first reaches it. Each kept pair is then decided on the input
// coordinates (exact_sign), so the float32 pass only ever proposes.
#if defined(__linux__)
#define _DEFAULT_SOURCE // madvise
#include <sys/mman.h>
#endif

#include "bpx/bpx.h"
#include "bpx/neighbors.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../core/alloc.h"
#include "../core/periodic.h"
#include "../core/validate.h"
#include "search.h"

// Past this, an object is too far from the origin, or too large, counted in periods: shifts are
// int32 and the sum of a wrap and an image shift must fit.
#define MAX_PERIODS (1 << 29)
// Coordinates, periods and the cutoff stay below this so that exact sums cannot overflow.
#define MAX_MAGNITUDE 0x1p1000

// Big arrays in 2 MiB pages where the OS has them on request (Linux's transparent huge pages in
// "madvise" mode, as src/query/bvh.c): the images, the wraps and the result are written once,
// fresh, and their page faults were a tenth of a search.
static void advise_huge(void *memory, size_t size)
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    const uintptr_t huge = (uintptr_t)2 << 20;
    uintptr_t begin = ((uintptr_t)memory + huge - 1) & ~(huge - 1);
    uintptr_t end = ((uintptr_t)memory + size) & ~(huge - 1);
    if (memory && end > begin)
        (void)madvise((void *)begin, end - begin, MADV_HUGEPAGE); // a hint: failure is fine
#else
    (void)memory;
    (void)size;
#endif
}

// Room for count items of size bytes in a kept array (*memory, of *capacity items), grown by a
// quarter more than asked so that counts that wander a little from cycle to cycle do not
// reallocate; its contents are not kept. NULL when out of memory (the old array stays).
static void *room(void *memory, size_t *capacity, size_t count, size_t size)
{
    void **kept = (void **)memory;
    if (*kept && count <= *capacity)
        return *kept;
    size_t want = count + count / 4 + 64;
    void *grown = bpx__alloc(want * size);
    if (!grown)
        return NULL;
    bpx__free(*kept, *capacity * size);
    *kept = grown;
    *capacity = want;
    return grown;
}

// Appends item (size bytes) at count in a kept array of *capacity items, doubling it when full.
static bool push_kept(void *memory, size_t *capacity, size_t count, const void *item, size_t size)
{
    if (count >= *capacity) {
        size_t grown = *capacity ? 2 * *capacity : 1024;
        if (!bpx__grow((void **)memory, *capacity * size, grown * size))
            return false;
        *capacity = grown;
    }
    memcpy((char *)*(void **)memory + count * size, item, size);
    return true;
}

bpx_neighbor_def bpx_default_neighbor_def(void)
{
    return (bpx_neighbor_def){.format = BPX_BOXES_F32, .metric = BPX_METRIC_BOX,
                              .backend = BPX_BACKEND_AUTO, .worker_count = 1};
}

void bpx_neighbor_list_free(bpx_neighbor_list *list)
{
    if (!list)
        return;
    bpx__free(list->pairs, list->capacity * sizeof *list->pairs);
    if (list->distances)
        bpx__free(list->distances, list->capacity * sizeof *list->distances);
    *list = (bpx_neighbor_list){0};
}

// floor(x), inline: without SSE4.1 floor is a call into libm, a third of the checks' time.
static inline double floor_fast(double x)
{
    if (!(fabs(x) < 0x1p52))
        return floor(x);
    double t = (double)(int64_t)x; // truncated toward 0, exact
    return t > x ? t - 1 : t;
}

// The float after / before f (f not NaN), as nextafterf(f, +-INFINITY) without the call.
// Selects, no branches: which way a coordinate rounds is a coin toss, and mispredicting it was
// most of the time of the images of float64 boxes.
static inline float float_up(float f)
{
    uint32_t b;
    memcpy(&b, &f, sizeof b);
    b = f < 0 ? b - 1 : (b & 0x7FFFFFFFu) + 1; // -0 and +0 both to the least subnormal
    memcpy(&f, &b, sizeof f);
    return f;
}

static inline float float_down(float f)
{
    uint32_t b;
    memcpy(&b, &f, sizeof b);
    b = f > 0 ? b - 1 : (b | 0x80000000u) + 1; // -0 and +0 both to minus the least subnormal
    memcpy(&f, &b, sizeof f);
    return f;
}

static inline float round_down(double x)
{
    float f = (float)x, d = float_down(f);
    f = (double)f > x ? d : f;
    f = f < -FLT_MAX ? -FLT_MAX : f;
    return f > FLT_MAX ? FLT_MAX : f;
}

static inline float round_up(double x)
{
    float f = (float)x, u = float_up(f);
    f = (double)f < x ? u : f;
    f = f < -FLT_MAX ? -FLT_MAX : f;
    return f > FLT_MAX ? FLT_MAX : f;
}

static bpx_status check_def(const bpx_neighbor_def *def, bool world, bpx_error *err)
{
    if ((unsigned)def->format > BPX_POINTS_F64 && !(world && def->format == BPX__BOXES_SOA))
        return bpx__error(err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "format %d is not a bpx_input_format", (int)def->format);
    if ((unsigned)def->metric > BPX_METRIC_EUCLIDEAN)
        return bpx__error(err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "metric %d is not a bpx_metric", (int)def->metric);
    if ((unsigned)def->backend >= BPX_BACKEND_COUNT)
        return bpx__error(err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "backend %d is not a bpx_backend", (int)def->backend);
    if (def->worker_count < 0 || def->worker_count > 256)
        return bpx__error(err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "worker_count %d is outside 0..256", def->worker_count);
    for (int a = 0; a < 3; a++) {
        double p = def->period[a];
        if (!(p >= 0 && p < MAX_MAGNITUDE))
            return bpx__error(err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, a,
                              "period[%d] = %g: a period must be finite and >= 0 (0: open)", a, p);
    }
    if (!(def->cutoff >= 0 && def->cutoff < MAX_MAGNITUDE))
        return bpx__error(err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "cutoff = %g: it must be finite and >= 0", def->cutoff);
    return BPX_OK;
}

// How many images below itself an object [lo, hi] wrapped by w periods gets on axis a: the
// copies shifted down by 1, 2, ... periods that still reach the cell's lower face o once grown by
// cutoff / 2. The slack only adds images, which the exact test then drops, and covers the
// rounding of the wrap: this object's, and its partner's, which can leave the partner's lower
// face a few ulps of its own magnitude below o (hence `magnitude`: the largest of all the
// objects' coordinates, from cell_origin).
static double images_below(const search *s, int a, double lo, double hi, double w, double o,
                           double magnitude)
{
    double L = s->period[a], half = s->def->cutoff / 2;
    double grown_lo = lo - half, grown_hi = hi + half;
    double slack =
        0x1p-40 * (fabs(grown_lo) + fabs(grown_hi) + fabs(w * L) + L + fabs(o) + magnitude);
    double q = grown_hi - o - w * L + slack;
    // q < L: q / L < 1 even rounded (L / L is 1, and the largest double below 1 is 1 - 2^-53,
    // no further from 1 than q / L): no image, and no division for the most of the objects.
    return q >= L ? floor_fast(q / L) : 0;
}

// What the image search keeps beside `search` (search.h, shared with the cell list).
typedef struct image_state {
    // Per object: whether its own image (u = 0) is its box exactly (no cutoff, no wrap,
    // float32 coordinates), so that a candidate of two such images is a pair as it stands:
    // the comparator's closed-interval test on them is the exact test, shift 0, distance 0.
    // NULL when no image can be exact (a cutoff) or when all are (all_exact).
    uint8_t *exact;
    bool all_exact;
    // The comparator's input: n boxes for the objects (their images, or the objects themselves),
    // then, from the objects themselves, `moved` images moved onto objects moved_ids, then the
    // ghosts (ghost_boxes; after the n boxes in s->images when those are images).
    const bpx_box *boxes;
    uint32_t moved;
    uint32_t *moved_ids;
    const bpx_box *moved_boxes, *ghost_boxes;
    size_t image_count;   // boxes allocated in s->images
    double origin[3];     // the cell's lower corner (cell_origin; 0 where the cell list may run)
    double magnitude;     // the largest |coordinate| + cutoff / 2 + |origin| (cell_origin)
    // With `mark` (periodic float32 boxes without cutoff, whose images are their boxes but for
    // the marked), check_objects lists the objects that wrap or have ghosts, in order: the
    // image pass then visits those alone.
    bool mark;
    uint32_t *marked;
    uint32_t marked_count, marked_capacity;
    uint32_t past_limit; // the object at which the images pass BPX_MAX_BOXES, or UINT32_MAX
    // wrap, exact and marked are s->keep's, kept clean (bpx__search_keep.clean): 0 and 1 at
    // every object that is not marked, so that the many in the cell are never written.
    bool sparse;
    uint32_t ghosts_made; // the sparse path's ghosts so far (scan_cell makes them)
} image_state;

// The cell's lower corner for the image search: the lowest object's grown lower face on each
// periodic axis, so that objects in one cell's span need no wrap (their own images are then their
// boxes, and exact). Where the cell lies is the search's own choice: it decides which objects
// wrap and which get images, never a pair or its shift. Non-finite and huge coordinates are left
// to check_objects (0 when no object has a usable one).
static void cell_origin(const search *s, double origin[3], double *magnitude)
{
    double half = s->def->cutoff / 2, lowest[3] = {INFINITY, INFINITY, INFINITY}, most = 0;
    for (uint32_t k = 0; k < s->n; k++) {
        double lo[3], hi[3];
        object_box(&s->in, k, lo, hi);
        for (int a = 0; a < 3; a++) {
            double x = lo[a] - half;
            bool usable = fabs(lo[a]) < MAX_MAGNITUDE && fabs(hi[a]) < MAX_MAGNITUDE;
            lowest[a] = usable && x < lowest[a] ? x : lowest[a];
            most = usable && fabs(lo[a]) > most ? fabs(lo[a]) : most;
            most = usable && fabs(hi[a]) > most ? fabs(hi[a]) : most;
        }
    }
    double farthest_origin = 0;
    for (int a = 0; a < 3; a++) {
        origin[a] = s->period[a] > 0 && lowest[a] < INFINITY ? lowest[a] : 0;
        farthest_origin = fmax(farthest_origin, fabs(origin[a]));
    }
    *magnitude = most + half + farthest_origin;
}

static bool mark(image_state *im, uint32_t k)
{
    if (im->marked_count == im->marked_capacity) {
        uint32_t grown = im->marked_capacity ? 2 * im->marked_capacity : 1024;
        if (!bpx__grow((void **)&im->marked, im->marked_capacity * sizeof *im->marked,
                       grown * sizeof *im->marked))
            return false;
        im->marked_capacity = grown;
    }
    im->marked[im->marked_count++] = k;
    return true;
}

// The bounds of check_objects' fast test, "in the cell on axis a": w = 0 and no image there.
typedef struct inside_test {
    double inside_slack[3], near_limit[3];
} inside_test;

static inside_test make_inside_test(const search *s, const image_state *im)
{
    inside_test in;
    for (int a = 0; a < 3; a++) {
        in.inside_slack[a] = 0x1p-39 * (4 * im->magnitude + s->period[a]);
        in.near_limit[a] = 0x1p28 * s->period[a];
    }
    return in;
}

// Object k's wrap and image count (check_objects, on a periodic search): into s->wrap[k] (and
// im->marked when it wraps or has ghosts), its ghosts added to *total.
static bpx_status wrap_object(search *s, image_state *im, uint32_t k, const double lo[3],
                              const double hi[3], const inside_test *in, uint64_t *total,
                              int32_t wk[3])
{
    const double *origin = im->origin;
    double half = s->def->cutoff / 2;
    uint64_t images = 1;
    wk[0] = wk[1] = wk[2] = 0;
    for (int a = 0; a < 3; a++) {
        double L = s->period[a];
        if (L == 0)
            continue;
        double grown_lo = lo[a] - half, from_origin = grown_lo - origin[a];
        if (from_origin >= 0 && from_origin < L && fabs(grown_lo) < in->near_limit[a] &&
            (hi[a] + half - origin[a]) + in->inside_slack[a] < L)
            continue; // w = 0, one copy
        // Within 2^29 periods of 0 (and of the cell, so that shifts fit): counted from 0,
        // wherever the cell lies, so that the limit is the caller's to know.
        double from_zero = lo[a] - half;
        bool near = fabs(from_zero) < 0x1p28 * L ||
                    fabs(floor_fast(from_zero / L)) < MAX_PERIODS;
        double x = from_zero - origin[a]; // w = 0 within the cell without a division
        double w = x >= 0 && x < L ? 0 : floor_fast(x / L);
        double below = images_below(s, a, lo[a], hi[a], w, origin[a], im->magnitude);
        if (!(near && fabs(w) < MAX_PERIODS && below < MAX_PERIODS))
            return bpx__error(s->err, BPX_ERR_TOO_MANY_BOXES, k, a,
                              "object %u lies or reaches more than 2^29 periods (%g) from "
                              "the origin on axis %c",
                              k, L, "xyz"[a]);
        wk[a] = (int32_t)w;
        uint64_t copies = 1 + (uint64_t)(below > 0 ? below : 0);
        if (copies > BPX_MAX_BOXES / images) // before the product can wrap around
            return bpx__error(s->err, BPX_ERR_TOO_MANY_BOXES, k, a,
                              "object %u has more than BPX_MAX_BOXES (%u) periodic images: "
                              "the cell is small for boxes and cutoff this large",
                              k, BPX_MAX_BOXES);
        images *= copies;
    }
    *total += images - 1;
    // Sparse: s->wrap[k] is 0 already; written only when it wraps (a line of 12 MB at 1M
    // objects, a cache miss each, was a quarter of scan_cell's time written for every marked).
    if (!im->sparse || (wk[0] | wk[1] | wk[2]))
        memcpy(s->wrap[k], wk, sizeof s->wrap[k]);
    if (im->mark && (images > 1 || wk[0] | wk[1] | wk[2]) && !mark(im, k))
        return bpx__error(s->err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %u objects", s->n);
    // The images' limit is the image search's: the cell list makes no images, so it is
    // checked only where the image search runs (too_many_images).
    if (*total + s->n > BPX_MAX_BOXES && im->past_limit == UINT32_MAX)
        im->past_limit = k;
    return BPX_OK;
}

// The input checks, then each object's wrap (relative to the cell's lower corner, im->origin)
// and image count. Fills s->wrap (and im->marked); returns the number of ghost images in *ghosts.
static bpx_status check_objects(search *s, image_state *im, uint64_t *ghosts)
{
    uint64_t total = 0;
    // A box in the cell on an axis (lower face in [o, o + L), upper face below o + L by more
    // than images_below's slack, at most 2^-40 (4 magnitude + L) for w = 0; twice that covers
    // its rounding) has w = 0 and no image there: decided without images_below's divisions.
    // A world's own float32 boxes were checked as they came in (finite, min <= max, far below
    // 2^1000): not again.
    bool trusted = s->in.format == BPX__BOXES_SOA;
    inside_test inside = make_inside_test(s, im);
    for (uint32_t k = 0; k < s->n; k++) {
        double lo[3], hi[3];
        object_box(&s->in, k, lo, hi);
        for (int a = 0; a < 3 && !trusted; a++) {
            if (!isfinite(lo[a]) || !isfinite(hi[a]))
                return bpx__error(s->err, BPX_ERR_NOT_FINITE, k, a,
                                  "object %u: a coordinate on axis %c is not finite", k, "xyz"[a]);
            if (!(fabs(lo[a]) < MAX_MAGNITUDE && fabs(hi[a]) < MAX_MAGNITUDE))
                return bpx__error(s->err, BPX_ERR_INVALID_ARGUMENT, k, a,
                                  "object %u: a coordinate on axis %c is beyond +-2^1000", k,
                                  "xyz"[a]);
        }
        for (int a = 0; a < 3 && !trusted; a++)
            if (lo[a] > hi[a])
                return bpx__error(s->err, BPX_ERR_MIN_GREATER_THAN_MAX, k, a,
                                  "object %u: min %g > max %g on axis %c", k, lo[a], hi[a],
                                  "xyz"[a]);
        if (!s->periodic)
            continue;
        int32_t wk[3];
        bpx_status status = wrap_object(s, im, k, lo, hi, &inside, &total, wk);
        if (status != BPX_OK)
            return status;
    }
    *ghosts = total;
    return BPX_OK;
}

static bpx_box image_box_of(const search *s, uint32_t k, const int32_t u[3], const int32_t w[3]);

// The sparse path's make_images for object k of wrap wk, just marked: its moved image and its
// ghosts into s->keep's arrays, while its box is in cache (a second pass over the marked,
// scattered over the arrays, waited on memory for most of its time). Ghosts in make_images'
// order.
static bpx_status images_of(search *s, image_state *im, uint32_t k, const int32_t wk[3])
{
    static const int32_t zero[3] = {0, 0, 0};
    bpx__search_keep *kept = s->keep;
    bool moves = wk[0] | wk[1] | wk[2];
    if (moves) { // (exact[k] is 1 already for the others)
        kept->exact[k] = 0;
        bpx_box b = image_box_of(s, k, zero, wk);
        if (!push_kept(&kept->moved_ids, &kept->moved_capacity, im->moved, &k, sizeof k) ||
            !push_kept(&kept->moved_boxes, &kept->moved_box_capacity, im->moved, &b, sizeof b))
            return bpx__error(s->err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                              "no memory for %u objects", s->n);
        im->moved++;
    }
    double lo[3], hi[3];
    object_box(&s->in, k, lo, hi);
    int32_t lowest[3] = {0, 0, 0};
    for (int a = 0; a < 3; a++) {
        if (s->period[a] == 0)
            continue;
        double below = images_below(s, a, lo[a], hi[a], wk[a], im->origin[a], im->magnitude);
        lowest[a] = below > 0 ? -(int32_t)below : 0;
    }
    int32_t u[3];
    for (u[0] = 0; u[0] >= lowest[0]; u[0]--)
        for (u[1] = 0; u[1] >= lowest[1]; u[1]--)
            for (u[2] = 0; u[2] >= lowest[2]; u[2]--) {
                if (!u[0] && !u[1] && !u[2])
                    continue;
                uint32_t g = im->ghosts_made;
                bpx_box b = image_box_of(s, k, u, wk);
                if (!push_kept(&kept->images, &kept->image_capacity, g, &b, sizeof b) ||
                    !push_kept(&kept->ghost_owner, &kept->ghost_owner_capacity, g, &k,
                               sizeof k) ||
                    !push_kept(&kept->ghost_shift, &kept->ghost_shift_capacity, g, u,
                               sizeof *kept->ghost_shift))
                    return bpx__error(s->err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                                      "no memory for the periodic images");
                im->ghosts_made++;
            }
    return BPX_OK;
}

// Four floats, and their lanes' masks (GCC and Clang vector extensions: SSE2 on x86-64, NEON
// on arm64, scalar code elsewhere).
typedef float f4 __attribute__((vector_size(16)));
typedef int32_t i4 __attribute__((vector_size(16)));

static inline f4 load4(const float *p)
{
    f4 v;
    memcpy(&v, p, sizeof v);
    return v;
}

static inline f4 pick4(i4 mask, f4 yes, f4 no)
{
    return (f4)(((i4)yes & mask) | ((i4)no & ~mask));
}

static inline f4 abs4(f4 v)
{
    return (f4)((i4)v & 0x7fffffff);
}

// check_objects and cell_origin for a periodic world's own float32 boxes without cutoff (the
// sparse path), the same wraps, images and marks in a fraction of the time: the origin and
// magnitude from the bounds set_boxes found (or a float pass over the arrays: a float's min and
// largest |x| are the double's, so the cell is cell_origin's), then a float test, four boxes at
// a time, that a box is in the cell on every periodic axis (it implies wrap_object's inside
// test, with room for that test's rounding); wrap_object decides the few others. The inside
// boxes' wraps are 0 already (s->keep is clean). *stale: the bounds given were not the boxes'
// (checked in the same pass), and nothing found is to be used.
static bpx_status scan_cell(search *s, image_state *im, uint64_t *ghosts, bool *stale)
{
    const bpx__soa_boxes *b = &s->in.soa;
    uint32_t n = s->n, n4 = n & ~3u;
    float most = 0;
    double farthest = 0;
    for (int a = 0; a < 3; a++) {
        const float *lo = b->lo[a], *hi = b->hi[a];
        f4 low4 = {INFINITY, INFINITY, INFINITY, INFINITY}, big4 = {0, 0, 0, 0};
        for (uint32_t k = 0; k < n4 && !b->low; k += 4) {
            f4 l = load4(lo + k), x = abs4(l), y = abs4(load4(hi + k));
            low4 = pick4(l < low4, l, low4);
            big4 = pick4(x > big4, x, big4);
            big4 = pick4(y > big4, y, big4);
        }
        float low = INFINITY, big = 0;
        for (int q = 0; q < 4; q++) {
            low = low4[q] < low ? low4[q] : low;
            big = big4[q] > big ? big4[q] : big;
        }
        for (uint32_t k = n4; k < n && !b->low; k++) {
            float x = fabsf(lo[k]), y = fabsf(hi[k]);
            low = lo[k] < low ? lo[k] : low;
            big = x > big ? x : big;
            big = y > big ? y : big;
        }
        if (b->low) {
            low = b->low[a];
            big = b->most;
        }
        im->origin[a] = s->period[a] > 0 && low < INFINITY ? (double)low : 0;
        farthest = fmax(farthest, fabs(im->origin[a]));
        most = big > most ? big : most;
    }
    inside_test in = make_inside_test(s, im);
    // Per periodic axis, in float: lo >= o is wrap_object's lo - o >= 0 exactly (o is a float);
    // |lo| < near_f implies |lo| < near_limit; hi < top_f implies (hi - o) + slack < L (which
    // implies lo - o < L) with 2^-48 of room, far more than the sums' rounding (a few 2^-53).
    float o_f[3], near_f[3], top_f[3];
    int axes[3], axis_count = 0;
    for (int a = 0; a < 3; a++) {
        double L = s->period[a], o = im->origin[a], slack = in.inside_slack[a];
        if (L == 0)
            continue;
        axes[axis_count++] = a;
        o_f[a] = (float)o;
        near_f[a] = round_down(in.near_limit[a]);
        top_f[a] = round_down(o + L - slack - 0x1p-48 * (fabs(o) + L + slack));
    }
    uint64_t total = 0;
    enum { BLOCK = 1024 };
    i4 inside[BLOCK / 4];
    // With bounds given, the bounds of what is read, to check them.
    f4 seen_low4[3] = {{INFINITY, INFINITY, INFINITY, INFINITY},
                       {INFINITY, INFINITY, INFINITY, INFINITY},
                       {INFINITY, INFINITY, INFINITY, INFINITY}};
    f4 seen_big4 = {0, 0, 0, 0};
    for (uint32_t k0 = 0; k0 < n; k0 += BLOCK) {
        uint32_t m = n - k0 < BLOCK ? n - k0 : BLOCK, m4 = m & ~3u;
        for (uint32_t x = 0; x < m4; x += 4) {
            i4 yes = {-1, -1, -1, -1};
            for (int a = 0; a < 3; a++) { // each box read once, for the test and the check
                if (s->period[a] == 0 && !b->low)
                    continue;
                f4 l = load4(b->lo[a] + k0 + x), h = load4(b->hi[a] + k0 + x);
                f4 x4 = abs4(l), y4 = abs4(h);
                if (s->period[a] > 0)
                    yes &= (l >= o_f[a]) & (x4 < near_f[a]) & (h < top_f[a]);
                if (b->low) {
                    seen_low4[a] = pick4(l < seen_low4[a], l, seen_low4[a]);
                    seen_big4 = pick4(x4 > seen_big4, x4, seen_big4);
                    seen_big4 = pick4(y4 > seen_big4, y4, seen_big4);
                }
            }
            inside[x / 4] = yes;
        }
        for (uint32_t x = 0; x < m; x++) {
            bool yes = true;
            if (x >= m4) { // the last few, one at a time
                for (int c = 0; c < axis_count; c++) {
                    int a = axes[c];
                    float l = b->lo[a][k0 + x], h = b->hi[a][k0 + x];
                    yes &= l >= o_f[a] && fabsf(l) < near_f[a] && h < top_f[a];
                }
                for (int a = 0; a < 3 && b->low; a++) {
                    float l = b->lo[a][k0 + x], h = b->hi[a][k0 + x];
                    seen_low4[a][0] = l < seen_low4[a][0] ? l : seen_low4[a][0];
                    seen_big4[0] = fabsf(l) > seen_big4[0] ? fabsf(l) : seen_big4[0];
                    seen_big4[0] = fabsf(h) > seen_big4[0] ? fabsf(h) : seen_big4[0];
                }
            } else {
                yes = inside[x / 4][x % 4] != 0;
            }
            if (yes)
                continue;
            double lo[3], hi[3];
            object_box(&s->in, k0 + x, lo, hi);
            uint32_t marked = im->marked_count;
            int32_t wk[3];
            bpx_status status = wrap_object(s, im, k0 + x, lo, hi, &in, &total, wk);
            // (past the images' limit the search fails: no more ghosts made)
            if (status == BPX_OK && im->marked_count > marked && im->past_limit == UINT32_MAX)
                status = images_of(s, im, k0 + x, wk);
            if (status != BPX_OK)
                return status;
        }
    }
    for (int q = 0; q < 4 && b->low; q++) {
        for (int a = 0; a < 3; a++)
            *stale |= s->period[a] > 0 && seen_low4[a][q] < b->low[a];
        *stale |= seen_big4[q] > b->most;
    }
    for (int a = 0; a < 3 && b->low && n > 0; a++) // the least is one of them
        *stale |= s->period[a] > 0 && !(seen_low4[a][0] == b->low[a] ||
                                        seen_low4[a][1] == b->low[a] ||
                                        seen_low4[a][2] == b->low[a] ||
                                        seen_low4[a][3] == b->low[a]);
    *ghosts = total;
    return BPX_OK;
}

// The sparse path's start: s->keep's wrap back to 0 and exact to 1 where last cycle's objects
// wrapped (or whole, when it did not end clean).
static void clean_keep(bpx__search_keep *keep, image_state *im)
{
    if (keep->clean) {
        for (uint32_t x = 0; x < keep->moved_count; x++) {
            uint32_t k = keep->moved_ids[x];
            keep->wrap[k][0] = keep->wrap[k][1] = keep->wrap[k][2] = 0;
            keep->exact[k] = 1;
        }
    } else {
        memset(keep->wrap, 0, keep->wrap_capacity * sizeof *keep->wrap);
        memset(keep->exact, 1, keep->exact_capacity);
    }
    keep->clean = false; // until this cycle's images are made
    keep->moved_count = 0;
    im->sparse = true;
}

static bpx_status too_many_images(const search *s, const image_state *im)
{
    return bpx__error(s->err, BPX_ERR_TOO_MANY_BOXES, im->past_limit, -1,
                      "the objects with their periodic images pass BPX_MAX_BOXES (%u) at object "
                      "%u: the cell is small for boxes and cutoff this large",
                      BPX_MAX_BOXES, im->past_limit);
}

// The float32 box of object k shifted by (u - w) periods, grown by cutoff / 2, rounded outward
// past the error of computing it in double.
static bpx_box image_box_of(const search *s, uint32_t k, const int32_t u[3], const int32_t w[3]);

static bpx_box image_box(const search *s, uint32_t k, const int32_t u[3])
{
    static const int32_t zero[3] = {0, 0, 0};
    return image_box_of(s, k, u, s->wrap ? s->wrap[k] : zero);
}

// image_box for object k of wrap w.
static bpx_box image_box_of(const search *s, uint32_t k, const int32_t u[3], const int32_t w[3])
{
    double lo[3], hi[3];
    object_box(&s->in, k, lo, hi);
    double half = s->def->cutoff / 2;
    bpx_box b;
    for (int a = 0; a < 3; a++) {
        double t = s->wrap ? ((double)u[a] - w[a]) * s->period[a] : 0;
        // Nothing to round when there is nothing to add: the box as given, rounded once.
        double error =
            half == 0 && t == 0 ? 0 : 0x1p-48 * (fabs(lo[a]) + fabs(hi[a]) + half + fabs(t));
        b.min[a] = round_down(lo[a] - half + t - error);
        b.max[a] = round_up(hi[a] + half + t + error);
    }
    return b;
}


static bool image_is_box(const search *s, uint32_t k, const bpx_box *b)
{
    if (s->wrap && (s->wrap[k][0] | s->wrap[k][1] | s->wrap[k][2]))
        return false;
    double lo[3], hi[3];
    object_box(&s->in, k, lo, hi);
    bool same = true;
    for (int a = 0; a < 3; a++)
        same &= (double)b->min[a] == lo[a] && (double)b->max[a] == hi[a];
    return same;
}

void bpx__round_boxes64_soa(const bpx_box64 *in, uint32_t n, float *const lo[3],
                            float *const hi[3])
{
    for (uint32_t k = 0; k < n; k++)
        for (int a = 0; a < 3; a++) {
            lo[a][k] = round_down(in[k].min[a]);
            hi[a][k] = round_up(in[k].max[a]);
        }
}

// Open, no cutoff, float64 boxes: each image is the box rounded outward, nothing added (as
// image_box, but for the sign of a zero); exact[k] whether it is the box. Returns how many are.
static uint32_t round_boxes64(const bpx_box64 *in, uint32_t n, bpx_box *out, uint8_t *exact)
{
    uint32_t count = 0;
    for (uint32_t k = 0; k < n; k++) {
        bool same = true;
        for (int a = 0; a < 3; a++) {
            float lo = round_down(in[k].min[a]), hi = round_up(in[k].max[a]);
            out[k].min[a] = lo;
            out[k].max[a] = hi;
            same &= ((double)lo == in[k].min[a]) & ((double)hi == in[k].max[a]);
        }
        exact[k] = same;
        count += same;
    }
    return count;
}

static bool wraps(const search *s, uint32_t k)
{
    return s->wrap && (s->wrap[k][0] | s->wrap[k][1] | s->wrap[k][2]);
}

static bpx_status make_images(search *s, image_state *im)
{
    // float32 boxes and no cutoff: an object's own image is its box unless it wraps. The
    // comparator gets the boxes themselves, then the images of the few that wrap moved onto
    // them, then the ghosts: no copy of the many.
    bool own = (s->in.format == BPX_BOXES_F32 || s->in.format == BPX__BOXES_SOA) &&
               s->def->cutoff == 0;
    if (im->sparse) { // scan_cell made them (own is true)
        bpx__search_keep *kept = s->keep;
        im->boxes = s->in.data;
        im->all_exact = im->moved == 0; // the ghosts never pair as they stand
        im->exact = im->all_exact ? NULL : kept->exact;
        im->moved_ids = kept->moved_ids;
        im->moved_boxes = kept->moved_boxes;
        im->ghost_boxes = kept->images;
        s->images = kept->images;
        s->ghost_owner = kept->ghost_owner;
        s->ghost_shift = kept->ghost_shift;
        return BPX_OK;
    }
    uint32_t moved = 0;
    for (uint32_t x = 0; own && im->mark && x < im->marked_count; x++)
        moved += wraps(s, im->marked[x]);
    if (own && moved == 0 && s->ghost_count == 0) {
        im->boxes = s->in.data;
        im->all_exact = true;
        return BPX_OK;
    }
    size_t count = own ? (size_t)moved + s->ghost_count : (size_t)s->n + s->ghost_count;
    bpx__search_keep *kept = s->keep; // a periodic world's: its arrays serve again
    if (kept) {
        s->images = room(&kept->images, &kept->image_capacity, count, sizeof *s->images);
    } else {
        s->images = bpx__alloc(count * sizeof *s->images);
        advise_huge(s->images, count * sizeof *s->images);
    }
    im->image_count = count;
    im->boxes = own ? s->in.data : s->images;
    im->moved = moved;
    im->moved_boxes = s->images;
    im->ghost_boxes = own ? s->images + moved : s->images + s->n;
    bpx_box *ghost_out = s->images ? (bpx_box *)im->ghost_boxes : NULL;
    if (s->def->cutoff == 0)
        im->exact = im->sparse ? kept->exact // 1 but where marked: no memset
                    : kept     ? room(&kept->exact, &kept->exact_capacity, s->n, 1)
                               : bpx__alloc(s->n);
    if (moved)
        im->moved_ids = kept ? room(&kept->moved_ids, &kept->moved_capacity, moved,
                                    sizeof *im->moved_ids)
                             : bpx__alloc((size_t)moved * sizeof *im->moved_ids);
    if ((s->def->cutoff == 0 && !im->exact) || (moved && !im->moved_ids))
        return bpx__error(s->err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %u objects", s->n);
    if (s->ghost_count && kept) {
        s->ghost_owner = room(&kept->ghost_owner, &kept->ghost_owner_capacity, s->ghost_count,
                              sizeof *s->ghost_owner);
        s->ghost_shift = room(&kept->ghost_shift, &kept->ghost_shift_capacity, s->ghost_count,
                              sizeof *s->ghost_shift);
    } else if (s->ghost_count) {
        s->ghost_owner = bpx__alloc((size_t)s->ghost_count * sizeof *s->ghost_owner);
        s->ghost_shift = bpx__alloc((size_t)s->ghost_count * sizeof *s->ghost_shift);
    }
    if (!s->images || (s->ghost_count && (!s->ghost_owner || !s->ghost_shift)))
        return bpx__error(s->err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %zu periodic images", count);
    static const int32_t zero[3] = {0, 0, 0};
    uint32_t g = 0, m = 0;
    uint32_t exact_count = 0;
    if (s->in.format == BPX_BOXES_F64 && !s->wrap && s->def->cutoff == 0) {
        exact_count = round_boxes64(s->in.data, s->n, s->images, im->exact);
        goto done;
    }
    if (own) {
        if (!im->sparse)
            memset(im->exact, 1, s->n); // but for those that move, below
        exact_count = s->n - moved;
    }
    uint32_t visits = own ? im->marked_count : s->n;
    for (uint32_t x = 0; x < visits; x++) {
        uint32_t k = own ? im->marked[x] : x;
        if (!own) {
            s->images[k] = image_box(s, k, zero);
            if (im->exact) {
                im->exact[k] = image_is_box(s, k, &s->images[k]);
                exact_count += im->exact[k];
            }
        } else {
            bool moves = wraps(s, k);
            if (moves) {
                im->moved_ids[m] = k;
                s->images[m++] = image_box(s, k, zero);
            }
            im->exact[k] = !moves;
        }
        if (!s->ghost_count)
            continue;
        // Enumerate u on each axis from 0 down while the copy reaches 0 (as check_objects
        // counted), skipping u == 0 on all axes (the object itself).
        double lo[3], hi[3];
        object_box(&s->in, k, lo, hi);
        int32_t lowest[3] = {0, 0, 0};
        for (int a = 0; a < 3; a++) {
            if (s->period[a] == 0)
                continue;
            double below =
                images_below(s, a, lo[a], hi[a], s->wrap[k][a], im->origin[a], im->magnitude);
            lowest[a] = below > 0 ? -(int32_t)below : 0;
        }
        int32_t u[3];
        for (u[0] = 0; u[0] >= lowest[0]; u[0]--)
            for (u[1] = 0; u[1] >= lowest[1]; u[1]--)
                for (u[2] = 0; u[2] >= lowest[2]; u[2]--) {
                    if (!u[0] && !u[1] && !u[2])
                        continue;
                    s->ghost_owner[g] = k;
                    memcpy(s->ghost_shift[g], u, sizeof u);
                    ghost_out[g] = image_box(s, k, u);
                    g++;
                }
    }
done:
    if (im->exact && (exact_count == 0 || exact_count == s->n)) {
        im->all_exact = exact_count == s->n;
        if (!kept)
            bpx__free(im->exact, s->n);
        im->exact = NULL;
    }
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// Deciding a candidate

typedef struct found {
    bpx_image_pair pair;
    double distance;
} found;

// within() on objects i and j as the input holds them.
static bool within_objects(const search *s, uint32_t i, uint32_t j, const int32_t shift[3],
                           double *distance)
{
    double lo_i[3], hi_i[3], lo_j[3], hi_j[3];
    object_box(&s->in, i, lo_i, hi_i);
    object_box(&s->in, j, lo_j, hi_j);
    return bpx__within(s, lo_i, hi_i, lo_j, hi_j, shift, distance);
}

enum { PREFETCH_AHEAD = 16 };

// Inlined always: as a function of its own GCC finds it "pure" (prefetches only read) and, its
// result unused, drops every call to it.
static inline __attribute__((always_inline)) void prefetch_object(const search *s,
                                                                  const image_state *im,
                                                                  uint32_t image)
{
    uint32_t k = image < s->n ? image : s->ghost_owner[image - s->n];
    if (s->in.format == BPX__BOXES_SOA) { // six arrays: the wrap and the flag only
        if (s->wrap)
            __builtin_prefetch(&s->wrap[k]);
        if (im->exact)
            __builtin_prefetch(&im->exact[k]);
        return;
    }
    size_t item = s->in.format == BPX_BOXES_F32 ? sizeof(bpx_box)
                  : s->in.format == BPX_BOXES_F64 ? sizeof(bpx_box64)
                  : s->in.format == BPX_POINTS_F32 ? 3 * sizeof(float)
                                                   : 3 * sizeof(double);
    const char *object = (const char *)s->in.data + item * k;
    __builtin_prefetch(object);
    __builtin_prefetch(object + item - 1);
    if (s->wrap)
        __builtin_prefetch(&s->wrap[k]);
    if (im->exact)
        __builtin_prefetch(&im->exact[k]);
}

// Whether objects i and j (shift 0) are within a cutoff of 0 by the box metric: the exact
// test's answer (bpx__within) without its sums, there being nothing to add; distance 0.
static inline bool touching(const search *s, uint32_t i, uint32_t j)
{
    double lo_i[3], hi_i[3], lo_j[3], hi_j[3];
    object_box(&s->in, i, lo_i, hi_i);
    object_box(&s->in, j, lo_j, hi_j);
    bool yes = true;
    for (int a = 0; a < 3; a++)
        yes &= lo_j[a] <= hi_i[a] && lo_i[a] <= hi_j[a];
    return yes;
}

static int compare_found(const void *pa, const void *pb)
{
    const bpx_image_pair *a = &((const found *)pa)->pair, *b = &((const found *)pb)->pair;
    if (a->i != b->i)
        return a->i < b->i ? -1 : 1;
    if (a->j != b->j)
        return a->j < b->j ? -1 : 1;
    for (int x = 0; x < 3; x++)
        if (a->shift[x] != b->shift[x])
            return a->shift[x] < b->shift[x] ? -1 : 1;
    return 0;
}

// A growable list of found pairs, for the pairs with an image.
typedef struct found_list {
    found *items;
    size_t count, capacity;
} found_list;

static bool push(found_list *list, found item)
{
    if (list->count == list->capacity) {
        size_t grown = list->capacity ? 2 * list->capacity : 1024;
        if (!bpx__grow((void **)&list->items, list->capacity * sizeof(found),
                       grown * sizeof(found)))
            return false;
        list->capacity = grown;
    }
    list->items[list->count++] = item;
    return true;
}

// Grows the result's arrays to hold at least `needed` pairs.
bool bpx__neighbors_reserve(bpx_neighbor_list *list, size_t needed, bool want_distances)
{
    if (needed <= list->capacity)
        return true;
    size_t grown = list->capacity ? 2 * list->capacity : 4096;
    if (grown < needed)
        grown = needed;
    bpx_image_pair *pairs = bpx__alloc(grown * sizeof *pairs);
    double *distances = want_distances ? bpx__alloc(grown * sizeof *distances) : NULL;
    if (!pairs || (want_distances && !distances)) {
        bpx__free(pairs, grown * sizeof *pairs);
        bpx__free(distances, grown * sizeof *distances);
        return false;
    }
    advise_huge(pairs, grown * sizeof *pairs);
    advise_huge(distances, want_distances ? grown * sizeof *distances : 0);
    if (list->count) {
        memcpy(pairs, list->pairs, list->count * sizeof *pairs);
        if (want_distances)
            memcpy(distances, list->distances, list->count * sizeof *distances);
    }
    size_t count = list->count;
    bpx_neighbor_list_free(list);
    *list = (bpx_neighbor_list){count, pairs, distances, grown};
    return true;
}

// Decides the candidates: pairs of objects themselves go straight to the result (already in
// (i, j) order, as the backend emits them), pairs with an image to `imaged`, sorted at the end.
static bpx_status decide(const search *s, const image_state *im, const bpx_pair *candidates,
                         size_t count, bpx_neighbor_list *list, found_list *imaged)
{
    bool want = s->def->want_distances;
    bool box0 = s->def->metric == BPX_METRIC_BOX && s->def->cutoff == 0;
    // Every candidate of two objects themselves may be a pair: room for them all at once.
    if (!bpx__neighbors_reserve(list, list->count + count, want))
        return bpx__error(s->err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for the pairs found");
    for (size_t c = 0; c < count; c++) {
        // The objects of a candidate a little ahead: its j is anywhere in memory, and waiting
        // for each in turn was most of this loop's time.
        // With exact flags, the flag twice as far ahead, and the object only where its flag
        // says it is needed: most candidates then touch one byte of j, not its box.
        if (!im->all_exact && c + PREFETCH_AHEAD < count) {
            bpx_pair next = candidates[c + PREFETCH_AHEAD];
            if (im->exact && c + 2 * PREFETCH_AHEAD < count &&
                candidates[c + 2 * PREFETCH_AHEAD].j < s->n)
                __builtin_prefetch(&im->exact[candidates[c + 2 * PREFETCH_AHEAD].j]);
            if (!(im->exact && next.i < s->n && next.j < s->n && im->exact[next.i] &&
                  im->exact[next.j]))
                prefetch_object(s, im, next.j);
        }
        uint32_t a = candidates[c].i, b = candidates[c].j;
        bool own = a < s->n && b < s->n && im->exact && im->exact[a] && im->exact[b];
        if (a < s->n && b < s->n && (im->all_exact || own || (box0 && !s->wrap))) {
            // Two objects as they are (a < b), shift 0: a pair as the comparator found it, or
            // as the plain closed-interval test says (box metric, no cutoff); distance 0.
            bool yes = im->all_exact || own || touching(s, a, b);
            list->pairs[list->count] = (bpx_image_pair){a, b, {0, 0, 0}};
            if (want)
                list->distances[list->count] = 0;
            list->count += yes;
            continue;
        }
        static const int32_t zero[3] = {0, 0, 0};
        uint32_t i = a < s->n ? a : s->ghost_owner[a - s->n];
        uint32_t j = b < s->n ? b : s->ghost_owner[b - s->n];
        const int32_t *u_a = a < s->n ? zero : s->ghost_shift[a - s->n];
        const int32_t *u_b = b < s->n ? zero : s->ghost_shift[b - s->n];
        int32_t shift[3] = {0, 0, 0};
        bool kept = true;
        for (int x = 0; x < 3 && s->wrap; x++) {
            if ((u_a[x] > u_b[x] ? u_a[x] : u_b[x]) != 0)
                kept = false;
            shift[x] = u_b[x] - u_a[x] + s->wrap[i][x] - s->wrap[j][x];
        }
        if (!kept)
            continue;
        bool flip = i > j;
        if (i == j)
            for (int x = 0; x < 3; x++)
                if (shift[x] != 0) {
                    flip = shift[x] < 0;
                    break;
                }
        found f;
        f.pair.i = flip ? j : i;
        f.pair.j = flip ? i : j;
        for (int x = 0; x < 3; x++)
            f.pair.shift[x] = flip ? -shift[x] : shift[x];
        if (!within_objects(s, f.pair.i, f.pair.j, f.pair.shift, &f.distance))
            continue;
        if (a < s->n && b < s->n) {
            list->pairs[list->count] = f.pair;
            if (want)
                list->distances[list->count] = f.distance;
            list->count++;
        } else if (!push(imaged, f)) {
            return bpx__error(s->err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                              "no memory for the pairs found");
        }
    }
    return BPX_OK;
}

// decide() for an open search into bpx_pair: keeps, in place and in order, the candidates that
// are pairs; returns how many.
static size_t decide_pairs(const search *s, const image_state *im, bpx_pair *pairs, size_t count)
{
    if (im->all_exact)
        return count;
    bool box0 = s->def->metric == BPX_METRIC_BOX && s->def->cutoff == 0;
    size_t kept = 0;
    for (size_t c = 0; c < count; c++) {
        if (c + PREFETCH_AHEAD < count)
            prefetch_object(s, im, pairs[c + PREFETCH_AHEAD].j);
        uint32_t i = pairs[c].i, j = pairs[c].j;
        static const int32_t zero[3] = {0, 0, 0};
        double distance;
        bool yes = (im->exact && im->exact[i] && im->exact[j]) ||
                   (box0 ? touching(s, i, j) : within_objects(s, i, j, zero, &distance));
        pairs[kept] = pairs[c];
        kept += yes;
    }
    return kept;
}

// Merges the sorted pairs with images into the result, from the back, in place.
static bpx_status merge_imaged(const search *s, found_list *imaged, bpx_neighbor_list *list)
{
    if (imaged->count == 0)
        return BPX_OK;
    qsort(imaged->items, imaged->count, sizeof(found), compare_found);
    bool want = s->def->want_distances;
    size_t total = list->count + imaged->count;
    if (!bpx__neighbors_reserve(list, total, want))
        return bpx__error(s->err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %zu pairs", total);
    size_t p = list->count, q = imaged->count, k = total;
    while (q > 0) {
        found last = imaged->items[q - 1];
        found mine = {.pair = p > 0 ? list->pairs[p - 1] : last.pair};
        if (p > 0 && compare_found(&mine, &last) > 0) {
            p--;
            list->pairs[--k] = list->pairs[p];
            if (want)
                list->distances[k] = list->distances[p];
        } else {
            q--;
            list->pairs[--k] = last.pair;
            if (want)
                list->distances[k] = last.distance;
        }
    }
    list->count = total;
    return BPX_OK;
}

static void free_search(search *s, image_state *im)
{
    if (s->keep)
        return; // all of them the periodic world's
    bpx__free(im->exact, s->n);
    bpx__free(s->wrap, (size_t)s->n * sizeof *s->wrap);
    bpx__free(s->ghost_owner, (size_t)s->ghost_count * sizeof *s->ghost_owner);
    bpx__free(s->ghost_shift, (size_t)s->ghost_count * sizeof *s->ghost_shift);
    bpx__free(s->images, im->image_count * sizeof *s->images);
    bpx__free(im->moved_ids, (size_t)im->moved * sizeof *im->moved_ids);
    bpx__free(im->marked, (size_t)im->marked_capacity * sizeof *im->marked);
}

// A world of images kept between calls (a periodic world's), or none: one made per call.
typedef struct keeper {
    bpx_world **world;           // NULL: make one and destroy it
    const bpx_world_def *def;    // how to make the kept one
    bpx__search_keep *search;    // the kept world and arrays, or NULL
} keeper;

static void done_with(const keeper *k, bpx_world *w)
{
    if (!k->world)
        bpx_world_destroy(w);
}

// The candidates from a world of the images, decided into the list; or, with out_count (an
// open search), into out as bpx_find_pairs would (CAPACITY when more than capacity).
static bpx_status run(search *s, image_state *im, const keeper *keep, bpx_neighbor_list *list,
                      bpx_pair *out, size_t capacity, size_t *out_count)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = s->def->backend;
    def.worker_count = s->def->worker_count;
    def.capacity_hint = s->n + s->ghost_count;
    if (keep->def)
        def = *keep->def;
    bpx_world *w = keep->world ? *keep->world : NULL;
    bpx_status status = BPX_OK;
    if (!w && (status = bpx_world_create(&def, &w)) != BPX_OK)
        return bpx__error(s->err, status, UINT32_MAX, -1, "%s (backend %s)",
                          bpx_status_string(status), bpx_backend_name(def.backend));
    if (keep->world)
        *keep->world = w;
    bool mine = false; // an error of this function's own, not the world's
    size_t image_total = (size_t)s->n + s->ghost_count;
    if (keep->world && s->in.format == BPX__BOXES_SOA && im->boxes != s->images) {
        // The world's own arrays copied as they are (no AoS round trip, no second check), the
        // wrapped boxes' images moved onto them, the ghosts after them.
        status = bpx__world_set_images(w, &s->in.soa, s->n, im->moved_ids, im->moved_boxes,
                                       im->moved, im->ghost_boxes, s->ghost_count);
    } else if (keep->world && im->boxes != s->images) {
        // A kept world gets every box in one set_boxes, so that its ids stay put and its
        // backend's state (sap's lists) carries over: no removed ids, no count that shrinks
        // between the calls.
        bpx_box *all = room(&keep->search->boxes, &keep->search->box_capacity, image_total,
                            sizeof *all);
        if (!all)
            return bpx__error(s->err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                              "no memory for %zu periodic images", image_total);
        if (s->n)
            memcpy(all, im->boxes, (size_t)s->n * sizeof *all);
        for (uint32_t m = 0; m < im->moved; m++)
            all[im->moved_ids[m]] = im->moved_boxes[m];
        if (s->ghost_count)
            memcpy(all + s->n, im->ghost_boxes, (size_t)s->ghost_count * sizeof *all);
        status = bpx_world_set_boxes(w, all, (uint32_t)image_total);
    } else if (im->boxes == s->images) {
        status = bpx_world_set_boxes(w, im->boxes, s->n + s->ghost_count);
    } else {
        // The objects themselves, the wrapped ones moved, the ghosts added: ids n, n + 1, ...
        // as the world hands them out after set_boxes.
        status = bpx_world_set_boxes(w, im->boxes, s->n);
        if (status == BPX_OK && im->moved)
            status = bpx_world_move_boxes(w, im->moved_ids, im->moved_boxes, im->moved);
        if (status == BPX_OK && s->ghost_count) {
            uint32_t *ids = bpx__alloc((size_t)s->ghost_count * sizeof *ids);
            status = ids ? bpx_world_add_boxes(w, im->ghost_boxes, s->ghost_count, ids)
                         : bpx__error(s->err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                                      "no memory for %u images", s->ghost_count);
            mine = !ids;
            for (uint32_t g = 0; status == BPX_OK && g < s->ghost_count; g++)
                if (ids[g] != s->n + g) {
                    status = bpx__error(s->err, BPX_ERR_BAD_STATE, g, -1,
                                        "image %u got id %u", g, ids[g]);
                    mine = true;
                }
            bpx__free(ids, (size_t)s->ghost_count * sizeof *ids);
        }
    }
    if (status == BPX_OK && out_count) {
        // The candidates straight into out, then the pairs among them kept in place; when
        // the candidates do not fit, the pairs may: the list's way, counted, then copied.
        size_t total = 0;
        status = bpx_world_collide_into(w, out, capacity, &total);
        if (status == BPX_OK) {
            *out_count = decide_pairs(s, im, out, total);
            done_with(keep, w);
            return BPX_OK;
        }
        if (status == BPX_ERR_CAPACITY) {
            bpx__error_clear(s->err);
            status = bpx_world_collide(w);
        }
    } else if (status == BPX_OK) {
        status = bpx_world_collide(w);
    }
    if (status != BPX_OK) {
        if (s->err && !mine)
            *s->err = *bpx_world_error(w);
        done_with(keep, w);
        return status;
    }
    size_t count;
    const bpx_pair *candidates = bpx_world_pairs(w, &count);
    found_list imaged = {0};
    if (s->keep) // last cycle's room
        imaged = (found_list){s->keep->imaged, 0, s->keep->imaged_capacity};
    status = decide(s, im, candidates, count, list, &imaged);
    done_with(keep, w);
    if (status == BPX_OK)
        status = merge_imaged(s, &imaged, list);
    if (s->keep) {
        s->keep->imaged = imaged.items;
        s->keep->imaged_capacity = imaged.capacity;
    } else {
        bpx__free(imaged.items, imaged.capacity * sizeof(found));
    }
    if (status == BPX_OK && out_count) {
        *out_count = list->count;
        if (list->count > capacity) {
            status = bpx__error(s->err, BPX_ERR_CAPACITY, UINT32_MAX, -1,
                                "%zu pairs found, capacity %zu", list->count, capacity);
        } else {
            for (size_t k = 0; k < list->count; k++)
                out[k] = (bpx_pair){list->pairs[k].i, list->pairs[k].j};
        }
    }
    if (status != BPX_OK || out_count)
        bpx_neighbor_list_free(list);
    return status;
}

// Whether def gives a triclinic cell: any entry not 0 (NaN included, refused later).
static bool has_cell(const bpx_neighbor_def *def)
{
    for (int a = 0; a < 3; a++)
        for (int c = 0; c < 3; c++)
            if (def->cell[a][c] != 0)
                return true;
    return false;
}

// A cell that is diagonal with finite positive entries, given with no period, as def's periods
// into *out (its open axes 0, the cell cleared); false for any other cell.
static bool orthorhombic_cell(const bpx_neighbor_def *def, bpx_neighbor_def *out)
{
    for (int a = 0; a < 3; a++) {
        if (def->period[a] != 0 || !(def->cell[a][a] > 0 && def->cell[a][a] < INFINITY))
            return false;
        for (int c = 0; c < 3; c++)
            if (c != a && def->cell[a][c] != 0)
                return false;
    }
    *out = *def;
    memset(out->cell, 0, sizeof out->cell);
    for (int a = 0; a < 3; a++)
        out->period[a] = def->cell_open[a] ? 0 : def->cell[a][a];
    return true;
}

// bpx_find_neighbors; with out_count, into out as bpx_find_pairs would (open searches only).
static bpx_status find(const bpx_neighbor_def *def, const void *data, uint32_t n,
                       const keeper *keep, bpx_neighbor_list *list, bpx_pair *out,
                       size_t capacity, size_t *out_count, bpx_error *err)
{
    if (keep->world)
        list->count = 0; // its arrays serve again
    else
        *list = (bpx_neighbor_list){0};
    if (!def || (!data && n > 0))
        return bpx__error(err, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "def is NULL, or data is NULL with n > 0");
    if (n > BPX_MAX_BOXES)
        return bpx__error(err, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "%u objects exceed BPX_MAX_BOXES (%u)", n, BPX_MAX_BOXES);
    // A triclinic cell (def->cell): diagonal with positive entries, it is the orthorhombic
    // cell of those periods (the same pairs, shifts and bits); otherwise its own search.
    bpx_neighbor_def diagonal;
    if (has_cell(def)) {
        if (keep->world || out_count)
            return bpx__error(err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                              "a triclinic cell is for bpx_find_neighbors");
        if (!orthorhombic_cell(def, &diagonal)) {
            bpx_status checked = check_def(def, false, err);
            return checked != BPX_OK ? checked
                                     : bpx__neighbors_triclinic(def, data, n, list, err);
        }
        def = &diagonal;
    }
    bpx_status status = check_def(def, keep->world != NULL, err);
    if (status != BPX_OK || n == 0)
        return status;
    search s = {.def = def, .in = {.data = data, .format = def->format}, .n = n, .err = err};
    if (def->format == BPX__BOXES_SOA)
        s.in.soa = *(const bpx__soa_boxes *)data;
    for (int a = 0; a < 3; a++) {
        s.period[a] = def->period[a];
        s.periodic |= def->period[a] > 0;
    }
    // A periodic world's own float32 boxes without cutoff (its usual case) take the sparse
    // path: the kept wraps and flags stay 0 and 1 but where boxes leave the cell, and only
    // those are written.
    bpx__search_keep *kept = keep->search;
    bool sparse = kept && s.periodic && def->format == BPX__BOXES_SOA && def->cutoff == 0;
    if (s.periodic && kept) {
        s.keep = kept;
        bool grows = !kept->wrap || n > kept->wrap_capacity ||
                     (sparse && (!kept->exact || n > kept->exact_capacity));
        bool fits = !grows;
        if (grows) { // contents lost: cleared whole by clean_keep
            kept->clean = false;
            fits = room(&kept->wrap, &kept->wrap_capacity, n, sizeof *kept->wrap) &&
                   (!sparse || room(&kept->exact, &kept->exact_capacity, n, 1));
            if (fits)
                advise_huge(kept->wrap, kept->wrap_capacity * sizeof *kept->wrap);
        }
        if (!fits)
            return bpx__error(err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                              "no memory for %u objects", n);
        s.wrap = kept->wrap;
    } else if (s.periodic) {
        s.wrap = bpx__alloc((size_t)n * sizeof *s.wrap);
        if (!s.wrap)
            return bpx__error(err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                              "no memory for %u objects", n);
        advise_huge(s.wrap, (size_t)n * sizeof *s.wrap);
    }
    uint64_t ghosts = 0;
    image_state im = {.past_limit = UINT32_MAX};
    // Points with the auto backend: the cell list, where the cell allows; its wraps are from 0.
    bool may_cells = !out_count && def->backend == BPX_BACKEND_AUTO &&
                     (def->format == BPX_POINTS_F32 || def->format == BPX_POINTS_F64);
    im.mark = s.periodic && (def->format == BPX_BOXES_F32 || def->format == BPX__BOXES_SOA) &&
              def->cutoff == 0;
    if (kept && s.periodic) { // marked is the world's (its last cycle's list, in sparse)
        im.marked = kept->marked;
        im.marked_capacity = kept->marked_capacity;
    }
    if (sparse) {
        clean_keep(kept, &im);
        bool stale = false;
        status = scan_cell(&s, &im, &ghosts, &stale);
        if (status == BPX_OK && stale) { // (a bug of a path that changed the boxes unversioned)
            s.in.soa.low = NULL;
            image_state fresh = {.past_limit = UINT32_MAX, .mark = true};
            fresh.marked = im.marked;
            fresh.marked_capacity = im.marked_capacity;
            im = fresh;
            clean_keep(kept, &im); // clears the arrays whole
            status = scan_cell(&s, &im, &ghosts, &stale);
        }
    } else {
        if (kept && s.periodic)
            kept->clean = false; // every wrap written
        if (s.periodic) {
            cell_origin(&s, im.origin, &im.magnitude);
            if (may_cells) // the image search then runs only where the cell list cannot
                im.origin[0] = im.origin[1] = im.origin[2] = 0;
        }
        status = check_objects(&s, &im, &ghosts);
    }
    if (kept && s.periodic) { // grown, perhaps
        kept->marked = im.marked;
        kept->marked_capacity = im.marked_capacity;
    }
    bool cells = false;
    if (status == BPX_OK && may_cells) {
        status = bpx__neighbors_cells(&s, list);
        cells = status != BPX_ERR_BAD_STATE;
        if (!cells)
            status = BPX_OK;
    }
    if (status == BPX_OK && !cells && im.past_limit != UINT32_MAX)
        status = too_many_images(&s, &im);
    if (status == BPX_OK && !cells) {
        s.ghost_count = (uint32_t)ghosts;
        status = make_images(&s, &im);
        if (status == BPX_OK && sparse) { // wrap and exact differ from 0 and 1 at marked only
            kept->clean = true;
            kept->moved_count = im.moved;
        }
        if (status == BPX_OK)
            status = run(&s, &im, keep, list, out, capacity, out_count);
    }
    free_search(&s, &im);
    return status;
}

bpx_status bpx_find_neighbors(const bpx_neighbor_def *def, const void *data, uint32_t n,
                              bpx_neighbor_list *list, bpx_error *err)
{
    bpx__error_clear(err);
    if (!list)
        return bpx__error(err, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "list is NULL");
    static const keeper none = {0};
    return find(def, data, n, &none, list, NULL, 0, NULL, err);
}

bpx_status bpx_find_pairs_f64(const bpx_box64 *boxes, uint32_t n, bpx_backend backend,
                              bpx_pair *out, size_t capacity, size_t *count, bpx_error *err)
{
    bpx__error_clear(err);
    if (!count || (!out && capacity > 0))
        return bpx__error(err, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "count is NULL, or out is NULL with capacity > 0");
    *count = 0;
    bpx_neighbor_def def = bpx_default_neighbor_def();
    def.format = BPX_BOXES_F64;
    def.backend = backend;
    bpx_neighbor_list list;
    static const keeper none = {0};
    return find(&def, boxes, n, &none, &list, out, capacity, count, err);
}

bpx_status bpx__find_neighbors_kept(const bpx_neighbor_def *def, const void *boxes, uint32_t n,
                                    bpx__search_keep *kept, const bpx_world_def *inner_def,
                                    bpx_neighbor_list *list, bpx_error *err)
{
    bpx__error_clear(err);
    keeper keep = {&kept->inner, inner_def, kept};
    return find(def, boxes, n, &keep, list, NULL, 0, NULL, err);
}

void bpx__search_keep_free(bpx__search_keep *k)
{
    bpx_world_destroy(k->inner);
    bpx__free(k->boxes, k->box_capacity * sizeof *k->boxes);
    bpx__free(k->wrap, k->wrap_capacity * sizeof *k->wrap);
    bpx__free(k->exact, k->exact_capacity);
    bpx__free(k->marked, (size_t)k->marked_capacity * sizeof *k->marked);
    bpx__free(k->images, k->image_capacity * sizeof *k->images);
    bpx__free(k->ghost_owner, k->ghost_owner_capacity * sizeof *k->ghost_owner);
    bpx__free(k->ghost_shift, k->ghost_shift_capacity * sizeof *k->ghost_shift);
    bpx__free(k->moved_ids, k->moved_capacity * sizeof *k->moved_ids);
    bpx__free(k->moved_boxes, k->moved_box_capacity * sizeof *k->moved_boxes);
    bpx__free(k->imaged, k->imaged_capacity * sizeof(found));
    *k = (bpx__search_keep){0};
}
