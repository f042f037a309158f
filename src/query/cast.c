#include "cast.h"

#include <math.h>
#include <stdlib.h>

#include "core/alloc.h"

bool bpx__hits_reserve(bpx_hit_list *list, size_t extra)
{
    if (list->count + extra <= list->capacity)
        return true;
    size_t cap = list->capacity ? list->capacity : 64;
    while (cap < list->count + extra)
        cap *= 2;
    void *memory = list->hits;
    if (!bpx__grow(&memory, sizeof(bpx_hit) * list->capacity, sizeof(bpx_hit) * cap))
        return false;
    list->hits = memory;
    list->capacity = cap;
    return true;
}

void bpx__hits_free(bpx_hit_list *list)
{
    bpx__free(list->hits, sizeof(bpx_hit) * list->capacity);
    *list = (bpx_hit_list){0};
}

// The query in the form the tests use, every constant of the definitions computed once.
typedef struct prepared {
    bpx_query_filter filter;
    float lo[3], hi[3]; // BOX: the region; RAY, SWEEP: the moving box at t = 0
    double centre[3];   // SPHERE
    double radius2;
    bool moving[3]; // RAY, SWEEP: the axis's direction is not zero
    double inv[3];
    double max_fraction;
} prepared;

static prepared prepare(const bpx_query *q)
{
    prepared p = {.filter = q->filter};
    for (int a = 0; a < 3; a++) {
        switch (q->kind) {
        case BPX_QUERY_RAY:
            p.lo[a] = p.hi[a] = q->origin[a];
            break;
        default:
            p.lo[a] = q->box.min[a];
            p.hi[a] = q->box.max[a];
        }
        p.centre[a] = q->centre[a];
        p.moving[a] = q->direction[a] != 0.0f;
        p.inv[a] = p.moving[a] ? 1.0 / (double)q->direction[a] : 0.0;
    }
    p.radius2 = (double)q->radius * (double)q->radius;
    p.max_fraction = q->max_fraction;
    return p;
}

static bool overlap(const prepared *p, const float lo[3], const float hi[3])
{
    return lo[0] <= p->hi[0] && hi[0] >= p->lo[0] && lo[1] <= p->hi[1] && hi[1] >= p->lo[1] &&
           lo[2] <= p->hi[2] && hi[2] >= p->lo[2];
}

// Monotone in the box: a node's distance is never more than a box's inside it, whatever the
// rounding, so the tree never skips a hit.
static bool touches_sphere(const prepared *p, const float lo[3], const float hi[3])
{
    double d2 = 0.0;
    for (int a = 0; a < 3; a++) {
        double below = (double)lo[a] - p->centre[a], above = p->centre[a] - (double)hi[a];
        double g = below > above ? below : above;
        if (g > 0.0)
            d2 += g * g;
    }
    return d2 <= p->radius2;
}

// The fraction at which the moving box first touches [lo, hi], if it does by max_fraction.
// Also monotone in the box (each step rounds monotonically), so a node's interval holds the
// intervals of the boxes inside it.
static bool sweep_hits(const prepared *p, const float lo[3], const float hi[3], double *t)
{
    double enter = 0.0, exit = p->max_fraction;
    for (int a = 0; a < 3; a++) {
        if (!p->moving[a]) {
            if (!(lo[a] <= p->hi[a] && hi[a] >= p->lo[a]))
                return false;
            continue;
        }
        double t1 = ((double)lo[a] - (double)p->hi[a]) * p->inv[a];
        double t2 = ((double)hi[a] - (double)p->lo[a]) * p->inv[a];
        if (t1 > t2) {
            double swap = t1;
            t1 = t2;
            t2 = swap;
        }
        enter = t1 > enter ? t1 : enter;
        exit = t2 < exit ? t2 : exit;
    }
    *t = enter;
    return enter <= exit;
}

static bool seen(const bpx_query_view *v, const prepared *p, uint32_t id)
{
    uint32_t category = v->category ? v->category[id] : 1u;
    uint32_t mask = v->mask ? v->mask[id] : 0xFFFFFFFFu;
    return (p->filter.category & mask) && (category & p->filter.mask);
}

static int by_id(const void *a, const void *b)
{
    uint32_t x = ((const bpx_hit *)a)->id, y = ((const bpx_hit *)b)->id;
    return (x > y) - (x < y);
}

static int by_fraction(const void *a, const void *b)
{
    const bpx_hit *x = a, *y = b;
    if (x->fraction != y->fraction)
        return x->fraction < y->fraction ? -1 : 1;
    return (x->id > y->id) - (x->id < y->id);
}

enum { STACK = 2 * BPX_BVH_MAX_DEPTH };

// BOX and SPHERE: every box the region touches, by id.
static bool region(const bpx_query_view *v, const bpx_query *q, const prepared *p,
                   bpx_hit_list *out)
{
    const bpx_bvh *t = v->tree;
    size_t first = out->count;
    bool sphere = q->kind == BPX_QUERY_SPHERE;
    uint32_t stack[STACK];
    int top = 0;
    if (t->node_count)
        stack[top++] = 0;
    while (top) {
        const bpx_bvh_node *node = &t->nodes[stack[--top]];
        if (sphere ? !touches_sphere(p, node->lo, node->hi) : !overlap(p, node->lo, node->hi))
            continue;
        if (!node->count) {
            stack[top++] = node->second;
            stack[top++] = (uint32_t)(node - t->nodes) + 1;
            continue;
        }
        if (!bpx__hits_reserve(out, node->count)) {
            out->count = first;
            return false;
        }
        for (uint32_t k = node->second; k < node->second + node->count; k++) {
            const bpx_box *b = &t->items[k];
            bool hit = sphere ? touches_sphere(p, b->min, b->max) : overlap(p, b->min, b->max);
            if (hit && seen(v, p, t->ids[k]))
                out->hits[out->count++] = (bpx_hit){t->ids[k], 0.0f};
        }
    }
    if (out->count - first > 1)
        qsort(out->hits + first, out->count - first, sizeof(bpx_hit), by_id);
    return true;
}

// RAY and SWEEP, every hit, by fraction then id.
static bool cast_all(const bpx_query_view *v, const prepared *p, bpx_hit_list *out)
{
    const bpx_bvh *t = v->tree;
    size_t first = out->count;
    uint32_t stack[STACK];
    int top = 0;
    if (t->node_count)
        stack[top++] = 0;
    double enter;
    while (top) {
        const bpx_bvh_node *node = &t->nodes[stack[--top]];
        if (!sweep_hits(p, node->lo, node->hi, &enter))
            continue;
        if (!node->count) {
            stack[top++] = node->second;
            stack[top++] = (uint32_t)(node - t->nodes) + 1;
            continue;
        }
        if (!bpx__hits_reserve(out, node->count)) {
            out->count = first;
            return false;
        }
        for (uint32_t k = node->second; k < node->second + node->count; k++)
            if (sweep_hits(p, t->items[k].min, t->items[k].max, &enter) && seen(v, p, t->ids[k]))
                out->hits[out->count++] = (bpx_hit){t->ids[k], (float)enter};
    }
    if (out->count - first > 1)
        qsort(out->hits + first, out->count - first, sizeof(bpx_hit), by_fraction);
    return true;
}

// RAY and SWEEP, the closest hit: nearer children first, and nothing farther than the best so
// far. Fractions compare as the floats reported, so a tie at the reported fraction still looks
// for a lower id.
static bool cast_closest(const bpx_query_view *v, const prepared *p, bpx_hit_list *out)
{
    const bpx_bvh *t = v->tree;
    bpx_hit best = {UINT32_MAX, INFINITY};
    typedef struct entry {
        uint32_t node;
        float enter; // where the sweep enters the node, as a reported fraction would round
    } entry;
    entry stack[STACK];
    int top = 0;
    double enter;
    if (t->node_count && sweep_hits(p, t->nodes[0].lo, t->nodes[0].hi, &enter))
        stack[top++] = (entry){0, (float)enter};
    while (top) {
        top--;
        if (stack[top].enter > best.fraction)
            continue;
        const bpx_bvh_node *node = &t->nodes[stack[top].node];
        if (node->count) {
            for (uint32_t k = node->second; k < node->second + node->count; k++) {
                if (!sweep_hits(p, t->items[k].min, t->items[k].max, &enter))
                    continue;
                bpx_hit hit = {t->ids[k], (float)enter};
                if ((hit.fraction < best.fraction ||
                     (hit.fraction == best.fraction && hit.id < best.id)) &&
                    seen(v, p, hit.id))
                    best = hit;
            }
            continue;
        }
        uint32_t first = (uint32_t)(node - t->nodes) + 1, second = node->second;
        double e1, e2;
        bool h1 = sweep_hits(p, t->nodes[first].lo, t->nodes[first].hi, &e1);
        bool h2 = sweep_hits(p, t->nodes[second].lo, t->nodes[second].hi, &e2);
        if (h1 && h2 && e2 < e1) { // the nearer on top
            stack[top++] = (entry){first, (float)e1};
            stack[top++] = (entry){second, (float)e2};
            continue;
        }
        if (h2)
            stack[top++] = (entry){second, (float)e2};
        if (h1)
            stack[top++] = (entry){first, (float)e1};
    }
    if (best.id == UINT32_MAX)
        return true;
    if (!bpx__hits_reserve(out, 1))
        return false;
    out->hits[out->count++] = best;
    return true;
}

bool bpx__query_run(const bpx_query_view *view, const bpx_query *query, bpx_hit_list *out)
{
    prepared p = prepare(query);
    switch (query->kind) {
    case BPX_QUERY_BOX:
    case BPX_QUERY_SPHERE:
        return region(view, query, &p, out);
    default:
        return query->closest ? cast_closest(view, &p, out) : cast_all(view, &p, out);
    }
}
