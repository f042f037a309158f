// Recursive coordinate bisection: one half-open region per rank, from sampled centres.
#pragma once

#include <stddef.h>

#include <bpx/types.h>

/// A centre standing for `weight` boxes of one rank.
typedef struct bpx_mpi_rcb_sample {
    float centre[3];
    float weight;
} bpx_mpi_rcb_sample;

/// Inner node: points with p[axis] < cut go left, the rest right. Leaf: rank >= 0.
typedef struct bpx_mpi_rcb_node {
    int axis;
    float cut;
    int left, right;
    int rank;
} bpx_mpi_rcb_node;

typedef struct bpx_mpi_rcb_tree {
    int ranks;
    bpx_mpi_rcb_node *nodes; ///< 2 * ranks - 1, the root first
    float (*lo)[3];          ///< per rank: lo <= p < hi per axis; -inf / +inf at the outside
    float (*hi)[3];
    int *stack; ///< scratch for bpx_mpi__rcb_touching, one entry per rank
} bpx_mpi_rcb_tree;

/// Allocates a tree for ranks ranks (all memory it will ever need). 0, or -1 on no memory.
int bpx_mpi__rcb_init(bpx_mpi_rcb_tree *tree, int ranks);
void bpx_mpi__rcb_free(bpx_mpi_rcb_tree *tree);

/// Bisects at weighted medians of the samples (reordered in place), along the longest side of
/// each part's samples, splitting ranks in halves (the left gets floor). The same samples in
/// the same order give the same tree on every rank.
void bpx_mpi__rcb_build(bpx_mpi_rcb_tree *tree, bpx_mpi_rcb_sample *samples, size_t count);

/// The rank whose region holds point p (finite).
int bpx_mpi__rcb_locate(const bpx_mpi_rcb_tree *tree, const float p[3]);

/// The ranks whose regions the closed box touches (min < hi and max >= lo on every axis), in
/// ascending order of node visits; returns how many were written to ranks (room for all).
int bpx_mpi__rcb_touching(const bpx_mpi_rcb_tree *tree, const bpx_box *box, int *ranks);

/// Whether point p lies in the region of rank.
static inline int bpx_mpi__rcb_holds(const bpx_mpi_rcb_tree *tree, int rank, const float p[3])
{
    const float *lo = tree->lo[rank], *hi = tree->hi[rank];
    return lo[0] <= p[0] && p[0] < hi[0] && lo[1] <= p[1] && p[1] < hi[1] && lo[2] <= p[2] &&
           p[2] < hi[2];
}

/// Whether the closed box lies wholly in the half-open region of rank (then it touches no other).
static inline int bpx_mpi__rcb_inside(const bpx_mpi_rcb_tree *tree, int rank, const bpx_box *b)
{
    const float *lo = tree->lo[rank], *hi = tree->hi[rank];
    return lo[0] <= b->min[0] && b->max[0] < hi[0] && lo[1] <= b->min[1] && b->max[1] < hi[1] &&
           lo[2] <= b->min[2] && b->max[2] < hi[2];
}

/// A box's centre, halved first so that boxes near +-FLT_MAX do not overflow.
static inline void bpx_mpi__rcb_centre(const bpx_box *box, float out[3])
{
    for (int k = 0; k < 3; k++)
        out[k] = 0.5f * box->min[k] + 0.5f * box->max[k];
}
