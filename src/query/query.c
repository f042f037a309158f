// The query API: checks, the tree brought up to date, queries in chunks over the workers, and
// the results joined in query order.
#include <math.h>
#include <stdatomic.h>
#include <string.h>

#include "cast.h"
#include "core/alloc.h"
#include "core/validate.h"

#ifdef BPX_COUNT_VISITS
uint64_t bpx__visits;
#endif

/// Queries per work item: enough to amortise handing one out, few enough to balance.
#define BPX_QUERY_CHUNK 64

typedef struct bpx_query_chunk {
    bpx_hit_list hits;
    bpx_status status;
} bpx_query_chunk;

struct bpx_query_state {
    bpx_bvh tree;
    bpx_query_chunk *chunks;
    uint32_t chunk_capacity;
    size_t *offsets; // query_count + 1
    uint32_t offset_capacity;
    bpx_hit_list results; // the last call's hits, joined
    uint32_t query_count;
    bool results_valid;
    atomic_int in_callbacks; // bpx_world_query_each calls now running (world.h's busy check)
};

bpx_query_filter bpx_default_query_filter(void)
{
    return (bpx_query_filter){0xFFFFFFFFu, 0xFFFFFFFFu};
}

bpx_query bpx_query_box(bpx_box box)
{
    return (bpx_query){.kind = BPX_QUERY_BOX, .filter = bpx_default_query_filter(), .box = box};
}

bpx_query bpx_query_sphere(const float centre[3], float radius)
{
    bpx_query q = {.kind = BPX_QUERY_SPHERE, .filter = bpx_default_query_filter()};
    memcpy(q.centre, centre, sizeof q.centre);
    q.radius = radius;
    return q;
}

bpx_query bpx_query_ray(const float origin[3], const float direction[3], float max_fraction,
                        bool closest)
{
    bpx_query q = {.kind = BPX_QUERY_RAY, .closest = closest,
                   .filter = bpx_default_query_filter(), .max_fraction = max_fraction};
    memcpy(q.origin, origin, sizeof q.origin);
    memcpy(q.direction, direction, sizeof q.direction);
    return q;
}

bpx_query bpx_query_sweep(bpx_box box, const float translation[3], float max_fraction,
                          bool closest)
{
    bpx_query q = {.kind = BPX_QUERY_SWEEP, .closest = closest,
                   .filter = bpx_default_query_filter(), .box = box,
                   .max_fraction = max_fraction};
    memcpy(q.direction, translation, sizeof q.direction);
    return q;
}

bpx_query bpx_query_point(const float point[3])
{
    bpx_box b;
    memcpy(b.min, point, sizeof b.min);
    memcpy(b.max, point, sizeof b.max);
    return bpx_query_box(b);
}

bpx_query bpx_query_oriented(const float centre[3], const float half_extents[3],
                             const float rotation[9])
{
    bpx_query q = {.kind = BPX_QUERY_ORIENTED, .filter = bpx_default_query_filter()};
    memcpy(q.centre, centre, sizeof q.centre);
    memcpy(q.half_extents, half_extents, sizeof q.half_extents);
    memcpy(q.rotation, rotation, sizeof q.rotation);
    return q;
}

// ---------------------------------------------------------------------------------------------
// Checks: the first problem of query `index`, naming the field and the axis.

static const char axis_name[3] = {'x', 'y', 'z'};

static bpx_status check_finite(const float v[3], const char *what, uint32_t index, bpx_error *e)
{
    for (int a = 0; a < 3; a++)
        if (!isfinite(v[a]))
            return bpx__error(e, BPX_ERR_NOT_FINITE, index, a, "query %u: %s %c is %g", index,
                              what, axis_name[a], (double)v[a]);
    return BPX_OK;
}

static bpx_status check_box(const bpx_box *b, uint32_t index, bpx_error *e)
{
    bpx_status s = check_finite(b->min, "box min", index, e);
    if (s == BPX_OK)
        s = check_finite(b->max, "box max", index, e);
    for (int a = 0; a < 3 && s == BPX_OK; a++)
        if (b->min[a] > b->max[a])
            s = bpx__error(e, BPX_ERR_MIN_GREATER_THAN_MAX, index, a,
                           "query %u: box min %c %g > max %g", index, axis_name[a],
                           (double)b->min[a], (double)b->max[a]);
    return s;
}

static bpx_status check_motion(const bpx_query *q, uint32_t index, bpx_error *e)
{
    bpx_status s = check_finite(q->direction, "direction", index, e);
    if (s != BPX_OK)
        return s;
    if (isnan(q->max_fraction))
        return bpx__error(e, BPX_ERR_NOT_FINITE, index, -1, "query %u: max_fraction is NaN",
                          index);
    if (q->max_fraction < 0.0f)
        return bpx__error(e, BPX_ERR_INVALID_ARGUMENT, index, -1,
                          "query %u: max_fraction %g is negative", index,
                          (double)q->max_fraction);
    bool zero = q->direction[0] == 0.0f && q->direction[1] == 0.0f && q->direction[2] == 0.0f;
    if (zero && q->max_fraction > 0.0f)
        return bpx__error(e, BPX_ERR_INVALID_ARGUMENT, index, -1,
                          "query %u: zero direction with max_fraction %g (a length needs a "
                          "direction; use max_fraction 0 for a point)",
                          index, (double)q->max_fraction);
    return BPX_OK;
}

static bpx_status check_oriented(const bpx_query *q, uint32_t index, bpx_error *e)
{
    bpx_status s = check_finite(q->centre, "centre", index, e);
    if (s == BPX_OK)
        s = check_finite(q->half_extents, "half extent", index, e);
    for (int r = 0; r < 3 && s == BPX_OK; r++)
        s = check_finite(q->rotation + 3 * r, "rotation row", index, e);
    for (int a = 0; a < 3 && s == BPX_OK; a++)
        if (q->half_extents[a] < 0.0f)
            s = bpx__error(e, BPX_ERR_INVALID_ARGUMENT, index, a,
                           "query %u: half extent %c %g is negative", index, axis_name[a],
                           (double)q->half_extents[a]);
    // Orthonormal: R^T R = I to 1e-3, so that the box is a box and the test's axes its own.
    for (int a = 0; a < 3 && s == BPX_OK; a++)
        for (int b = 0; b < 3 && s == BPX_OK; b++) {
            double dot = 0.0;
            for (int r = 0; r < 3; r++)
                dot += (double)q->rotation[3 * r + a] * (double)q->rotation[3 * r + b];
            if (fabs(dot - (a == b ? 1.0 : 0.0)) > 1e-3)
                s = bpx__error(e, BPX_ERR_INVALID_ARGUMENT, index, -1,
                               "query %u: rotation is not orthonormal (columns %d . %d = %g)",
                               index, a, b, dot);
        }
    return s;
}

static bpx_status check_query(const bpx_query *q, uint32_t index, bpx_error *e)
{
    if (q->closest && q->any)
        return bpx__error(e, BPX_ERR_INVALID_ARGUMENT, index, -1,
                          "query %u: closest and any both set (choose one)", index);
    switch (q->kind) {
    case BPX_QUERY_BOX:
        return check_box(&q->box, index, e);
    case BPX_QUERY_SPHERE: {
        bpx_status s = check_finite(q->centre, "centre", index, e);
        if (s == BPX_OK && !isfinite(q->radius))
            s = bpx__error(e, BPX_ERR_NOT_FINITE, index, -1, "query %u: radius is %g", index,
                           (double)q->radius);
        if (s == BPX_OK && q->radius < 0.0f)
            s = bpx__error(e, BPX_ERR_INVALID_ARGUMENT, index, -1,
                           "query %u: radius %g is negative", index, (double)q->radius);
        return s;
    }
    case BPX_QUERY_RAY: {
        bpx_status s = check_finite(q->origin, "origin", index, e);
        return s == BPX_OK ? check_motion(q, index, e) : s;
    }
    case BPX_QUERY_SWEEP: {
        bpx_status s = check_box(&q->box, index, e);
        return s == BPX_OK ? check_motion(q, index, e) : s;
    }
    case BPX_QUERY_ORIENTED:
        return check_oriented(q, index, e);
    default:
        return bpx__error(e, BPX_ERR_INVALID_ARGUMENT, index, -1, "query %u: unknown kind %d",
                          index, (int)q->kind);
    }
}

// ---------------------------------------------------------------------------------------------
// State, made by the first query: a world that is never queried holds none.

static bpx_query_state *state(bpx_world *w)
{
    if (!w->query) {
        w->query = bpx__alloc(sizeof *w->query);
        if (w->query)
            memset(w->query, 0, sizeof *w->query);
    }
    return w->query;
}

void bpx__query_free(bpx_world *w)
{
    bpx_query_state *q = w->query;
    if (!q)
        return;
    bpx__bvh_free(&q->tree);
    for (uint32_t c = 0; c < q->chunk_capacity; c++)
        bpx__hits_free(&q->chunks[c].hits);
    bpx__free(q->chunks, sizeof(bpx_query_chunk) * q->chunk_capacity);
    bpx__free(q->offsets, sizeof(size_t) * q->offset_capacity);
    bpx__hits_free(&q->results);
    bpx__free(q, sizeof *q);
    w->query = NULL;
}

bool bpx__query_callbacks_running(const bpx_world *w)
{
    return w->query && atomic_load_explicit(&w->query->in_callbacks, memory_order_acquire) > 0;
}

static bpx_query_view view(const bpx_world *w)
{
    return (bpx_query_view){&w->query->tree, w->category, w->mask, w->user_data, w->simd};
}

static bpx_status refuse_device_boxes(bpx_error *e)
{
    return bpx__error(e, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                      "query: the world's boxes are in a device buffer; set host boxes");
}

static bool reserve_chunks(bpx_query_state *q, uint32_t chunks, uint32_t queries)
{
    if (chunks > q->chunk_capacity) {
        void *memory = q->chunks;
        if (!bpx__grow(&memory, sizeof(bpx_query_chunk) * q->chunk_capacity,
                       sizeof(bpx_query_chunk) * chunks))
            return false;
        q->chunks = memory;
        memset(q->chunks + q->chunk_capacity, 0,
               sizeof(bpx_query_chunk) * (chunks - q->chunk_capacity));
        q->chunk_capacity = chunks;
    }
    if (queries + 1 > q->offset_capacity) {
        void *memory = q->offsets;
        if (!bpx__grow(&memory, sizeof(size_t) * q->offset_capacity,
                       sizeof(size_t) * ((size_t)queries + 1)))
            return false;
        q->offsets = memory;
        q->offset_capacity = queries + 1;
    }
    return true;
}

typedef struct batch_job {
    bpx_query_state *state;
    bpx_query_view view;
    const bpx_query *queries;
    uint32_t count;
} batch_job;

static void batch_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    batch_job *job = context;
    for (int c = begin; c < end; c++) {
        bpx_query_chunk *chunk = &job->state->chunks[c];
        chunk->hits.count = 0;
        chunk->status = BPX_OK;
        uint32_t first = (uint32_t)c * BPX_QUERY_CHUNK;
        uint32_t last = first + BPX_QUERY_CHUNK < job->count ? first + BPX_QUERY_CHUNK : job->count;
        for (uint32_t k = first; k < last; k++) {
            size_t before = chunk->hits.count;
            if (!bpx__query_run(&job->view, &job->queries[k], NULL, NULL, &chunk->hits)) {
                chunk->status = BPX_ERR_OUT_OF_MEMORY;
                break;
            }
            job->state->offsets[k + 1] = chunk->hits.count - before;
        }
    }
}

static bpx_status run_batch(bpx_world *w, const bpx_query *queries, uint32_t count)
{
    if (w->boxes_on_device)
        return refuse_device_boxes(&w->error);
    for (uint32_t k = 0; k < count; k++) {
        bpx_status s = check_query(&queries[k], k, &w->error);
        if (s != BPX_OK)
            return s;
    }
    bpx_query_state *q = state(w);
    uint32_t chunks = (count + BPX_QUERY_CHUNK - 1) / BPX_QUERY_CHUNK;
    if (!q || !reserve_chunks(q, chunks, count))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %u queries", count);
    q->results_valid = false;
    if (bpx__bvh_update(&q->tree, w) != BPX_OK)
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for the query tree over %u boxes", w->n);
    batch_job job = {q, view(w), queries, count};
    if (chunks > 1)
        bpx__parallel_for(&w->executor, batch_task, (int)chunks, &job);
    else if (chunks)
        batch_task(0, 1, 0, &job);
    size_t total = 0;
    q->offsets[0] = 0;
    for (uint32_t k = 0; k < count; k++)
        q->offsets[k + 1] = total += q->offsets[k + 1];
    for (uint32_t c = 0; c < chunks; c++)
        if (q->chunks[c].status != BPX_OK)
            return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                              "no memory for the hits of %u queries", count);
    q->results.count = 0;
    if (!bpx__hits_reserve(&q->results, total))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %zu hits", total);
    for (uint32_t c = 0; c < chunks; c++) {
        const bpx_hit_list *h = &q->chunks[c].hits;
        if (h->count)
            memcpy(q->results.hits + q->results.count, h->hits, sizeof(bpx_hit) * h->count);
        q->results.count += h->count;
    }
    q->query_count = count;
    q->results_valid = true;
    return BPX_OK;
}

bpx_status bpx_world_query_batch(bpx_world *w, const bpx_query *queries, uint32_t count,
                                 size_t *offsets, bpx_hit *hits, size_t capacity, size_t *total)
{
    bpx_status entered = bpx__world_enter(w, "query_batch");
    if (entered != BPX_OK)
        return entered;
    if ((count && !queries) || !offsets || !total || (capacity && !hits))
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "query_batch: queries, offsets, total or hits is NULL");
    bpx_status s = run_batch(w, queries, count);
    if (s != BPX_OK)
        return s;
    const bpx_query_state *q = w->query;
    memcpy(offsets, q->offsets, sizeof(size_t) * ((size_t)count + 1));
    *total = q->results.count;
    if (q->results.count > capacity)
        return bpx__error(&w->error, BPX_ERR_CAPACITY, UINT32_MAX, -1,
                          "query_batch: %zu hits, room for %zu", q->results.count, capacity);
    if (q->results.count)
        memcpy(hits, q->results.hits, sizeof(bpx_hit) * q->results.count);
    return BPX_OK;
}

bpx_status bpx_world_query(bpx_world *w, const bpx_query *query, bpx_hit *hits, size_t capacity,
                           size_t *count)
{
    bpx_status entered = bpx__world_enter(w, "query");
    if (entered != BPX_OK)
        return entered;
    if (!query || !count || (capacity && !hits))
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "query: query, count or hits is NULL");
    bpx_status s = run_batch(w, query, 1);
    if (s != BPX_OK)
        return s;
    const bpx_hit_list *r = &w->query->results;
    *count = r->count;
    if (r->count > capacity)
        return bpx__error(&w->error, BPX_ERR_CAPACITY, UINT32_MAX, -1,
                          "query: %zu hits, room for %zu", r->count, capacity);
    if (r->count)
        memcpy(hits, r->hits, sizeof(bpx_hit) * r->count);
    return BPX_OK;
}

bpx_status bpx_world_prepare_queries(bpx_world *w)
{
    bpx_status s = bpx__world_enter(w, "prepare_queries");
    if (s != BPX_OK)
        return s;
    if (w->boxes_on_device)
        return refuse_device_boxes(&w->error);
    bpx_query_state *q = state(w);
    if (!q || bpx__bvh_update(&q->tree, w) != BPX_OK)
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for the query tree over %u boxes", w->n);
    return BPX_OK;
}

// The checks of the read-only calls: the query, and a tree made from the current boxes.
static bpx_status check_shared(const bpx_world *w, const bpx_query *query, bpx_error *e)
{
    if (w->boxes_on_device)
        return refuse_device_boxes(e);
    bpx_status s = check_query(query, 0, e);
    if (s != BPX_OK)
        return s;
    const bpx_bvh *t = w->query ? &w->query->tree : NULL;
    if (!t || !t->valid || t->version != w->boxes_version)
        return bpx__error(e, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "query: the boxes changed since bpx_world_prepare_queries (or it was "
                          "never called)");
    return BPX_OK;
}

bpx_status bpx_world_query_shared(const bpx_world *w, const bpx_query *query, bpx_hit *hits,
                                  size_t capacity, size_t *count, bpx_error *err)
{
    bpx_error scratch;
    bpx_error *e = err ? err : &scratch;
    bpx__error_clear(e);
    if (!w || !query || !count || (capacity && !hits))
        return bpx__error(e, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "query_shared: world, query, count or hits is NULL");
    bpx_status s = check_shared(w, query, e);
    if (s != BPX_OK)
        return s;
    bpx_hit_list out = {hits, 0, capacity, true};
    bpx_query_view v = view(w);
    bpx__query_run(&v, query, NULL, NULL, &out); // a fixed list never runs out of memory
    *count = out.count;
    if (out.count > capacity)
        return bpx__error(e, BPX_ERR_CAPACITY, UINT32_MAX, -1, "query_shared: %zu hits, room for %zu",
                          out.count, capacity);
    return BPX_OK;
}

bpx_status bpx_world_query_each(const bpx_world *w, const bpx_query *query,
                                bpx_query_hit_fn *fn, void *context, bpx_error *err)
{
    bpx_error scratch;
    bpx_error *e = err ? err : &scratch;
    bpx__error_clear(e);
    if (!w || !query || !fn)
        return bpx__error(e, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "query_each: world, query or fn is NULL");
    if (query->closest || query->any)
        return bpx__error(e, BPX_ERR_INVALID_ARGUMENT, 0, -1,
                          "query_each: closest and any do not apply (the callback decides)");
    bpx_status s = check_shared(w, query, e);
    if (s != BPX_OK)
        return s;
    // Counted so that a callback calling back into the world to change it is refused (BAD_STATE)
    // instead of pulling the tree from under the walk.
    atomic_int *running = &w->query->in_callbacks;
    atomic_fetch_add_explicit(running, 1, memory_order_acq_rel);
    bpx_hit_list none = {NULL, 0, 0, true};
    bpx_query_view v = view(w);
    bpx__query_run(&v, query, fn, context, &none);
    atomic_fetch_sub_explicit(running, 1, memory_order_acq_rel);
    return BPX_OK;
}

const bpx_hit *bpx_world_query_hits(const bpx_world *w, const size_t **offsets,
                                    uint32_t *query_count, size_t *total)
{
    const bpx_query_state *q = w ? w->query : NULL;
    bool valid = q && q->results_valid;
    if (offsets)
        *offsets = valid ? q->offsets : NULL;
    if (query_count)
        *query_count = valid ? q->query_count : 0;
    if (total)
        *total = valid ? q->results.count : 0;
    return valid ? q->results.hits : NULL;
}

bpx_query_stats bpx_world_query_stats(const bpx_world *w)
{
    bpx_query_stats s = {0};
    if (w && w->query) {
        const bpx_bvh *t = &w->query->tree;
        s = (bpx_query_stats){t->builds, t->refits, t->node_count, t->item_count,
                              t->last_update_ns};
    }
    return s;
}
