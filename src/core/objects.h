// The object layer's side of the world (objects.c): what the world's interface and updater call
// when boxes are replaced, rewritten and collided. The object layer's own state is the per-id
// part of struct bpx_world (world.h); it changes boxes only through the box storage (boxes.h),
// never through the world's interface, so calls go one way: world.c -> objects.c -> boxes.c.
#pragma once

#include "world.h"

/// The optional per-id columns (category, mask, group, user data, exclusion counts): each NULL
/// until first set, then as long as the per-id arrays, ids never set holding `fill`.
typedef struct id_column {
    void **data;
    size_t size; // 4 or 8 bytes
    uint64_t fill;
} id_column;
enum { BPX_ID_COLUMNS = 5 };
void bpx__objects_columns(bpx_world *w, id_column c[BPX_ID_COLUMNS]);
void bpx__objects_fill_column(const id_column *c, uint32_t from, uint32_t to);
/// Makes the column at `data` exist, every id at its default. False when out of memory.
bool bpx__objects_use_column(bpx_world *w, void **data);
/// The per-id arrays hold n ids (kept contents; new ids live, at the defaults). All or nothing.
bool bpx__objects_reserve(bpx_world *w, uint32_t n);

/// Every id below n live, none pending or free; filters kept for the ids in use below both the
/// old n (w->n, so call before the boxes change) and the new, else reset (set_boxes, load).
/// All or nothing: on false (no memory) nothing changed.
bool bpx__objects_reset(bpx_world *w, uint32_t n);
/// Re-inerts removed ids after the updater rewrote every box.
void bpx__objects_reinert(bpx_world *w);
/// Whether filters, groups or excluded pairs are set (the device-resident path cannot apply them).
bool bpx__objects_filtering(const bpx_world *w);
/// Whether boxes i and j may pair by exclusions, groups and filters (i == j: a box and its own
/// periodic image, by groups and filters).
bool bpx__objects_may_pair(const bpx_world *w, uint32_t i, uint32_t j);
/// Contact margins: w->grown becomes the boxes grown by end_margin / 2 (rounded outward, so
/// that every pair within end_margin is found). False when out of memory.
bool bpx__margins_grow_boxes(bpx_world *w);
/// Contact margins over the blocks: keeps the pairs with gap <= begin_margin, and those of the
/// last collide with gap <= end_margin.
void bpx__margins_filter_blocks(bpx_world *w);
/// The pair filter over the blocks (after bpx__filter_blocks): pairs new since the last cycle
/// asked, the rest decided as before. OUT_OF_MEMORY leaves the decisions as they were.
bpx_status bpx__pair_filter_blocks(bpx_world *w);
/// Every pair will be asked about again (a new filter, a restore).
void bpx__objects_forget_decisions(bpx_world *w);
/// Drops filtered-out hits from the blocks (no-op without filters).
void bpx__filter_blocks(bpx_world *w);
/// After a successful collide: events from the merged pairs, then pending ids become free.
bpx_status bpx__objects_after_collide(bpx_world *w, const bpx_pair *pairs, size_t count);
void bpx__objects_free(bpx_world *w);
