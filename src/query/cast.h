// One query against the tree, on the calling thread: the definitions of include/bpx/query.h.
#pragma once

#include "bpx/query.h"
#include "bvh.h"

/// A growable list of hits, kept between calls; or (fixed) the caller's memory, which never
/// grows and counts the hits past its end without storing them.
typedef struct bpx_hit_list {
    bpx_hit *hits;
    size_t count;
    size_t capacity;
    bool fixed;
} bpx_hit_list;

/// Room for extra more hits. False when out of memory, or for a fixed list without the room.
bool bpx__hits_reserve(bpx_hit_list *list, size_t extra);
void bpx__hits_free(bpx_hit_list *list);

/// Which boxes a query may see: the world's filters (NULL when never set) and removed ids are
/// read through this.
typedef struct bpx_query_view {
    const bpx_bvh *tree;
    const uint32_t *category; // per id, or NULL: every box category 1
    const uint32_t *mask;     // per id, or NULL: every box mask all ones
    const uint64_t *user_data; // per id, or NULL: every box's is 0 (for callbacks)
    bpx_simd simd;            // the walks' instruction set (the same results from each)
} bpx_query_view;

/// Appends the query's hits, in their defined order, to out (or hands each to visit, when not
/// NULL). False when memory ran out (out then holds what it held before).
bool bpx__query_run(const bpx_query_view *view, const bpx_query *query, bpx_query_hit_fn *visit,
                    void *visit_context, bpx_hit_list *out);
