// Periodic worlds: each cycle, the live boxes go to the image search (src/neighbors), which
// runs on a world of images kept between cycles, on this world's backend and workers. Its
// image pairs, exact and sorted by (i, j, shift), give the distinct pairs (i < j) that the
// world's filters and events then see as any world's.
#include "periodic.h"

#include <string.h>

#include "alloc.h"
#include "objects.h"
#include "validate.h"
#include "world.h"

bool bpx__world_periodic(const bpx_world *w)
{
    return w->def.period[0] > 0 || w->def.period[1] > 0 || w->def.period[2] > 0;
}

bpx_status bpx__period_check(const double period[3], bpx_error *err)
{
    for (int a = 0; a < 3; a++) {
        double p = period[a];
        // Past 2^1000 the image search's exact sums could overflow.
        if (!(p >= 0 && p < 0x1p1000))
            return bpx__error(err, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, a,
                              "period[%d] = %g: a period must be finite, >= 0 (0: open) and "
                              "below 2^1000",
                              a, p);
    }
    return BPX_OK;
}

// The world of images runs its parallel work on this world's workers: no threads of its own.
static void *run_on_world(bpx_task_fn *task, int item_count, int min_range, void *task_context,
                          void *user_context)
{
    (void)min_range;
    bpx__parallel_for(user_context, task, item_count, task_context);
    return NULL; // done already
}

static void finish_nothing(void *user_task, void *user_context)
{
    (void)user_task;
    (void)user_context;
}

// Room for n live boxes and their ids.
static bool reserve(bpx_periodic *p, uint32_t n)
{
    if (n <= p->capacity && p->boxes)
        return true;
    uint32_t want = n ? n : 1;
    bpx_box *boxes = bpx__alloc((size_t)want * sizeof *boxes);
    uint32_t *id = bpx__alloc((size_t)want * sizeof *id);
    if (!boxes || !id) {
        bpx__free(boxes, (size_t)want * sizeof *boxes);
        bpx__free(id, (size_t)want * sizeof *id);
        return false;
    }
    bpx__free(p->boxes, (size_t)p->capacity * sizeof *p->boxes);
    bpx__free(p->ids, (size_t)p->capacity * sizeof *p->ids);
    p->boxes = boxes;
    p->ids = id;
    p->capacity = want;
    return true;
}

bpx_status bpx__periodic_compare(bpx_world *w)
{
    bpx_periodic *p = &w->periodic;
    p->images.count = 0;
    uint32_t n = w->n;
    bool removed = false;
    for (uint32_t i = 0; w->dead && i < n && !removed; i++)
        removed = w->dead[i] != 0;
    // Float64 boxes (all live: they are set whole), and float32 boxes with no id removed, are
    // searched where they lie; only a world with removed ids copies its live boxes out.
    const bpx_box_arrays *b = &w->boxes;
    bpx__soa_boxes soa = {.lo = {b->lo[0], b->lo[1], b->lo[2]},
                          .hi = {b->hi[0], b->hi[1], b->hi[2]}};
    if (w->bounds_set && w->bounds_version == w->boxes_version) { // set_boxes found them
        soa.low = w->bounds_low;
        soa.most = w->bounds_most;
    }
    bpx_neighbor_def def = bpx_default_neighbor_def();
    def.format = w->boxes64_set ? BPX_BOXES_F64 : BPX__BOXES_SOA;
    const void *data = w->boxes64_set ? (const void *)w->boxes64 : (const void *)&soa;
    uint32_t live = n;
    if (removed && !w->boxes64_set) {
        if (!reserve(p, n))
            return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                              "no memory for %u boxes of a periodic world", n);
        // The live boxes, in id order (removed ids hold inert boxes, which the search
        // refuses): ids keep their order, so the search's (i, j, shift) order is the ids'.
        live = 0;
        for (uint32_t i = 0; i < n; i++) {
            if (w->dead[i])
                continue;
            for (int a = 0; a < 3; a++) {
                p->boxes[live].min[a] = b->lo[a][i];
                p->boxes[live].max[a] = b->hi[a][i];
            }
            p->ids[live++] = i;
        }
        def.format = BPX_BOXES_F32;
        data = p->boxes;
    }
    removed = removed && !w->boxes64_set;
    memcpy(def.period, w->def.period, sizeof def.period);
    def.backend = w->def.backend;
    def.worker_count = w->executor.worker_count;
    // The world of images: this world's definition, open, no events, margins or hooks of the
    // caller's (its work goes to this world's executor).
    bpx_world_def inner = w->def;
    memset(inner.period, 0, sizeof inner.period);
    inner.track_events = false;
    inner.begin_margin = inner.end_margin = 0;
    inner.capacity_hint = 0;
    inner.worker_count = w->executor.worker_count;
    inner.enqueue_task = run_on_world;
    inner.finish_task = finish_nothing;
    inner.user_task_context = &w->executor;
    bpx_error err;
    bpx_status status =
        bpx__find_neighbors_kept(&def, data, live, &p->search, &inner, &p->images, &err);
    if (status != BPX_OK) {
        if (err.index < live && removed) // the search counts live boxes only: name the id
            return bpx__error(&w->error, status, p->ids[err.index], err.axis,
                              "periodic collide (%s), box id %u (the search's object %u): %s",
                              bpx_backend_name(w->def.backend), p->ids[err.index], err.index,
                              err.message);
        return bpx__error(&w->error, status, err.index, err.axis, "periodic collide (%s): %s",
                          bpx_backend_name(w->def.backend), err.message);
    }
    bpx_image_pair *images = p->images.pairs;
    size_t count = p->images.count;
    for (size_t k = 0; removed && k < count; k++) {
        images[k].i = p->ids[images[k].i];
        images[k].j = p->ids[images[k].j];
    }
    // The distinct pairs, in (i, j) order as the images are, into one block.
    bpx_block *block;
    status = bpx__emitter_one_block(&w->emitter, n, &block);
    if (status == BPX_OK && !bpx__list_reserve(&block->hits, count))
        status = BPX_ERR_OUT_OF_MEMORY;
    if (status != BPX_OK)
        return bpx__error(&w->error, status, UINT32_MAX, -1,
                          "no memory for the pairs of %zu periodic images", count);
    bpx_pair *hits = block->hits.pairs;
    size_t distinct = 0;
    for (size_t k = 0; k < count; k++) {
        bpx_pair q = {images[k].i, images[k].j};
        bool fresh = q.i != q.j && (distinct == 0 || hits[distinct - 1].i != q.i ||
                                    hits[distinct - 1].j != q.j);
        hits[distinct] = q;
        distinct += fresh;
    }
    block->hits.count = distinct;
    bpx_cycle_stats inner_stats = bpx_world_stats(p->search.inner);
    block->tests = inner_stats.pair_tests;
    w->stats.rebuilt = inner_stats.rebuilt;
    w->stats.transfer_in_ns = inner_stats.transfer_in_ns;
    w->stats.transfer_out_ns = inner_stats.transfer_out_ns;
    w->stats.device_ns = inner_stats.device_ns;
    w->stats.bytes_in = inner_stats.bytes_in;
    w->stats.bytes_out = inner_stats.bytes_out;
    w->stats.device_share = inner_stats.device_share;
    return BPX_OK;
}

void bpx__periodic_filter_images(bpx_world *w)
{
    if (!bpx__objects_filtering(w))
        return; // every pair found passed
    bpx_image_pair *images = w->periodic.images.pairs;
    size_t count = w->periodic.images.count, kept = 0, at = 0;
    const bpx_pair_list *pairs = &w->emitter.blocks[0].hits; // the one block, filtered
    for (size_t k = 0; k < count; k++) {
        bpx_image_pair q = images[k];
        bool keep;
        if (q.i == q.j) {
            keep = bpx__objects_may_pair(w, q.i, q.i);
        } else {
            bpx_pair key = {q.i, q.j};
            while (at < pairs->count && bpx__pair_less(pairs->pairs[at], key))
                at++;
            keep = at < pairs->count && pairs->pairs[at].i == q.i && pairs->pairs[at].j == q.j;
        }
        images[kept] = q;
        kept += keep;
    }
    w->periodic.images.count = kept;
}

bpx_backend bpx__periodic_backend(const bpx_world *w)
{
    const bpx_world *inner = w->periodic.search.inner;
    return inner ? bpx_world_backend(inner) : BPX_BACKEND_COUNT;
}

void bpx__periodic_free(bpx_periodic *p)
{
    bpx__search_keep_free(&p->search);
    bpx__free(p->boxes, (size_t)p->capacity * sizeof *p->boxes);
    bpx__free(p->ids, (size_t)p->capacity * sizeof *p->ids);
    bpx_neighbor_list_free(&p->images);
    *p = (bpx_periodic){0};
}
