// Objects added and removed between cycles, collision filters, and begin/end pair events.
#include "objects.h"

#include <float.h>
#include <math.h>
#include <string.h>

#include "alloc.h"
#include "boxes.h"
#include "validate.h"

// ---------------------------------------------------------------------------------------------
// Per-id arrays

// The optional per-id columns: each NULL until first set, then as long as the others, and every
// id not set holding the default (a new box: category 1, mask all ones, group 0, no user data,
// in no excluded pair).
enum { COLUMNS = BPX_ID_COLUMNS };

static void id_columns(bpx_world *w, id_column c[COLUMNS])
{
    c[0] = (id_column){(void **)&w->category, sizeof(uint32_t), 1};
    c[1] = (id_column){(void **)&w->mask, sizeof(uint32_t), UINT32_MAX};
    c[2] = (id_column){(void **)&w->group, sizeof(int32_t), 0};
    c[3] = (id_column){(void **)&w->user_data, sizeof(uint64_t), 0};
    c[4] = (id_column){(void **)&w->exclusions, sizeof(uint32_t), 0};
}

void bpx__objects_columns(bpx_world *w, id_column c[BPX_ID_COLUMNS])
{
    id_columns(w, c);
}

void bpx__objects_fill_column(const id_column *c, uint32_t from, uint32_t to)
{
    if (c->size == sizeof(uint64_t))
        for (uint32_t id = from; id < to; id++)
            ((uint64_t *)*c->data)[id] = c->fill;
    else
        for (uint32_t id = from; id < to; id++)
            ((uint32_t *)*c->data)[id] = (uint32_t)c->fill;
}

// Every column in use back to its default for one id (a box added, or an id dropped).
static void reset_id(bpx_world *w, uint32_t id)
{
    id_column c[COLUMNS];
    id_columns(w, c);
    for (int k = 0; k < COLUMNS; k++)
        if (*c[k].data)
            bpx__objects_fill_column(&c[k], id, id + 1);
}

static size_t column_size(bpx_world *w, void **data)
{
    id_column c[COLUMNS];
    id_columns(w, c);
    for (int k = 0; k < COLUMNS; k++)
        if (c[k].data == data)
            return c[k].size;
    return 0;
}

// Makes a column exist (all ids at the default). False when out of memory.
bool bpx__objects_use_column(bpx_world *w, void **data)
{
    if (*data)
        return true;
    *data = bpx__alloc(column_size(w, data) * w->object_capacity);
    if (!*data)
        return false;
    id_column c[COLUMNS];
    id_columns(w, c);
    for (int k = 0; k < COLUMNS; k++)
        if (c[k].data == data)
            bpx__objects_fill_column(&c[k], 0, w->object_capacity);
    return true;
}

static void free_object_arrays(bpx_world *w)
{
    size_t cap = w->object_capacity;
    bpx__free(w->dead, cap);
    bpx__free(w->pending_ids, cap * sizeof(uint32_t));
    bpx__free(w->free_ids, cap * sizeof(uint32_t));
    id_column c[COLUMNS];
    id_columns(w, c);
    for (int k = 0; k < COLUMNS; k++) {
        bpx__free(*c[k].data, cap * c[k].size);
        *c[k].data = NULL;
    }
    w->dead = NULL;
    w->pending_ids = w->free_ids = NULL;
    w->object_capacity = 0;
}

// Grows the per-id arrays to hold n ids, keeping contents; new ids are live and at the
// defaults. All or nothing.
bool bpx__objects_reserve(bpx_world *w, uint32_t n)
{
    uint32_t old = w->object_capacity;
    if (n <= old && w->dead)
        return true;
    uint32_t cap = old ? old : 64;
    while (cap < n)
        cap = cap > UINT32_MAX / 2 ? n : cap * 2;
    id_column c[COLUMNS];
    id_columns(w, c);
    void *grown[COLUMNS] = {0};
    uint8_t *dead = bpx__alloc(cap);
    uint32_t *pending = bpx__alloc(cap * sizeof(uint32_t));
    uint32_t *freed = bpx__alloc(cap * sizeof(uint32_t));
    bool ok = dead && pending && freed;
    for (int k = 0; k < COLUMNS; k++)
        if (*c[k].data && !(grown[k] = bpx__alloc(cap * c[k].size)))
            ok = false;
    if (!ok) {
        bpx__free(dead, cap);
        bpx__free(pending, cap * sizeof(uint32_t));
        bpx__free(freed, cap * sizeof(uint32_t));
        for (int k = 0; k < COLUMNS; k++)
            bpx__free(grown[k], cap * c[k].size);
        return false;
    }
    memset(dead, 0, cap);
    if (w->dead) {
        memcpy(dead, w->dead, old);
        memcpy(pending, w->pending_ids, w->pending_count * sizeof(uint32_t));
        memcpy(freed, w->free_ids, w->free_count * sizeof(uint32_t));
    }
    for (int k = 0; k < COLUMNS; k++)
        if (grown[k]) {
            memcpy(grown[k], *c[k].data, old * c[k].size);
            bpx__free(*c[k].data, old * c[k].size);
            *c[k].data = grown[k];
            bpx__objects_fill_column(&c[k], old, cap);
        }
    bpx__free(w->dead, old);
    bpx__free(w->pending_ids, old * sizeof(uint32_t));
    bpx__free(w->free_ids, old * sizeof(uint32_t));
    w->dead = dead;
    w->pending_ids = pending;
    w->free_ids = freed;
    w->object_capacity = cap;
    return true;
}

// Excluded pairs with an id that `dropped` marks go; the ids' counts follow.
typedef struct drop_context {
    bpx_world *w;
    const uint8_t *dropped; // per id: nonzero = the id's exclusions go
} drop_context;

static bool drop_excluded(uint64_t key, const void *context)
{
    const drop_context *d = context;
    uint32_t i = (uint32_t)(key >> 32), j = (uint32_t)key;
    if (!d->dropped[i] && !d->dropped[j])
        return false;
    d->w->exclusions[i]--;
    d->w->exclusions[j]--;
    return true;
}

bool bpx__objects_reset(bpx_world *w, uint32_t n)
{
    if (!w->dead) // never used: nothing to reset, and set_boxes stays free of extra work
        return true;
    if (!bpx__objects_reserve(w, n))
        return false;
    // What is set per id lasts while the id holds a box: ids kept (below the old and the new n,
    // and not removed) keep theirs; the rest start again at the defaults. w->n is still the old n.
    uint32_t kept = n < w->n ? n : w->n;
    for (uint32_t id = 0; id < w->object_capacity; id++)
        w->dead[id] = id >= kept || w->dead[id]; // 1: the id's settings go
    if (w->excluded.count)
        bpx__pair_set_remove_if(&w->excluded, drop_excluded, &(drop_context){w, w->dead});
    for (uint32_t id = 0; id < w->object_capacity; id++)
        if (w->dead[id])
            reset_id(w, id);
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
    bpx__pair_set_free(&w->excluded);
    bpx_pair_list *lists[] = {&w->previous,         &w->began,         &w->ended,
                              &w->candidates,       &w->rejected,      &w->fresh_candidates,
                              &w->fresh_rejected};
    for (int k = 0; k < 7; k++) {
        bpx__free(lists[k]->pairs, lists[k]->capacity * sizeof(bpx_pair));
        *lists[k] = (bpx_pair_list){0};
    }
}

// ---------------------------------------------------------------------------------------------
// Add, remove, move

// Float64 boxes are kept whole: a float32 box by id would leave them half exact.
static bpx_status float64_set_whole(bpx_world *w, const char *call)
{
    return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                      "%s: the world holds float64 boxes (bpx_world_set_boxes64), which are "
                      "set whole",
                      call);
}

bpx_status bpx_world_add_boxes(bpx_world *w, const bpx_box *boxes, uint32_t count,
                               uint32_t *out_ids)
{
    bpx_status entered = bpx__world_enter(w, "add_boxes");
    if (entered != BPX_OK)
        return entered;
    if (count && (!boxes || !out_ids))
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "boxes or out_ids is NULL");
    if (w->extents_loaded)
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "add_boxes: the world is in the two-phase mode (load_extents)");
    if (w->boxes64_set)
        return float64_set_whole(w, "add_boxes");
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
    if (!bpx__objects_reserve(w, (uint32_t)new_n) || !bpx__boxes_resize(w, (uint32_t)new_n))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %llu boxes", (unsigned long long)new_n);
    for (uint32_t k = 0; k < count; k++) {
        uint32_t id = k < reused ? w->free_ids[--w->free_count] : old_n + (k - reused);
        w->dead[id] = 0;
        reset_id(w, id);
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
    bpx_status entered = bpx__world_enter(w, "remove_boxes");
    if (entered != BPX_OK)
        return entered;
    if (count && !ids)
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "ids is NULL");
    if (w->boxes64_set)
        return float64_set_whole(w, "remove_boxes");
    if (!bpx__objects_reserve(w, w->n))
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
    bpx_status entered = bpx__world_enter(w, "move_boxes");
    if (entered != BPX_OK)
        return entered;
    if (count && (!ids || !boxes))
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "ids or boxes is NULL");
    if (w->boxes64_set)
        return float64_set_whole(w, "move_boxes");
    if (!bpx__objects_reserve(w, w->n))
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
// Filters, groups, excluded pairs, user data

// Checks that ids (NULL: 0 .. count-1) are boxes in use; the error names the position.
static bpx_status check_in_use(bpx_world *w, const uint32_t *ids, uint32_t count, const char *what)
{
    for (uint32_t k = 0; k < count; k++) {
        uint32_t id = ids ? ids[k] : k;
        if (id >= w->n || (w->dead && w->dead[id]))
            return bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, k, -1,
                              "%s: ids[%u] = %u is not a box in use (n = %u)", what, k, id, w->n);
    }
    return BPX_OK;
}

// The per-id arrays and the named columns exist (b may be NULL). All or nothing: false when out
// of memory, with no column made.
static bool use_columns(bpx_world *w, void **a, void **b)
{
    bool had_a = *a != NULL;
    if (!bpx__objects_reserve(w, w->n) || !bpx__objects_use_column(w, a))
        return false;
    if (b && !bpx__objects_use_column(w, b)) {
        if (!had_a) {
            bpx__free(*a, w->object_capacity * column_size(w, a));
            *a = NULL;
        }
        return false;
    }
    return true;
}

bpx_status bpx_world_set_filters(bpx_world *w, const uint32_t *ids, const uint32_t *categories,
                                 const uint32_t *masks, uint32_t count)
{
    bpx_status entered = bpx__world_enter(w, "set_filters");
    if (entered != BPX_OK)
        return entered;
    if (count && (!categories || !masks))
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1,
                          "categories or masks is NULL");
    bpx_status status = check_in_use(w, ids, count, "set_filters");
    if (status != BPX_OK)
        return status;
    if (!use_columns(w, (void **)&w->category, (void **)&w->mask))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1, "no memory");
    for (uint32_t k = 0; k < count; k++) {
        uint32_t id = ids ? ids[k] : k;
        w->category[id] = categories[k];
        w->mask[id] = masks[k];
    }
    return BPX_OK;
}

bpx_status bpx_world_set_groups(bpx_world *w, const uint32_t *ids, const int32_t *groups,
                                uint32_t count)
{
    bpx_status entered = bpx__world_enter(w, "set_groups");
    if (entered != BPX_OK)
        return entered;
    if (count && !groups)
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "groups is NULL");
    bpx_status status = check_in_use(w, ids, count, "set_groups");
    if (status != BPX_OK)
        return status;
    if (!use_columns(w, (void **)&w->group, NULL))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1, "no memory");
    for (uint32_t k = 0; k < count; k++)
        w->group[ids ? ids[k] : k] = groups[k];
    return BPX_OK;
}

bpx_status bpx_world_set_user_data(bpx_world *w, const uint32_t *ids, const uint64_t *values,
                                   uint32_t count)
{
    bpx_status entered = bpx__world_enter(w, "set_user_data");
    if (entered != BPX_OK)
        return entered;
    if (count && !values)
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "values is NULL");
    bpx_status status = check_in_use(w, ids, count, "set_user_data");
    if (status != BPX_OK)
        return status;
    if (!use_columns(w, (void **)&w->user_data, NULL))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1, "no memory");
    for (uint32_t k = 0; k < count; k++)
        w->user_data[ids ? ids[k] : k] = values[k];
    return BPX_OK;
}

uint64_t bpx_world_user_data(const bpx_world *w, uint32_t id)
{
    if (!w || !w->user_data || id >= w->n || w->dead[id])
        return 0;
    return w->user_data[id];
}

// Checks a batch of pairs: both ids in use and different.
static bpx_status check_pairs(bpx_world *w, const bpx_pair *pairs, uint32_t count,
                              const char *what)
{
    if (count && !pairs)
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "pairs is NULL");
    for (uint32_t k = 0; k < count; k++) {
        bpx_pair p = pairs[k];
        bool i_out = p.i >= w->n || (w->dead && w->dead[p.i]);
        bool j_out = p.j >= w->n || (w->dead && w->dead[p.j]);
        if (i_out || j_out)
            return bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, k, -1,
                              "%s: pairs[%u] = (%u, %u): %u is not a box in use (n = %u)", what,
                              k, p.i, p.j, i_out ? p.i : p.j, w->n);
        if (p.i == p.j)
            return bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, k, -1,
                              "%s: pairs[%u] = (%u, %u) pairs a box with itself", what, k, p.i,
                              p.j);
    }
    return BPX_OK;
}

bpx_status bpx_world_exclude_pairs(bpx_world *w, const bpx_pair *pairs, uint32_t count)
{
    bpx_status entered = bpx__world_enter(w, "exclude_pairs");
    if (entered != BPX_OK)
        return entered;
    bpx_status status = check_pairs(w, pairs, count, "exclude_pairs");
    if (status != BPX_OK)
        return status;
    if (!use_columns(w, (void **)&w->exclusions, NULL) ||
        !bpx__pair_set_reserve(&w->excluded, count))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %u more excluded pairs (%u now)", count,
                          w->excluded.count);
    for (uint32_t k = 0; k < count; k++)
        if (bpx__pair_set_add(&w->excluded, bpx__pair_key(pairs[k].i, pairs[k].j))) {
            w->exclusions[pairs[k].i]++;
            w->exclusions[pairs[k].j]++;
        }
    return BPX_OK;
}

bpx_status bpx_world_include_pairs(bpx_world *w, const bpx_pair *pairs, uint32_t count)
{
    bpx_status entered = bpx__world_enter(w, "include_pairs");
    if (entered != BPX_OK)
        return entered;
    bpx_status status = check_pairs(w, pairs, count, "include_pairs");
    if (status != BPX_OK)
        return status;
    for (uint32_t k = 0; k < count; k++)
        if (bpx__pair_set_remove(&w->excluded, bpx__pair_key(pairs[k].i, pairs[k].j))) {
            w->exclusions[pairs[k].i]--;
            w->exclusions[pairs[k].j]--;
        }
    return BPX_OK;
}

bool bpx_world_pair_excluded(const bpx_world *w, uint32_t i, uint32_t j)
{
    return w && i != j && bpx__pair_set_has(&w->excluded, bpx__pair_key(i, j));
}

bool bpx__objects_filtering(const bpx_world *w)
{
    return w->category || w->group || w->excluded.count || w->pair_filter ||
           bpx__world_margins(w);
}

bpx_status bpx_world_set_pair_filter(bpx_world *w, bpx_pair_filter_fn *fn, void *context)
{
    bpx_status entered = bpx__world_enter(w, "set_pair_filter");
    if (entered != BPX_OK)
        return entered;
    w->pair_filter = fn;
    w->pair_filter_context = context;
    bpx__objects_forget_decisions(w);
    return BPX_OK;
}

void bpx__objects_forget_decisions(bpx_world *w)
{
    w->candidates.count = w->rejected.count = 0;
}

// Whether a sorted list holds p, walking a cursor that only moves forward (the pairs asked
// about come in order).
static bool holds(const bpx_pair_list *list, size_t *cursor, bpx_pair p)
{
    while (*cursor < list->count && bpx__pair_less(list->pairs[*cursor], p))
        ++*cursor;
    return *cursor < list->count && list->pairs[*cursor].i == p.i &&
           list->pairs[*cursor].j == p.j;
}

bpx_status bpx__pair_filter_blocks(bpx_world *w)
{
    if (!w->pair_filter)
        return BPX_OK;
    size_t total = 0;
    bpx_status status = bpx__emitter_total(&w->emitter, &total);
    if (status != BPX_OK)
        return status;
    bpx_pair_list *fresh = &w->fresh_candidates, *refused = &w->fresh_rejected;
    fresh->count = refused->count = 0;
    if (!bpx__list_reserve(fresh, total) || !bpx__list_reserve(refused, total))
        return BPX_ERR_OUT_OF_MEMORY;
    // The blocks, in order, are this cycle's pairs in (i, j) order.
    size_t was_candidate = 0, was_rejected = 0;
    w->in_callback = true;
    for (int b = 0; b < w->emitter.block_count; b++) {
        bpx_pair_list *hits = &w->emitter.blocks[b].hits;
        size_t kept = 0;
        for (size_t k = 0; k < hits->count; k++) {
            bpx_pair p = hits->pairs[k];
            fresh->pairs[fresh->count++] = p;
            bool refuse;
            if (holds(&w->candidates, &was_candidate, p))
                refuse = holds(&w->rejected, &was_rejected, p);
            else
                refuse = !w->pair_filter(p.i, p.j, w->user_data ? w->user_data[p.i] : 0,
                                         w->user_data ? w->user_data[p.j] : 0,
                                         w->pair_filter_context);
            if (refuse)
                refused->pairs[refused->count++] = p;
            hits->pairs[kept] = p;
            kept += !refuse;
        }
        hits->count = kept;
    }
    w->in_callback = false;
    bpx_pair_list t = w->candidates;
    w->candidates = *fresh;
    *fresh = t;
    t = w->rejected;
    w->rejected = *refused;
    *refused = t;
    return BPX_OK;
}

// Whether two boxes may pair: excluded pairs never; then a shared non-zero group decides
// (positive: always, negative: never); then categories and masks.
static inline bool may_pair(const bpx_world *w, uint32_t i, uint32_t j)
{
    if (w->excluded.count && w->exclusions[i] && w->exclusions[j] &&
        bpx__pair_set_has(&w->excluded, bpx__pair_key(i, j)))
        return false;
    if (w->group && w->group[i] == w->group[j] && w->group[i] != 0)
        return w->group[i] > 0;
    return !w->category ||
           ((w->category[i] & w->mask[j]) && (w->category[j] & w->mask[i]));
}

bool bpx__objects_may_pair(const bpx_world *w, uint32_t i, uint32_t j)
{
    return may_pair(w, i, j);
}

void bpx__filter_blocks(bpx_world *w)
{
    // Only the rules of may_pair: margins and the pair filter have passes of their own.
    if (!w->category && !w->group && !w->excluded.count)
        return;
    for (int b = 0; b < w->emitter.block_count; b++) {
        bpx_pair_list *hits = &w->emitter.blocks[b].hits;
        size_t kept = 0;
        for (size_t k = 0; k < hits->count; k++) {
            bpx_pair p = hits->pairs[k];
            hits->pairs[kept] = p;
            kept += may_pair(w, p.i, p.j);
        }
        hits->count = kept;
    }
}

// ---------------------------------------------------------------------------------------------
// Contact margins

// x moved by d and rounded outward (down for d < 0, up for d > 0); infinite x (an inert box)
// stays infinite, a finite one stays finite.
static float widen(float x, float d)
{
    if (!isfinite(x))
        return x;
    double exact = (double)x + (double)d;
    float f = (float)exact;
    if (d < 0.0f && (double)f > exact)
        f = nextafterf(f, -INFINITY);
    if (d > 0.0f && (double)f < exact)
        f = nextafterf(f, INFINITY);
    return f < -FLT_MAX ? -FLT_MAX : f > FLT_MAX ? FLT_MAX : f;
}

bool bpx__margins_grow_boxes(bpx_world *w)
{
    if (!bpx__box_arrays_reserve(&w->grown, w->n))
        return false;
    // A little more than half the margin each side: a gap within end_margin in double is
    // within the grown boxes' reach whatever the rounding.
    float half = nextafterf(w->def.end_margin * 0.5f, INFINITY);
    for (int a = 0; a < 3; a++)
        for (uint32_t i = 0; i < w->n; i++) {
            w->grown.lo[a][i] = widen(w->boxes.lo[a][i], -half);
            w->grown.hi[a][i] = widen(w->boxes.hi[a][i], half);
        }
    bpx__box_arrays_pad(&w->grown, w->n);
    return true;
}

// The gap between boxes i and j (see bpx_world_def.begin_margin), from the exact boxes.
static double gap(const bpx_world *w, uint32_t i, uint32_t j)
{
    double g = -INFINITY;
    for (int a = 0; a < 3; a++) {
        double lo_i = w->boxes.lo[a][i], hi_i = w->boxes.hi[a][i];
        double lo_j = w->boxes.lo[a][j], hi_j = w->boxes.hi[a][j];
        double apart = lo_j - hi_i > lo_i - hi_j ? lo_j - hi_i : lo_i - hi_j;
        g = apart > g ? apart : g;
    }
    return g;
}

void bpx__margins_filter_blocks(bpx_world *w)
{
    if (!bpx__world_margins(w))
        return;
    double begin = w->def.begin_margin, end = w->def.end_margin;
    size_t held = 0; // cursor in the last pairs, which come in order as the blocks do
    for (int b = 0; b < w->emitter.block_count; b++) {
        bpx_pair_list *hits = &w->emitter.blocks[b].hits;
        size_t kept = 0;
        for (size_t k = 0; k < hits->count; k++) {
            bpx_pair p = hits->pairs[k];
            double g = gap(w, p.i, p.j);
            hits->pairs[kept] = p;
            kept += g <= begin || (g <= end && holds(&w->previous, &held, p));
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
    // The last pairs are kept for events, and for the margins (a pair held by end_margin).
    if (w->def.track_events || bpx__world_margins(w)) {
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
    // The removed boxes' pairs have now been reported as ended: their ids may be reused, free of
    // the excluded pairs they were in.
    if (w->excluded.count) {
        bool any = false;
        for (uint32_t k = 0; k < w->pending_count; k++)
            any |= w->exclusions[w->pending_ids[k]] != 0;
        if (any) // dead[id] is 1 for every removed id; those freed before are in no pair now
            bpx__pair_set_remove_if(&w->excluded, drop_excluded, &(drop_context){w, w->dead});
    }
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
