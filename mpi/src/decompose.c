// Recursive coordinate bisection at weighted sample medians.
#include "decompose.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mpi_alloc.h"

int bpx_mpi__rcb_init(bpx_mpi_rcb_tree *tree, int ranks)
{
    memset(tree, 0, sizeof *tree);
    tree->ranks = ranks;
    tree->nodes = bpx_mpi__alloc(sizeof *tree->nodes * (size_t)(2 * ranks - 1));
    tree->lo = bpx_mpi__alloc(sizeof *tree->lo * (size_t)ranks);
    tree->hi = bpx_mpi__alloc(sizeof *tree->hi * (size_t)ranks);
    tree->stack = bpx_mpi__alloc(sizeof *tree->stack * (size_t)(2 * ranks));
    if (!tree->nodes || !tree->lo || !tree->hi || !tree->stack) {
        bpx_mpi__rcb_free(tree);
        return -1;
    }
    return 0;
}

void bpx_mpi__rcb_free(bpx_mpi_rcb_tree *tree)
{
    size_t ranks = tree->ranks > 0 ? (size_t)tree->ranks : 0;
    bpx_mpi__free(tree->nodes, sizeof *tree->nodes * (ranks > 0 ? 2 * ranks - 1 : 0));
    bpx_mpi__free(tree->lo, sizeof *tree->lo * ranks);
    bpx_mpi__free(tree->hi, sizeof *tree->hi * ranks);
    bpx_mpi__free(tree->stack, sizeof *tree->stack * 2 * ranks);
    memset(tree, 0, sizeof *tree);
}

// A total order on samples along one axis (then the other axes, then the weight), so that
// qsort, which is not stable, gives the same order on every rank.
static int compare_on(const bpx_mpi_rcb_sample *a, const bpx_mpi_rcb_sample *b, int axis)
{
    for (int k = 0; k < 3; k++) {
        int ax = (axis + k) % 3;
        if (a->centre[ax] != b->centre[ax])
            return a->centre[ax] < b->centre[ax] ? -1 : 1;
    }
    return (a->weight > b->weight) - (a->weight < b->weight);
}
static int compare_x(const void *a, const void *b)
{
    return compare_on(a, b, 0);
}
static int compare_y(const void *a, const void *b)
{
    return compare_on(a, b, 1);
}
static int compare_z(const void *a, const void *b)
{
    return compare_on(a, b, 2);
}

typedef struct build_state {
    bpx_mpi_rcb_tree *tree;
    int next_node;
} build_state;

// A cut for a part without samples: anywhere works for exactness; between finite bounds keeps
// regions tidy.
static float empty_cut(const float lo[3], const float hi[3], int *axis)
{
    *axis = 0;
    if (isfinite(lo[0]) && isfinite(hi[0]))
        return 0.5f * lo[0] + 0.5f * hi[0];
    if (isfinite(lo[0]))
        return lo[0] + 1.0f;
    if (isfinite(hi[0]))
        return hi[0] - 1.0f;
    return 0.0f;
}

// Where to cut sorted samples so that the left side carries about `fraction` of the weight;
// *split is the number of samples going left. Samples on the cut go right (p < cut is left).
static float weighted_cut(const bpx_mpi_rcb_sample *s, size_t count, int axis, double fraction,
                          size_t *split)
{
    double total = 0;
    for (size_t i = 0; i < count; i++)
        total += s[i].weight;
    double target = total * fraction, sum = 0;
    size_t k = 0; // samples left of the cut
    while (k < count && sum + 0.5 * s[k].weight <= target)
        sum += s[k++].weight;
    // Samples with the same coordinate must fall on the same side: move k to the nearer change.
    size_t down = k, up = k;
    while (down > 0 && down < count && s[down - 1].centre[axis] == s[down].centre[axis])
        down--;
    while (up > 0 && up < count && s[up - 1].centre[axis] == s[up].centre[axis])
        up++;
    if (down == 0)
        k = up;
    else if (up >= count)
        k = down;
    else
        k = (k - down <= up - k) ? down : up;
    if (k == 0 || k >= count) { // all on one coordinate (or one sample): cut below all of them
        *split = 0;
        return s[0].centre[axis];
    }
    *split = k;
    float a = s[k - 1].centre[axis], b = s[k].centre[axis];
    float mid = 0.5f * a + 0.5f * b;
    return (mid > a && mid <= b) ? mid : b;
}

static int build_node(build_state *st, bpx_mpi_rcb_sample *s, size_t count, int r0, int r1,
                      const float lo[3], const float hi[3])
{
    bpx_mpi_rcb_tree *tree = st->tree;
    int index = st->next_node++;
    bpx_mpi_rcb_node *node = &tree->nodes[index];
    if (r1 - r0 == 1) {
        *node = (bpx_mpi_rcb_node){.axis = -1, .cut = 0, .left = -1, .right = -1, .rank = r0};
        memcpy(tree->lo[r0], lo, sizeof(float[3]));
        memcpy(tree->hi[r0], hi, sizeof(float[3]));
        return index;
    }
    int left_ranks = (r1 - r0) / 2;
    int axis;
    float cut;
    size_t split = 0;
    if (count == 0) {
        cut = empty_cut(lo, hi, &axis);
    } else {
        float bmin[3], bmax[3];
        for (int k = 0; k < 3; k++)
            bmin[k] = bmax[k] = s[0].centre[k];
        for (size_t i = 1; i < count; i++)
            for (int k = 0; k < 3; k++) {
                bmin[k] = fminf(bmin[k], s[i].centre[k]);
                bmax[k] = fmaxf(bmax[k], s[i].centre[k]);
            }
        axis = 0;
        for (int k = 1; k < 3; k++) // halved so that +-FLT_MAX spans do not overflow
            if (0.5f * bmax[k] - 0.5f * bmin[k] > 0.5f * bmax[axis] - 0.5f * bmin[axis])
                axis = k;
        int (*compare[3])(const void *, const void *) = {compare_x, compare_y, compare_z};
        qsort(s, count, sizeof *s, compare[axis]);
        cut = weighted_cut(s, count, axis, (double)left_ranks / (r1 - r0), &split);
    }
    // Keep the cut inside the part's region, so every region stays a non-empty half-open cell.
    if (!(cut > lo[axis]))
        cut = lo[axis];
    if (cut > hi[axis])
        cut = hi[axis];
    float left_hi[3], right_lo[3];
    memcpy(left_hi, hi, sizeof left_hi);
    memcpy(right_lo, lo, sizeof right_lo);
    left_hi[axis] = cut;
    right_lo[axis] = cut;
    node->axis = axis;
    node->cut = cut;
    node->rank = -1;
    int left = build_node(st, s, split, r0, r0 + left_ranks, lo, left_hi);
    int right = build_node(st, s + split, count - split, r0 + left_ranks, r1, right_lo, hi);
    tree->nodes[index].left = left; // nodes[] is not moved by the recursion; node is still valid
    tree->nodes[index].right = right;
    return index;
}

void bpx_mpi__rcb_build(bpx_mpi_rcb_tree *tree, bpx_mpi_rcb_sample *samples, size_t count)
{
    build_state st = {tree, 0};
    float lo[3] = {-INFINITY, -INFINITY, -INFINITY}, hi[3] = {INFINITY, INFINITY, INFINITY};
    build_node(&st, samples, count, 0, tree->ranks, lo, hi);
}

int bpx_mpi__rcb_locate(const bpx_mpi_rcb_tree *tree, const float p[3])
{
    const bpx_mpi_rcb_node *node = &tree->nodes[0];
    while (node->rank < 0)
        node = &tree->nodes[p[node->axis] < node->cut ? node->left : node->right];
    return node->rank;
}

int bpx_mpi__rcb_touching(const bpx_mpi_rcb_tree *tree, const bpx_box *box, int *ranks)
{
    int *stack = tree->stack, top = 0, found = 0;
    stack[top++] = 0;
    while (top > 0) {
        const bpx_mpi_rcb_node *node = &tree->nodes[stack[--top]];
        if (node->rank >= 0) {
            ranks[found++] = node->rank;
            continue;
        }
        if (box->max[node->axis] >= node->cut)
            stack[top++] = node->right;
        if (box->min[node->axis] < node->cut)
            stack[top++] = node->left;
    }
    return found;
}
