// The updater: the boxes of each cycle into the world's SoA arrays (whole boxes, float64 boxes,
// a periodic world's images, or the paper's extents plus centres), checked as they are copied.
#include "world.h"

#include <float.h>
#include <math.h>
#include <string.h>

#include "alloc.h"
#include "boxes.h"
#include "clock.h"
#include "objects.h"
#include "transpose.h"
#include "validate.h"

// The updater's passes split into chunks of box ids for large n (below, one chunk: threads
// would cost more than they save). Chunks depend on n only; each writes its own range of the
// spare set and its own verdict, so the result is the same for any worker count.
enum { UPDATE_PARALLEL_MIN = 32768, UPDATE_CHUNK_MIN = 16384, UPDATE_CHUNKS_MAX = 64 };

typedef struct update_job {
    const bpx_box *boxes;     // set_boxes
    const float *centres;     // update_centres
    const float *minima[3];   // update_centres
    bpx_box_arrays *out;
    uint32_t n;
    int chunks;
    int ok[UPDATE_CHUNKS_MAX];
    bool bounds; // set_boxes of a periodic world: per chunk, the least lo and largest |x|
    float low[UPDATE_CHUNKS_MAX][3], most[UPDATE_CHUNKS_MAX];
} update_job;

static void chunk_range(const update_job *job, int c, uint32_t *begin, uint32_t *end)
{
    *begin = (uint32_t)((uint64_t)job->n * (uint64_t)c / (uint64_t)job->chunks);
    *end = (uint32_t)((uint64_t)job->n * (uint64_t)(c + 1) / (uint64_t)job->chunks);
}

// Valid iff -FLT_MAX <= min <= max <= FLT_MAX: NaN fails a comparison, infinity a bound.
static void set_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    update_job *job = context;
    float *lx = job->out->lo[0], *ly = job->out->lo[1], *lz = job->out->lo[2];
    float *hx = job->out->hi[0], *hy = job->out->hi[1], *hz = job->out->hi[2];
    for (int c = begin; c < end; c++) {
        uint32_t i0, i1;
        chunk_range(job, c, &i0, &i1);
        int ok = 1;
        uint32_t i = i0;
        float least[3] = {INFINITY, INFINITY, INFINITY}, most = 0;
#ifdef BPX_HAVE_TRANSPOSE4
        // Four boxes at a time: one transpose, three range checks on whole vectors.
        const __m128 low = _mm_set1_ps(-FLT_MAX), high = _mm_set1_ps(FLT_MAX);
        const __m128 magnitude = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
        __m128 good = _mm_castsi128_ps(_mm_set1_epi32(-1));
        __m128 least4[3] = {_mm_set1_ps(INFINITY), _mm_set1_ps(INFINITY), _mm_set1_ps(INFINITY)};
        __m128 most4 = _mm_setzero_ps();
        for (; i + 4 <= i1; i += 4) {
            __m128 v[6];
            bpx__boxes4_to_soa(&job->boxes[i], v);
            for (int a = 0; a < 3; a++)
                good = _mm_and_ps(good, _mm_and_ps(_mm_and_ps(_mm_cmple_ps(low, v[a]),
                                                              _mm_cmple_ps(v[a], v[3 + a])),
                                                   _mm_cmple_ps(v[3 + a], high)));
            for (int a = 0; a < 3 && job->bounds; a++) {
                least4[a] = _mm_min_ps(v[a], least4[a]);
                most4 = _mm_max_ps(_mm_and_ps(v[a], magnitude), most4);
                most4 = _mm_max_ps(_mm_and_ps(v[3 + a], magnitude), most4);
            }
            _mm_storeu_ps(lx + i, v[0]);
            _mm_storeu_ps(ly + i, v[1]);
            _mm_storeu_ps(lz + i, v[2]);
            _mm_storeu_ps(hx + i, v[3]);
            _mm_storeu_ps(hy + i, v[4]);
            _mm_storeu_ps(hz + i, v[5]);
        }
        ok &= _mm_movemask_ps(good) == 0xf;
        float lanes[4][4];
        _mm_storeu_ps(lanes[0], least4[0]);
        _mm_storeu_ps(lanes[1], least4[1]);
        _mm_storeu_ps(lanes[2], least4[2]);
        _mm_storeu_ps(lanes[3], most4);
        for (int q = 0; q < 4 && job->bounds; q++) {
            for (int a = 0; a < 3; a++)
                least[a] = lanes[a][q] < least[a] ? lanes[a][q] : least[a];
            most = lanes[3][q] > most ? lanes[3][q] : most;
        }
#endif
        for (; i < i1; i++) {
            const bpx_box *box = &job->boxes[i];
            for (int a = 0; a < 3; a++)
                ok &= (-FLT_MAX <= box->min[a]) & (box->min[a] <= box->max[a]) &
                      (box->max[a] <= FLT_MAX);
            lx[i] = box->min[0], ly[i] = box->min[1], lz[i] = box->min[2];
            hx[i] = box->max[0], hy[i] = box->max[1], hz[i] = box->max[2];
            for (int a = 0; a < 3 && job->bounds; a++) {
                float x = fabsf(box->min[a]), y = fabsf(box->max[a]);
                least[a] = box->min[a] < least[a] ? box->min[a] : least[a];
                most = x > most ? x : most;
                most = y > most ? y : most;
            }
        }
        job->ok[c] = ok;
        for (int a = 0; a < 3; a++)
            job->low[c][a] = least[a];
        job->most[c] = most;
    }
}

// One axis of boxes [i0, i1): min = centre + stored minimum, max = centre - stored minimum;
// true when all are finite. restrict: the stores cannot touch the loads, so the loop runs in
// vectors (it was 10% of a cycle at n = 50, one box at a time).
static int centres_axis(const float *restrict centre, const float *restrict m,
                        float *restrict lo, float *restrict hi, uint32_t i0, uint32_t i1)
{
    int ok = 1;
    for (uint32_t i = i0; i < i1; i++) {
        float v = centre[3 * (size_t)i];
        float l = v + m[i], h = v - m[i];
        lo[i] = l;
        hi[i] = h;
        ok &= (-FLT_MAX <= l) & (h <= FLT_MAX);
    }
    return ok;
}

// min = centre + stored minimum, max = centre - stored minimum; finiteness checked (see
// bpx_world_update_centres).
static void centres_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    update_job *job = context;
    for (int c = begin; c < end; c++) {
        uint32_t i0, i1;
        chunk_range(job, c, &i0, &i1);
        int ok = 1;
        for (int a = 0; a < 3; a++)
            ok &= centres_axis(job->centres + a, job->minima[a], job->out->lo[a],
                               job->out->hi[a], i0, i1);
        job->ok[c] = ok;
    }
}

// Tells the backend that the boxes were replaced (by centres, or else by whole boxes or extents).
static void tell_backend(bpx_world *w, const float *centres)
{
    if (!w->backend->boxes_set)
        return;
    bpx_boxes_change change = {
        .centres = centres,
        .extents = bpx__world_extents(w),
        .boxes_version = w->boxes_version,
        .inert_ids = w->dead != NULL,
    };
    w->backend->boxes_set(&w->backend_state, &w->def, &change);
}

void bpx__world_boxes_replaced(bpx_world *w)
{
    tell_backend(w, NULL);
}

// Runs an updater pass over all n boxes; true when every box passed its check.
static int run_update(bpx_world *w, bpx_task_fn *task, update_job *job)
{
    int chunks = 1;
    if (job->n >= UPDATE_PARALLEL_MIN && w->executor.worker_count > 1) {
        uint32_t by_size = job->n / UPDATE_CHUNK_MIN;
        chunks = by_size < UPDATE_CHUNKS_MAX ? (int)by_size : UPDATE_CHUNKS_MAX;
    }
    job->chunks = chunks;
    bpx__parallel_for(&w->executor, task, chunks, job);
    int ok = 1;
    for (int c = 0; c < chunks; c++)
        ok &= job->ok[c];
    return ok;
}

// The checks every way of giving boxes starts with: the world may be changed now, the count fits,
// and the array is there when the count says there is one.
static bpx_status enter_with(bpx_world *w, const char *call, const void *array, const char *name,
                             uint32_t n, const char *items)
{
    bpx_status entered = bpx__world_enter(w, call);
    if (entered != BPX_OK)
        return entered;
    if (n > BPX_MAX_BOXES)
        return bpx__error(&w->error, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "%u %s exceed BPX_MAX_BOXES (%u)", n, items, BPX_MAX_BOXES);
    if (!array && n > 0)
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "%s is NULL", name);
    return BPX_OK;
}

bpx_status bpx_world_set_boxes(bpx_world *w, const bpx_box *boxes, uint32_t n)
{
    bpx_status entered = enter_with(w, "set_boxes", boxes, "boxes", n, "boxes");
    if (entered != BPX_OK)
        return entered;
    uint64_t start = bpx__now_ns();
    if (!bpx__box_arrays_reserve(&w->spare, n))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %u boxes", n);
    // One pass: transpose into the spare set and check every box, without branching on data,
    // in parallel for large n (each chunk writes its own range; a bad box anywhere sends the
    // serial check over all of them, which names the first).
    update_job job = {.boxes = boxes, .out = &w->spare, .n = n};
    job.bounds = bpx__world_periodic(w); // the image search's first pass, done here
    int ok = run_update(w, set_task, &job);
    if (!ok)
        return bpx__check_boxes(boxes, n, &w->error); // names the first bad box
    if (!bpx__objects_reset(w, n)) // the last step that can fail: it changes nothing on failure
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %u objects", n);
    bpx__boxes_swap_in_spare(w, n);
    w->bounds_set = job.bounds;
    for (int c = 0; c < job.chunks && job.bounds; c++) {
        for (int a = 0; a < 3; a++)
            w->bounds_low[a] = c == 0 || job.low[c][a] < w->bounds_low[a] ? job.low[c][a]
                                                                          : w->bounds_low[a];
        w->bounds_most = c == 0 || job.most[c] > w->bounds_most ? job.most[c] : w->bounds_most;
    }
    w->bounds_version = w->boxes_version;
    // The boxes no longer come from the loaded extents: centres would rebuild stale boxes.
    w->extents_loaded = false;
    w->boxes64_set = false;
    tell_backend(w, NULL);
    w->stats.update_ns = bpx__now_ns() - start;
    if (w->def.profile) // read: the caller's boxes; written: six arrays (the check reads them)
        w->update_stage = (bpx_stage_stats){"update", "world", w->stats.update_ns,
                                            24 * (uint64_t)n, 24 * (uint64_t)n, 0,
                                            BPX_ACCESS_SEQUENTIAL};
    return BPX_OK;
}

bpx_status bpx_world_set_boxes64(bpx_world *w, const bpx_box64 *boxes, uint32_t n)
{
    bpx_status entered = enter_with(w, "set_boxes64", boxes, "boxes", n, "boxes");
    if (entered != BPX_OK)
        return entered;
    uint64_t start = bpx__now_ns();
    if (bpx__world_margins(w)) // the gap would be measured on the float32 boxes
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "set_boxes64: a world with contact margins takes float32 boxes");
    for (uint32_t k = 0; k < n; k++) {
        for (int a = 0; a < 3; a++)
            if (!isfinite(boxes[k].min[a]) || !isfinite(boxes[k].max[a]))
                return bpx__error(&w->error, BPX_ERR_NOT_FINITE, k, a,
                                  "box %u: a coordinate on axis %c is not finite", k, "xyz"[a]);
        for (int a = 0; a < 3; a++)
            if (boxes[k].min[a] > boxes[k].max[a])
                return bpx__error(&w->error, BPX_ERR_MIN_GREATER_THAN_MAX, k, a,
                                  "box %u: min %g > max %g on axis %c", k, boxes[k].min[a],
                                  boxes[k].max[a], "xyz"[a]);
    }
    // Everything that can fail first, the per-id arrays last (they commit on success).
    bpx_box64 *keep = w->boxes64;
    bool grow = n > w->boxes64_capacity;
    if (grow && !(keep = bpx__alloc((size_t)n * sizeof *keep)))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %u float64 boxes", n);
    if (!bpx__box_arrays_reserve(&w->spare, n) || !bpx__objects_reset(w, n)) {
        if (grow)
            bpx__free(keep, (size_t)n * sizeof *keep);
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %u boxes", n);
    }
    if (grow) {
        bpx__free(w->boxes64, (size_t)w->boxes64_capacity * sizeof *w->boxes64);
        w->boxes64 = keep;
        w->boxes64_capacity = n;
    }
    if (n)
        memcpy(w->boxes64, boxes, (size_t)n * sizeof *boxes);
    float *const lo[3] = {w->spare.lo[0], w->spare.lo[1], w->spare.lo[2]};
    float *const hi[3] = {w->spare.hi[0], w->spare.hi[1], w->spare.hi[2]};
    bpx__round_boxes64_soa(boxes, n, lo, hi);
    bpx__boxes_swap_in_spare(w, n);
    w->extents_loaded = false;
    w->boxes64_set = true;
    tell_backend(w, NULL);
    w->stats.update_ns = bpx__now_ns() - start;
    return BPX_OK;
}

bpx_status bpx__world_set_images(bpx_world *w, const bpx__soa_boxes *soa, uint32_t n,
                                 const uint32_t *moved_ids, const bpx_box *moved,
                                 uint32_t moved_count, const bpx_box *extra, uint32_t extra_count)
{
    bpx_status entered = bpx__world_enter(w, "set_images");
    if (entered != BPX_OK)
        return entered;
    uint64_t start = bpx__now_ns();
    uint64_t total = (uint64_t)n + extra_count;
    if (total > BPX_MAX_BOXES)
        return bpx__error(&w->error, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "%llu boxes with their images exceed BPX_MAX_BOXES (%u)",
                          (unsigned long long)total, BPX_MAX_BOXES);
    // The count of images wanders from cycle to cycle as boxes cross faces: room for 1/32 more,
    // so that the two sets (boxes and spare, swapped each cycle) are not made again, on fresh
    // pages, whenever the count passes the larger set's (1M boxes: 24 MB of page faults).
    uint64_t roomy = total + total / 32;
    if (bpx__boxes_padded((uint32_t)total) > w->spare.capacity &&
        !bpx__box_arrays_reserve(&w->spare, roomy < BPX_MAX_BOXES ? (uint32_t)roomy
                                                                  : (uint32_t)total) &&
        !bpx__box_arrays_reserve(&w->spare, (uint32_t)total))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %llu boxes", (unsigned long long)total);
    if (!bpx__objects_reset(w, (uint32_t)total))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %llu boxes", (unsigned long long)total);
    bpx_box_arrays *out = &w->spare;
    for (int a = 0; a < 3 && n; a++) {
        memcpy(out->lo[a], soa->lo[a], sizeof(float) * n);
        memcpy(out->hi[a], soa->hi[a], sizeof(float) * n);
    }
    for (uint32_t m = 0; m < moved_count; m++)
        for (int a = 0; a < 3; a++) {
            out->lo[a][moved_ids[m]] = moved[m].min[a];
            out->hi[a][moved_ids[m]] = moved[m].max[a];
        }
    for (uint32_t g = 0; g < extra_count; g++)
        for (int a = 0; a < 3; a++) {
            out->lo[a][n + g] = extra[g].min[a];
            out->hi[a][n + g] = extra[g].max[a];
        }
    bpx__boxes_swap_in_spare(w, (uint32_t)total);
    w->extents_loaded = false;
    w->boxes64_set = false;
    tell_backend(w, NULL);
    w->stats.update_ns = bpx__now_ns() - start;
    return BPX_OK;
}

bpx_status bpx_world_load_extents(bpx_world *w, const float *minima, uint32_t n)
{
    bpx_status entered = enter_with(w, "load_extents", minima, "minima", n, "objects");
    if (entered != BPX_OK)
        return entered;
    bpx_status status = bpx__check_minima(minima, n, &w->error);
    if (status != BPX_OK)
        return status;
    // Everything that can fail comes first, into memory the world does not use yet, so that
    // an error leaves the world as it was: new minima arrays, the spare set, a grown current
    // set (update_centres swaps the two and never allocates), the per-id arrays.
    float *arrays[3] = {0};
    bpx_box_arrays grown = {0};
    bool grow_minima = n > w->extent_capacity;
    bool ok = true;
    for (int a = 0; a < 3 && grow_minima && ok; a++)
        ok = (arrays[a] = bpx__alloc(sizeof(float) * n)) != NULL;
    ok = ok && bpx__box_arrays_reserve(&w->spare, n);
    if (ok && bpx__boxes_padded(n) > w->boxes.capacity)
        ok = bpx__box_arrays_reserve(&grown, n);
    ok = ok && bpx__objects_reset(w, n); // the last step that can fail; it commits on success
    if (!ok) {
        for (int a = 0; a < 3; a++)
            bpx__free(arrays[a], sizeof(float) * n);
        bpx__box_arrays_free(&grown);
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %u objects", n);
    }
    if (grow_minima) {
        for (int a = 0; a < 3; a++) {
            bpx__free(w->minima[a], sizeof(float) * w->extent_capacity);
            w->minima[a] = arrays[a];
        }
        w->extent_capacity = n;
    }
    if (grown.capacity) {
        bpx__box_arrays_free(&w->boxes);
        w->boxes = grown;
    }
    // Until the first centres arrive, every object sits at the origin (the paper's n register
    // is set at initialisation).
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            float m = minima[3 * (size_t)i + a];
            w->minima[a][i] = m;
            w->spare.lo[a][i] = m;
            w->spare.hi[a][i] = -m;
        }
    w->extent_count = n;
    w->extents_loaded = true;
    w->boxes64_set = false;
    bpx__boxes_swap_in_spare(w, n);
    tell_backend(w, NULL);
    return BPX_OK;
}

bpx_status bpx_world_update_centres(bpx_world *w, const float *centres)
{
    bpx_status entered = bpx__world_enter(w, "update_centres");
    if (entered != BPX_OK)
        return entered;
    uint64_t start = bpx__now_ns();
    if (!w->extents_loaded)
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "update_centres before load_extents");
    uint32_t n = w->extent_count;
    if (!centres && n > 0)
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "centres is NULL");
    // The paper's updater: min = centre + stored minimum, max = centre - stored minimum, into
    // the spare set. min <= max holds by construction (rounding is monotone and minimum <= 0), so
    // only finiteness is checked: a NaN or infinite centre, or an overflow, fails a bound.
    update_job job = {.centres = centres, .out = &w->spare, .n = n};
    for (int a = 0; a < 3; a++)
        job.minima[a] = w->minima[a];
    int ok = run_update(w, centres_task, &job);
    if (!ok) {
        const float *const minima[3] = {w->minima[0], w->minima[1], w->minima[2]};
        return bpx__check_centres(centres, minima, n, &w->error); // names the first bad one
    }
    bpx__boxes_swap_in_spare(w, n);
    bpx__objects_reinert(w); // removed objects stay out of the broad phase
    tell_backend(w, centres);
    w->stats.update_ns = bpx__now_ns() - start;
    if (w->def.profile) // read: the centres and the minima; written: six arrays
        w->update_stage = (bpx_stage_stats){"update", "world", w->stats.update_ns,
                                            24 * (uint64_t)n, 24 * (uint64_t)n, 0,
                                            BPX_ACCESS_SEQUENTIAL};
    return BPX_OK;
}

