// A query made ready for the walks (traverse.h): every constant of the header's definitions
// computed once, and what the walks share with cast.c.
#pragma once

#include "cast.h"

typedef struct bpx_prepared {
    bpx_query_kind kind;
    bool closest;
    bool any;
    bpx_query_hit_fn *visit; // bpx_world_query_each's callback, or NULL: hits are stored
    void *visit_context;
    bpx_query_filter filter;
    float lo[3], hi[3]; // BOX: the region; RAY, SWEEP: the moving box at t = 0
    double centre[3];   // SPHERE
    double radius2;
    // RAY, SWEEP. Per axis, the plane met first (the lower one for a positive direction) and
    // the last: lane fraction = (plane - q) * inv, with q the moving box's opposite side.
    bool moving[3]; // the axis's direction is not zero
    bool all_moving;
    double inv[3];
    double q_near[3], q_far[3];
    uint32_t near_plane[3], far_plane[3]; // byte offsets of the planes' lanes in a node
    double max_fraction;
} bpx_prepared;

static inline bool bpx__query_seen(const bpx_query_view *v, const bpx_prepared *p, uint32_t id)
{
    uint32_t category = v->category ? v->category[id] : 1u;
    uint32_t mask = v->mask ? v->mask[id] : 0xFFFFFFFFu;
    return (p->filter.category & mask) && (category & p->filter.mask);
}

/// Sorts out->hits[first..] (nothing when a fixed list overflowed: the hits are not all there) by id, or (cast) by fraction then id.
void bpx__hits_sort(bpx_hit_list *out, size_t first, bool cast);

/// The walks, per instruction set.
bool bpx__traverse_scalar(const bpx_query_view *view, const bpx_prepared *p, bpx_hit_list *out);
bool bpx__traverse_avx2(const bpx_query_view *view, const bpx_prepared *p, bpx_hit_list *out);
bool bpx__traverse_avx512(const bpx_query_view *view, const bpx_prepared *p, bpx_hit_list *out);
