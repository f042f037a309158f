// The interface (world lifetime, counts, timings) and each cycle's comparator and emitter;
// the updater (the boxes in SoA form) is updater.c.
#include "world.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "alloc.h"
#include "boxes.h"
#include "clock.h"
#include "log.h"
#include "objects.h"
#include "transpose.h"
#include "validate.h"

// Names of every backend id; an id whose implementation is not in this build has no entry in
// `backends` and reports itself unavailable.
static const char *const backend_names[BPX_BACKEND_COUNT] = {
    [BPX_BACKEND_AUTO] = "auto",   [BPX_BACKEND_REFERENCE] = "reference",
    [BPX_BACKEND_BRUTE] = "brute", [BPX_BACKEND_PRUNE] = "prune",
    [BPX_BACKEND_SAP] = "sap",     [BPX_BACKEND_GRID] = "grid",
    [BPX_BACKEND_MODEL] = "model", [BPX_BACKEND_OPENCL] = "opencl",
    [BPX_BACKEND_CUDA] = "cuda",
    [BPX_BACKEND_HYBRID] = "hybrid", [BPX_BACKEND_RTL] = "rtl",
};

static const bpx_backend_impl *const backends[BPX_BACKEND_COUNT] = {
    [BPX_BACKEND_AUTO] = &bpx__auto_backend,
    [BPX_BACKEND_REFERENCE] = &bpx__reference_backend,
    [BPX_BACKEND_BRUTE] = &bpx__brute_backend,
    [BPX_BACKEND_PRUNE] = &bpx__prune_backend,
    [BPX_BACKEND_SAP] = &bpx__sap_backend,
    [BPX_BACKEND_GRID] = &bpx__grid_backend,
#if BPX_HAVE_MODEL
    [BPX_BACKEND_MODEL] = &bpx__model_backend,
#endif
#if BPX_HAVE_OPENCL
    [BPX_BACKEND_OPENCL] = &bpx__opencl_backend,
#endif
#if BPX_HAVE_CUDA
    [BPX_BACKEND_CUDA] = &bpx__cuda_backend,
#endif
    [BPX_BACKEND_HYBRID] = &bpx__hybrid_backend,
    [BPX_BACKEND_RTL] = &bpx__rtl_backend, // without Verilator, a stub that says so
};

enum { MAX_WORKERS = 256, DEFAULT_SPIN_US = 200 };

bpx_world_def bpx_default_world_def(void)
{
    return (bpx_world_def){.backend = BPX_BACKEND_AUTO, .simd = BPX_SIMD_AUTO, .worker_count = 1};
}

// ---------------------------------------------------------------------------------------------
// Backends

const char *bpx_backend_name(bpx_backend backend)
{
    return (unsigned)backend < BPX_BACKEND_COUNT ? backend_names[backend] : NULL;
}

bpx_status bpx_backend_from_name(const char *name, bpx_backend *out)
{
    if (!name || !out)
        return BPX_ERR_NULL_ARGUMENT;
    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        const char *candidate = bpx_backend_name((bpx_backend)b);
        if (candidate && strcmp(candidate, name) == 0) {
            *out = (bpx_backend)b;
            return BPX_OK;
        }
    }
    return BPX_ERR_UNKNOWN_BACKEND;
}

static bpx_backend_info query_with(bpx_backend backend, const bpx_world_def *def)
{
    bpx_backend_info info = {.backend = backend, .name = bpx_backend_name(backend), .reason = ""};
    if (!info.name) {
        info.name = "?";
        info.reason = "no such backend";
        return info;
    }
    const bpx_backend_impl *impl = backends[backend];
    if (!impl) {
        info.reason = "not in this build";
        return info;
    }
    info.available = impl->query(def, &info.reason, info.detail, sizeof info.detail);
    return info;
}

bpx_backend_info bpx_backend_query(bpx_backend backend)
{
    bpx_world_def def = bpx_default_world_def();
    return query_with(backend, &def);
}

// ---------------------------------------------------------------------------------------------
// Lifetime

static void free_boxes(bpx_world *w)
{
    bpx__box_arrays_free(&w->boxes);
    bpx__box_arrays_free(&w->spare);
    bpx__box_arrays_free(&w->grown);
    for (int a = 0; a < 3; a++) {
        bpx__free(w->minima[a], sizeof(float) * w->extent_capacity);
        w->minima[a] = NULL;
    }
    w->extent_capacity = 0;
}

bpx_status bpx_world_def_check(const bpx_world_def *def, bpx_error *err)
{
    bpx__error_clear(err);
    if (!def)
        return bpx__error(err, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "def is NULL");
    const char *what = NULL;
    if (def->worker_count < 0 || def->worker_count > MAX_WORKERS)
        what = "worker_count is outside 0..256";
    else if ((unsigned)def->backend >= BPX_BACKEND_COUNT)
        what = "backend is not a bpx_backend";
    else if ((unsigned)def->simd >= BPX_SIMD_COUNT)
        what = "simd is not a bpx_simd";
    else if (!def->enqueue_task != !def->finish_task)
        what = "enqueue_task and finish_task must be given both or neither";
    else if (def->capacity_hint > BPX_MAX_BOXES)
        what = "capacity_hint is past BPX_MAX_BOXES";
    else if (!(def->hybrid_device_share >= 0.0f && def->hybrid_device_share <= 1.0f))
        what = "hybrid_device_share is outside [0, 1]";
    else if (!(def->begin_margin >= 0.0f && def->begin_margin <= FLT_MAX))
        what = "begin_margin must be finite and >= 0";
    else if (!(def->end_margin == 0.0f ||
               (def->end_margin >= def->begin_margin && def->end_margin <= FLT_MAX)))
        what = "end_margin must be 0, or finite and >= begin_margin";
    if (what)
        return bpx__error(err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1, "%s", what);
    bpx_status status = bpx__period_check(def->period, err);
    if (status != BPX_OK)
        return status;
    bool periodic = def->period[0] > 0 || def->period[1] > 0 || def->period[2] > 0;
    if (periodic && (def->begin_margin > 0.0f || def->end_margin > 0.0f))
        return bpx__error(err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "contact margins on a periodic world are not supported: set "
                          "begin_margin and end_margin to 0, or leave period at 0");
    return BPX_OK;
}

bpx_status bpx_world_create(const bpx_world_def *def, bpx_world **out_world)
{
    if (!out_world)
        return BPX_ERR_NULL_ARGUMENT;
    *out_world = NULL;
    if (!def)
        return BPX_ERR_NULL_ARGUMENT;
    bpx_error err;
    bpx_status checked = bpx_world_def_check(def, &err);
    if (checked != BPX_OK) {
        bpx__log(0, "bpx_world_create: %s", err.message); // no world to keep the message in
        return checked;
    }

    bpx_backend resolved = def->backend;
    const char *reason;
    char detail[96];
    if (!backends[resolved] || !bpx_simd_supported(def->simd) ||
        !backends[resolved]->query(def, &reason, detail, sizeof detail))
        return BPX_ERR_BACKEND_UNAVAILABLE;

    bpx_world *w = bpx__alloc(sizeof *w);
    if (!w)
        return BPX_ERR_OUT_OF_MEMORY;
    *w = (bpx_world){.def = *def, .backend = backends[resolved]};
    w->emitter.planned_n = UINT32_MAX;
    w->def.worker_count = def->worker_count ? def->worker_count : 1;
    w->def.spin_us = def->spin_us ? def->spin_us : DEFAULT_SPIN_US;
    w->simd = def->simd == BPX_SIMD_AUTO ? bpx_simd_best() : def->simd;
    if (w->def.end_margin == 0.0f)
        w->def.end_margin = w->def.begin_margin;
    bpx__error_clear(&w->error);
    w->executor = (bpx_executor){
        .worker_count = w->def.worker_count,
        .enqueue_task = def->enqueue_task,
        .finish_task = def->finish_task,
        .user_task_context = def->user_task_context,
    };
    bool ok = bpx__box_arrays_reserve(&w->boxes, def->capacity_hint) &&
              bpx__box_arrays_reserve(&w->spare, def->capacity_hint);
    if (ok && !def->enqueue_task && w->def.worker_count > 1)
        ok = (w->executor.pool = bpx__pool_create(w->def.worker_count - 1, w->def.spin_us));
    if (!ok) {
        bpx_world_destroy(w);
        return BPX_ERR_OUT_OF_MEMORY;
    }
    bpx__box_arrays_pad(&w->boxes, 0);
    *out_world = w;
    return BPX_OK;
}

void bpx_world_destroy(bpx_world *w)
{
    if (!w)
        return;
    bpx__pool_destroy(w->executor.pool);
    if (w->backend_state && w->backend->destroy)
        w->backend->destroy(w->backend_state);
    bpx__emitter_free(&w->emitter);
    bpx__list_free(&w->pairs);
    bpx__objects_free(w);
    bpx__query_free(w);
    bpx__periodic_free(&w->periodic);
    bpx__free(w->boxes64, (size_t)w->boxes64_capacity * sizeof *w->boxes64);
    free_boxes(w);
    bpx__free(w, sizeof *w);
}

const bpx_error *bpx_world_error(const bpx_world *w)
{
    static const bpx_error null_world = {BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "world is NULL"};
    return w ? &w->error : &null_world;
}

uint32_t bpx_world_box_count(const bpx_world *w)
{
    return w ? w->n : 0;
}

bpx_backend bpx_world_backend(const bpx_world *w)
{
    if (!w)
        return BPX_BACKEND_AUTO;
    if (bpx__world_periodic(w) && bpx__periodic_backend(w) != BPX_BACKEND_COUNT)
        return bpx__periodic_backend(w); // the world of images ran the cycle
    return w->backend->id == BPX_BACKEND_AUTO ? bpx__auto_choice(w->backend_state, w->n)
                                              : w->backend->id;
}

const void *bpx__world_backend_state(const bpx_world *w, const bpx_backend_impl *backend)
{
    return w && w->backend == backend ? w->backend_state : NULL;
}

bpx_simd bpx_world_simd(const bpx_world *w)
{
    return w ? w->simd : BPX_SIMD_AUTO;
}

bpx_cycle_stats bpx_world_stats(const bpx_world *w)
{
    return w ? w->stats : (bpx_cycle_stats){0};
}

// ---------------------------------------------------------------------------------------------
// Every call that changes the world enters here

bpx_status bpx__world_enter(bpx_world *w, const char *call)
{
    if (!w)
        return BPX_ERR_NULL_ARGUMENT;
    bpx__error_clear(&w->error);
    if (w->in_callback || bpx__query_callbacks_running(w))
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "%s: called from a callback of this world (a pair filter, or "
                          "bpx_world_query_each's); a callback must not change the world",
                          call);
    return BPX_OK;
}

// Float64 boxes: the comparator's candidates (float32 boxes rounded outward) kept where the
// doubles overlap. Closed intervals of doubles compare exactly: no sums, nothing rounded.
static void filter_boxes64(bpx_world *w)
{
    const bpx_box64 *b = w->boxes64;
    for (int k = 0; k < w->emitter.block_count; k++) {
        bpx_pair_list *hits = &w->emitter.blocks[k].hits;
        size_t kept = 0;
        for (size_t h = 0; h < hits->count; h++) {
            bpx_pair p = hits->pairs[h];
            const bpx_box64 *x = &b[p.i], *y = &b[p.j];
            bool yes = true;
            for (int a = 0; a < 3; a++)
                yes &= y->min[a] <= x->max[a] && x->min[a] <= y->max[a];
            hits->pairs[kept] = p;
            kept += yes;
        }
        hits->count = kept;
    }
}

// ---------------------------------------------------------------------------------------------
// Comparator + emitter

// The blocks' pairs, concatenated into the world's own list (total from bpx__emitter_total).
static bool merge_own(bpx_world *w, size_t total)
{
    w->pairs.count = 0;
    // A sixteenth over what is needed, not the next power of two: this list is one of the
    // biggest a world holds (10M boxes: 5M pairs, 40 MB), and totals move little between cycles.
    if (w->pairs.capacity < total) {
        size_t capacity = total + total / 16 + 64;
        if (capacity > SIZE_MAX / sizeof(bpx_pair) ||
            !bpx__grow((void **)&w->pairs.pairs, w->pairs.capacity * sizeof(bpx_pair),
                       capacity * sizeof(bpx_pair)))
            return false;
        w->pairs.capacity = capacity;
    }
    bpx__emitter_merge(&w->emitter, w->pairs.pairs);
    w->pairs.count = total;
    w->merged = true;
    return true;
}

// Gives back the blocks' hits and the merged list after a cycle that ran out of memory or pairs.
static void release_pairs(bpx_world *w)
{
    bpx__emitter_release(&w->emitter);
    bpx__list_free(&w->pairs);
}

// Runs the comparator into the blocks. On success *total is the number of pairs, and *end the
// clock when it ended (the emitter's start: one clock read fewer per cycle).
static bpx_status compare(bpx_world *w, size_t *total, uint64_t *end)
{
    w->merged = false;
    w->result_valid = false; // the blocks are about to change: no reads of them until done
    // Last cycle's events go with its pairs: a cycle that fails shows neither (the next
    // successful one reports against the last successful one, whose pairs objects.c keeps).
    w->events_valid = false;
    w->stats.pair_count = 0;
    w->stats.stage_count = 0;
    if (w->def.profile) { // the updater's last call first (a collide without one shows none)
        w->profile.count = 0;
        if (w->update_stage.name)
            w->profile.stage[w->profile.count++] = w->update_stage;
        w->update_stage = (bpx_stage_stats){0};
    }
    uint64_t start = bpx__now_ns();
    bpx_cycle cycle = bpx__world_cycle(w);
    bool periodic = bpx__world_periodic(w);
    if (bpx__world_margins(w)) { // the comparator sees the boxes grown; the gaps decide after
        if (!bpx__margins_grow_boxes(w))
            return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                              "no memory for %u boxes grown by the contact margin", w->n);
        const bpx_box_arrays *g = &w->grown;
        cycle.boxes = (bpx_soa){{g->lo[0], g->lo[1], g->lo[2]}, {g->hi[0], g->hi[1], g->hi[2]}, w->n};
    }
    bpx_status status;
    if (periodic) {
        status = bpx__periodic_compare(w); // fills the stats of the backend's report itself
    } else {
        // The spare set is dead until the next update writes it whole: the backend's scratch
        // (the grid's entries, most of its memory). After the first update it is not there yet
        // (that update's set became the boxes): made now, since the next update makes it
        // anyway, so that the backend sizes its own memory for what it borrows from the first
        // cycle on. Without memory for it the cycle just lends nothing.
        if (w->spare.capacity < w->boxes.capacity)
            (void)bpx__box_arrays_reserve(&w->spare, w->n);
        cycle.scratch = w->spare.lo[0];
        cycle.scratch_bytes = 6 * sizeof(float) * (size_t)w->spare.capacity;
        status = w->backend->compare(&w->backend_state, &cycle);
        const bpx_backend_report *r = &cycle.report;
        w->stats.rebuilt = r->rebuilt;
        w->stats.transfer_in_ns = r->transfer_in_ns;
        w->stats.transfer_out_ns = r->transfer_out_ns;
        w->stats.device_ns = r->device_ns;
        w->stats.bytes_in = r->bytes_in;
        w->stats.bytes_out = r->bytes_out;
        w->stats.device_share = r->device_share;
    }
    if (status == BPX_OK && w->boxes64_set && !periodic) // the image search decided them
        filter_boxes64(w);
    if (status == BPX_OK) {
        bpx__filter_blocks(w);
        bpx__margins_filter_blocks(w);
        status = bpx__pair_filter_blocks(w);
    }
    if (status == BPX_OK && periodic)
        bpx__periodic_filter_images(w);
    if (status == BPX_OK)
        status = bpx__emitter_total(&w->emitter, total);
    *end = bpx__now_ns();
    w->stats.compare_ns = *end - start;
    w->result_valid = status == BPX_OK; // nothing partial is ever reported
    if (status == BPX_ERR_OUT_OF_MEMORY || status == BPX_ERR_TOO_MANY_PAIRS)
        release_pairs(w); // a cycle too big for memory leaves none of it held
    // A backend that named what failed (a device box, its index and axis; the failing call)
    // keeps its error; the callers cleared it before the cycle.
    if (status != BPX_OK && w->error.status != status) {
        return bpx__error(&w->error, status, UINT32_MAX, -1, "%s, %u boxes: %s",
                          w->backend->name, w->n, bpx_status_string(status));
    }
    if (status != BPX_OK)
        return status;
    uint64_t tests = 0;
    for (int b = 0; b < w->emitter.block_count; b++)
        tests += w->emitter.blocks[b].tests;
    w->stats.pair_tests = tests;
    w->stats.pair_count = *total;
    w->stats.cycle_count++;
    return BPX_OK;
}

// A profiled cycle's stages, into the stats.
static void profile_done(bpx_world *w)
{
    if (!w->def.profile)
        return;
    w->stats.stage_count = w->profile.count;
    memcpy(w->stats.stages, w->profile.stage, sizeof(bpx_stage_stats) * w->profile.count);
}

bpx_status bpx_world_collide(bpx_world *w)
{
    bpx_status entered = bpx__world_enter(w, "collide");
    if (entered != BPX_OK)
        return entered;
    size_t total = 0;
    uint64_t start = 0;
    bpx_status status = compare(w, &total, &start);
    if (status != BPX_OK)
        return status;
    if (!merge_own(w, total)) {
        w->result_valid = false;
        release_pairs(w);
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %zu pairs", total);
    }
    if (w->def.profile) // the blocks' pairs copied into the world's list
        bpx__profile_add_ns(&w->profile, "world", "merge", bpx__now_ns() - start,
                            BPX_ACCESS_SEQUENTIAL, 8 * (uint64_t)total, 8 * (uint64_t)total, 0);
    status = bpx__objects_after_collide(w, w->pairs.pairs, total);
    w->stats.emit_ns = bpx__now_ns() - start;
    profile_done(w);
    if (status != BPX_OK) {
        w->result_valid = false;
        return bpx__error(&w->error, status, UINT32_MAX, -1, "no memory for pair events");
    }
    return BPX_OK;
}

bpx_status bpx_world_collide_into(bpx_world *w, bpx_pair *out, size_t capacity, size_t *count)
{
    bpx_status entered = bpx__world_enter(w, "collide_into");
    if (entered != BPX_OK)
        return entered;
    if (!count || (!out && capacity > 0))
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "count is NULL, or out is NULL with capacity > 0");
    size_t total = 0;
    uint64_t compared = 0;
    bpx_status status = compare(w, &total, &compared);
    *count = total;
    if (status != BPX_OK)
        return status;
    if (w->def.track_events || w->pending_count || bpx__world_margins(w)) {
        // Events and margins need the whole ordered set; the world's own copy serves them.
        if (!bpx_world_pairs(w, NULL) && total > 0)
            status = BPX_ERR_OUT_OF_MEMORY;
        if (status == BPX_OK)
            status = bpx__objects_after_collide(w, w->pairs.pairs, total);
        if (status != BPX_OK) {
            w->result_valid = false;
            return bpx__error(&w->error, status, UINT32_MAX, -1, "no memory for pair events");
        }
    }
    if (total > capacity) {
        profile_done(w); // the cycle ran: its stages so far (the pairs stay in the blocks)
        return bpx__error(&w->error, BPX_ERR_CAPACITY, UINT32_MAX, -1,
                          "%zu pairs found, capacity %zu", total, capacity);
    }
    uint64_t start = bpx__now_ns();
    bpx__emitter_merge(&w->emitter, out);
    w->stats.emit_ns = bpx__now_ns() - start;
    if (w->def.profile) { // the blocks' pairs copied into the caller's array
        bpx__profile_add_ns(&w->profile, "world", "merge", w->stats.emit_ns,
                            BPX_ACCESS_SEQUENTIAL, 8 * (uint64_t)total, 8 * (uint64_t)total, 0);
        profile_done(w);
    }
    return BPX_OK;
}

// The blocks keep the last cycle's pairs until the next compare, so the world's own merged copy
// is made only when asked for (after collide_into).
const bpx_pair *bpx_world_pairs(bpx_world *w, size_t *count)
{
    if (count)
        *count = 0;
    if (!w)
        return NULL;
    size_t total = 0;
    if (!w->result_valid || bpx__emitter_total(&w->emitter, &total) != BPX_OK)
        return NULL;
    if (!w->merged && !merge_own(w, total)) {
        bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                   "no memory to merge %zu pairs", total);
        return NULL;
    }
    if (count)
        *count = total;
    return w->pairs.pairs;
}

const bpx_image_pair *bpx_world_image_pairs(bpx_world *w, size_t *count)
{
    if (count)
        *count = 0;
    size_t total = 0;
    if (!w || !w->result_valid || bpx__emitter_total(&w->emitter, &total) != BPX_OK)
        return NULL;
    bpx_neighbor_list *images = &w->periodic.images;
    if (!bpx__world_periodic(w)) {
        // An open world's images are its pairs, shift 0: made when asked for.
        const bpx_pair *pairs = bpx_world_pairs(w, NULL);
        if (!pairs && total > 0)
            return NULL; // no memory to merge them; the world's error says so
        images->count = 0;
        if (total > images->capacity) {
            bpx_neighbor_list_free(images);
            images->pairs = bpx__alloc(total * sizeof *images->pairs);
            if (!images->pairs) {
                bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                           "no memory for %zu image pairs", total);
                return NULL;
            }
            images->capacity = total;
        }
        for (size_t k = 0; k < total; k++)
            images->pairs[k] = (bpx_image_pair){pairs[k].i, pairs[k].j, {0, 0, 0}};
        images->count = total;
    }
    if (count)
        *count = images->count;
    return images->pairs;
}

void bpx_world_period(const bpx_world *w, double period[3])
{
    for (int a = 0; a < 3 && period; a++)
        period[a] = w ? w->def.period[a] : 0;
}

bpx_status bpx_world_copy_pairs(const bpx_world *w, bpx_pair *out, size_t capacity,
                                size_t *count)
{
    if (!w || !count || (!out && capacity > 0))
        return BPX_ERR_NULL_ARGUMENT;
    size_t total = 0;
    if (!w->result_valid || bpx__emitter_total(&w->emitter, &total) != BPX_OK)
        total = 0;
    *count = total;
    if (total > capacity)
        return BPX_ERR_CAPACITY;
    if (total > 0)
        bpx__emitter_merge(&w->emitter, out);
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// One-shot

bpx_status bpx_validate_boxes(const bpx_box *boxes, uint32_t n, bpx_error *err)
{
    bpx__error_clear(err);
    if (n > BPX_MAX_BOXES)
        return bpx__error(err, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "%u boxes exceed BPX_MAX_BOXES (%u)", n, BPX_MAX_BOXES);
    if (!boxes && n > 0)
        return bpx__error(err, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "boxes is NULL");
    return bpx__check_boxes(boxes, n, err);
}

bpx_status bpx_find_pairs(const bpx_box *boxes, uint32_t n, bpx_backend backend, bpx_pair *out,
                          size_t capacity, size_t *count, bpx_error *err)
{
    bpx__error_clear(err);
    if (!count || (!out && capacity > 0))
        return bpx__error(err, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "count is NULL, or out is NULL with capacity > 0");
    *count = 0;
    bpx_status status = bpx_validate_boxes(boxes, n, err);
    if (status != BPX_OK)
        return status;
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.capacity_hint = n;
    bpx_world *w;
    status = bpx_world_create(&def, &w);
    if (status != BPX_OK)
        return bpx__error(err, status, UINT32_MAX, -1, "%s", bpx_status_string(status));
    status = bpx_world_set_boxes(w, boxes, n);
    if (status == BPX_OK)
        status = bpx_world_collide_into(w, out, capacity, count);
    if (status != BPX_OK && err)
        *err = w->error;
    bpx_world_destroy(w);
    return status;
}
