// Objects added and removed between cycles, collision filters, and begin/end pair events.
#include "objects.h"

#include <string.h>

#include "alloc.h"
#include "boxes.h"
#include "validate.h"

// ---------------------------------------------------------------------------------------------
// Per-id arrays

static void free_object_arrays(bpx_world *w)
{
    size_t cap = w->object_capacity;
    bpx__free(w->dead, cap);
    bpx__free(w->pending_ids, cap * sizeof(uint32_t));
    bpx__free(w->free_ids, cap * sizeof(uint32_t));
    bpx__free(w->category, cap * sizeof(uint32_t));
    bpx__free(w->mask, cap * sizeof(uint32_t));
    w->dead = NULL;
    w->pending_ids = w->free_ids = w->category = w->mask = NULL;
    w->object_capacity = 0;
}

// Grows the per-id arrays to hold n ids, keeping contents; new ids are live and unfiltered.
static bool reserve_objects(bpx_world *w, uint32_t n)
{
    uint32_t old = w->object_capacity;
    if (n <= old && w->dead)
        return true;
    uint32_t cap = old ? old : 64;
    while (cap < n)
        cap = cap > UINT32_MAX / 2 ? n : cap * 2;
    uint8_t *dead = bpx__alloc(cap);
    uint32_t *pending = bpx__alloc(cap * sizeof(uint32_t));
    uint32_t *freed = bpx__alloc(cap * sizeof(uint32_t));
    uint32_t *category = w->category ? bpx__alloc(cap * sizeof(uint32_t)) : NULL;
    uint32_t *mask = w->mask ? bpx__alloc(cap * sizeof(uint32_t)) : NULL;
    if (!dead || !pending || !freed || (w->category && (!category || !mask))) {
        bpx__free(dead, cap);
        bpx__free(pending, cap * sizeof(uint32_t));
        bpx__free(freed, cap * sizeof(uint32_t));
        bpx__free(category, cap * sizeof(uint32_t));
        bpx__free(mask, cap * sizeof(uint32_t));
        return false;
    }
    memset(dead, 0, cap);
    if (w->dead) {
        memcpy(dead, w->dead, old);
        memcpy(pending, w->pending_ids, w->pending_count * sizeof(uint32_t));
        memcpy(freed, w->free_ids, w->free_count * sizeof(uint32_t));
    }
    if (category) {
        memcpy(category, w->category, old * sizeof(uint32_t));
        memcpy(mask, w->mask, old * sizeof(uint32_t));
        for (uint32_t id = old; id < cap; id++)
            category[id] = 1, mask[id] = UINT32_MAX;
    }
    uint32_t pending_count = w->pending_count, free_count = w->free_count;
    free_object_arrays(w);
    w->dead = dead;
    w->pending_ids = pending;
    w->free_ids = freed;
    w->category = category;
    w->mask = mask;
    w->pending_count = pending_count;
    w->free_count = free_count;
    w->object_capacity = cap;
    return true;
}

bool bpx__objects_reset(bpx_world *w, uint32_t n)
{
    if (!w->dead) // never used: nothing to reset, and set_boxes stays free of extra work
        return true;
    if (!reserve_objects(w, n))
        return false;
    if (w->category) {
        // A filter lasts while its id holds a box: ids kept (below the old and the new n, and
        // not removed) keep theirs; the rest start again unfiltered. w->n is still the old n.
        uint32_t kept = n < w->n ? n : w->n;
        for (uint32_t id = 0; id < w->object_capacity; id++)
            if (id >= kept || w->dead[id])
                w->category[id] = 1, w->mask[id] = UINT32_MAX;
    }
    memset(w->dead, 0, w->object_capacity);
    w->pending_count = w->free_count = 0;
    return true;
}

void bpx__objects_reinert(bpx_world *w)
{
    for (uint32_t k = 0; k < w->pending_count; k++)
        bpx__box_make_inert(w, w->pending_ids[k]);
    for (uint32_t k = 0; k < w->free_count; k++)
        bpx__box_make_inert(w, w->free_ids[k]);
}

void bpx__objects_free(bpx_world *w)
{
    free_object_arrays(w);
    bpx_pair_list *lists[] = {&w->previous, &w->began, &w->ended};
    for (int k = 0; k < 3; k++) {
        bpx__free(lists[k]->pairs, lists[k]->capacity * sizeof(bpx_pair));
        *lists[k] = (bpx_pair_list){0};
    }
}

// ---------------------------------------------------------------------------------------------
// Add, remove, move

bpx_status bpx_world_add_boxes(bpx_world *w, const bpx_box *boxes, uint32_t count,
                               uint32_t *out_ids)
{
    if (!w)
        return BPX_ERR_NULL_ARGUMENT;
    bpx__error_clear(&w->error);
    if (count && (!boxes || !out_ids))
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "boxes or out_ids is NULL");
    if (w->extents_loaded)
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "add_boxes: the world is in the two-phase mode (load_extents)");
    // The count first: a count past the limit is refused before its boxes are read.
    uint32_t reused = count < w->free_count ? count : w->free_count;
    uint64_t new_n = (uint64_t)w->n + (count - reused);
    if (new_n > BPX_MAX_BOXES)
        return bpx__error(&w->error, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "add_boxes: %u boxes added to %u make %llu, past BPX_MAX_BOXES (%u)",
                          count, w->n, (unsigned long long)new_n, BPX_MAX_BOXES);
    bpx_status status = bpx__check_boxes(boxes, count, &w->error);
    if (status != BPX_OK)
        return status;
    uint32_t old_n = w->n;
    if (!reserve_objects(w, (uint32_t)new_n) || !bpx__boxes_resize(w, (uint32_t)new_n))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %llu boxes", (unsigned long long)new_n);
    for (uint32_t k = 0; k < count; k++) {
        uint32_t id = k < reused ? w->free_ids[--w->free_count] : old_n + (k - reused);
        w->dead[id] = 0;
        if (w->category)
            w->category[id] = 1, w->mask[id] = UINT32_MAX;
        bpx__box_set(w, id, &boxes[k]);
        out_ids[k] = id;
    }
    return BPX_OK;
}

// Checks that every id is in use and appears once (w->dead must exist). Ids are marked 2 while
// the batch is walked, so a repeat is seen; the marks are undone before returning.
static bpx_status check_ids(bpx_world *w, const uint32_t *ids, uint32_t count, const char *what)
{
    bpx_status status = BPX_OK;
    uint32_t k = 0;
    for (; k < count; k++) {
        uint32_t id = ids[k];
        if (id >= w->n || w->dead[id] == 1) {
            status = bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, k, -1,
                                "%s: ids[%u] = %u is not a box in use", what, k, id);
            break;
        }
        if (w->dead[id] == 2) {
            status = bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, k, -1,
                                "%s: ids[%u] = %u appears twice", what, k, id);
            break;
        }
        w->dead[id] = 2;
    }
    for (uint32_t r = 0; r < k; r++)
        w->dead[ids[r]] = 0;
    return status;
}

bpx_status bpx_world_remove_boxes(bpx_world *w, const uint32_t *ids, uint32_t count)
{
    if (!w)
        return BPX_ERR_NULL_ARGUMENT;
    bpx__error_clear(&w->error);
    if (count && !ids)
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "ids is NULL");
    if (!reserve_objects(w, w->n))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1, "no memory");
    bpx_status status = check_ids(w, ids, count, "remove_boxes");
    if (status != BPX_OK)
        return status;
    for (uint32_t k = 0; k < count; k++) {
        w->dead[ids[k]] = 1;
        w->pending_ids[w->pending_count++] = ids[k];
        bpx__box_make_inert(w, ids[k]);
    }
    return BPX_OK;
}

bpx_status bpx_world_move_boxes(bpx_world *w, const uint32_t *ids, const bpx_box *boxes,
                                uint32_t count)
{
    if (!w)
        return BPX_ERR_NULL_ARGUMENT;
    bpx__error_clear(&w->error);
    if (count && (!ids || !boxes))
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "ids or boxes is NULL");
    if (!reserve_objects(w, w->n))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1, "no memory");
    bpx_status status = bpx__check_boxes(boxes, count, &w->error);
    if (status == BPX_OK)
        status = check_ids(w, ids, count, "move_boxes");
    if (status != BPX_OK)
        return status;
    for (uint32_t k = 0; k < count; k++)
        bpx__box_set(w, ids[k], &boxes[k]);
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// Filters

bpx_status bpx_world_set_filters(bpx_world *w, const uint32_t *ids, const uint32_t *categories,
                                 const uint32_t *masks, uint32_t count)
{
    if (!w)
        return BPX_ERR_NULL_ARGUMENT;
    bpx__error_clear(&w->error);
    if (count && (!categories || !masks))
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "categories or masks is NULL");
    for (uint32_t k = 0; k < count; k++) {
        uint32_t id = ids ? ids[k] : k;
        if (id >= w->n || (w->dead && w->dead[id]))
            return bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, k, -1,
                              "set_filters: ids[%u] = %u is not a box in use (n = %u)", k, id,
                              w->n);
    }
    if (!reserve_objects(w, w->n))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1, "no memory");
    if (!w->category) {
        size_t size = w->object_capacity * sizeof(uint32_t);
        w->category = bpx__alloc(size);
        w->mask = bpx__alloc(size);
        if (!w->category || !w->mask) {
            bpx__free(w->category, size);
            bpx__free(w->mask, size);
            w->category = w->mask = NULL;
            return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1, "no memory");
        }
        for (uint32_t id = 0; id < w->object_capacity; id++)
            w->category[id] = 1, w->mask[id] = UINT32_MAX;
    }
    for (uint32_t k = 0; k < count; k++) {
        uint32_t id = ids ? ids[k] : k;
        w->category[id] = categories[k];
        w->mask[id] = masks[k];
    }
    return BPX_OK;
}

void bpx__filter_blocks(bpx_world *w)
{
    if (!w->category)
        return;
    const uint32_t *category = w->category, *mask = w->mask;
    for (int b = 0; b < w->emitter.block_count; b++) {
        bpx_pair_list *hits = &w->emitter.blocks[b].hits;
        size_t kept = 0;
        for (size_t k = 0; k < hits->count; k++) {
            bpx_pair p = hits->pairs[k];
            hits->pairs[kept] = p;
            kept += (category[p.i] & mask[p.j]) && (category[p.j] & mask[p.i]);
        }
        hits->count = kept;
    }
}

// ---------------------------------------------------------------------------------------------
// Events

// began = now - before, ended = before - now: one merge walk over two sorted lists.
static bool diff_sorted(const bpx_pair *before, size_t nb, const bpx_pair *now, size_t nn,
                        bpx_pair_list *began, bpx_pair_list *ended)
{
    began->count = ended->count = 0;
    if (!bpx__list_reserve(began, nn) || !bpx__list_reserve(ended, nb))
        return false;
    size_t a = 0, b = 0;
    while (a < nb || b < nn) {
        if (b == nn || (a < nb && bpx__pair_less(before[a], now[b])))
            ended->pairs[ended->count++] = before[a++];
        else if (a == nb || bpx__pair_less(now[b], before[a]))
            began->pairs[began->count++] = now[b++];
        else
            a++, b++;
    }
    return true;
}

bpx_status bpx__objects_after_collide(bpx_world *w, const bpx_pair *pairs, size_t count)
{
    if (w->def.track_events) {
        w->events_valid = false;
        bpx_pair_list *prev = &w->previous;
        // Room for this cycle's pairs before the last cycle's are dropped: on failure they stay,
        // and the next collide reports its events against them.
        if (!bpx__list_reserve(prev, count > prev->count ? count - prev->count : 0) ||
            !diff_sorted(prev->pairs, prev->count, pairs, count, &w->began, &w->ended))
            return BPX_ERR_OUT_OF_MEMORY;
        if (count)
            memcpy(w->previous.pairs, pairs, count * sizeof(bpx_pair));
        w->previous.count = count;
        w->events_valid = true;
    }
    // The removed boxes' pairs have now been reported as ended: their ids may be reused.
    for (uint32_t k = 0; k < w->pending_count; k++)
        w->free_ids[w->free_count++] = w->pending_ids[k];
    w->pending_count = 0;
    return BPX_OK;
}

bpx_status bpx_world_pair_events(const bpx_world *w, bpx_pair_events *events)
{
    if (!w || !events)
        return BPX_ERR_NULL_ARGUMENT;
    if (!w->def.track_events || !w->events_valid)
        return BPX_ERR_BAD_STATE;
    *events = (bpx_pair_events){w->began.pairs, w->began.count, w->ended.pairs, w->ended.count};
    return BPX_OK;
}
