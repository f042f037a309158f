// The walks with lanes tested one at a time: the portable build, and the reference for the
// wider ones (the same operations in the same order, so the same bits).
#include <math.h>
#include <stddef.h>

#include "query_prep.h"

static inline uint32_t lanes_box(const bpx_bvh_node *n, const bpx_prepared *p)
{
    uint32_t hit = 0;
    for (int k = 0; k < BPX_BVH_WIDTH; k++) {
        bool in = true;
        for (int a = 0; a < 3; a++)
            in &= n->lo[a][k] <= p->hi[a] && n->hi[a][k] >= p->lo[a];
        hit |= (uint32_t)in << k;
    }
    return hit;
}

// Monotone in the box: a node's distance is never more than a box's inside it, whatever the
// rounding, so the tree never skips a hit.
static inline uint32_t lanes_sphere(const bpx_bvh_node *n, const bpx_prepared *p)
{
    uint32_t hit = 0;
    for (int k = 0; k < BPX_BVH_WIDTH; k++) {
        double d2 = 0.0;
        for (int a = 0; a < 3; a++) {
            double below = (double)n->lo[a][k] - p->centre[a];
            double above = p->centre[a] - (double)n->hi[a][k];
            double g = below > above ? below : above;
            g = g > 0.0 ? g : 0.0;
            d2 += g * g;
        }
        hit |= (uint32_t)(d2 <= p->radius2) << k;
    }
    return hit;
}

// Also monotone in the box (each step rounds monotonically), so a node's interval holds the
// intervals of the boxes inside it. A lane with lo <= hi meets its near plane first, so the
// near and far fractions are the definition's t1 and t2 in order; an unused lane (+inf .. -inf)
// enters at +inf and leaves at -inf.
static inline uint32_t lanes_cast(const bpx_bvh_node *n, const bpx_prepared *p, float limit,
                                  float enter[BPX_BVH_WIDTH])
{
    uint32_t hit = 0;
    for (int k = 0; k < BPX_BVH_WIDTH; k++) {
        double in = 0.0, out = p->max_fraction;
        bool overlap = true;
        for (int a = 0; a < 3; a++) {
            if (!p->moving[a]) {
                overlap &= n->lo[a][k] <= p->hi[a] && n->hi[a][k] >= p->lo[a];
                continue;
            }
            const float *near = (const float *)((const char *)n + p->near_plane[a]);
            const float *far = (const float *)((const char *)n + p->far_plane[a]);
            double t1 = ((double)near[k] - p->q_near[a]) * p->inv[a];
            double t2 = ((double)far[k] - p->q_far[a]) * p->inv[a];
            in = t1 > in ? t1 : in;
            out = t2 < out ? t2 : out;
        }
        enter[k] = (float)in;
        hit |= (uint32_t)(overlap && in <= out && enter[k] <= limit) << k;
    }
    return hit;
}

#define BPX_TRAVERSE bpx__traverse_scalar
#include "traverse.h"
