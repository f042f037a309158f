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
    // ORIENTED: its centre, half extents and rotation in double; lo, hi hold its bounding box
    // (rounded outward), which the walk prunes with before the exact test of each leaf.
    double o_centre[3], o_half[3], o_rot[3][3], o_abs[3][3];
} bpx_prepared;

/// ORIENTED: whether the oriented box meets the box [lo, hi] (query.h's definition).
static inline bool bpx__oriented_hits(const bpx_prepared *p, const float lo[3], const float hi[3])
{
    double t[3], e[3];
    for (int a = 0; a < 3; a++) {
        double c = 0.5 * ((double)lo[a] + (double)hi[a]);
        e[a] = 0.5 * ((double)hi[a] - (double)lo[a]);
        t[a] = p->o_centre[a] - c;
    }
    // The box's axes x, y, z: the oriented box's reach along axis i is sum_j |R_ij| h_j.
    for (int i = 0; i < 3; i++) {
        double r = p->o_abs[i][0] * p->o_half[0] + p->o_abs[i][1] * p->o_half[1] +
                   p->o_abs[i][2] * p->o_half[2];
        if (fabs(t[i]) > e[i] + r)
            return false;
    }
    // The oriented box's axes (R's columns j).
    for (int j = 0; j < 3; j++) {
        double d = t[0] * p->o_rot[0][j] + t[1] * p->o_rot[1][j] + t[2] * p->o_rot[2][j];
        double r = e[0] * p->o_abs[0][j] + e[1] * p->o_abs[1][j] + e[2] * p->o_abs[2][j];
        if (fabs(d) > r + p->o_half[j])
            return false;
    }
    // Cross products: world axis i x column j.
    for (int i = 0; i < 3; i++) {
        int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
        for (int j = 0; j < 3; j++) {
            int j1 = (j + 1) % 3, j2 = (j + 2) % 3;
            double d = t[i2] * p->o_rot[i1][j] - t[i1] * p->o_rot[i2][j];
            double rb = e[i1] * p->o_abs[i2][j] + e[i2] * p->o_abs[i1][j];
            double rq = p->o_half[j1] * p->o_abs[i][j2] + p->o_half[j2] * p->o_abs[i][j1];
            if (fabs(d) > rb + rq)
                return false;
        }
    }
    return true;
}

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
