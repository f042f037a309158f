// The cell-list search for points (bpx_find_neighbors with the auto backend): points binned
// into cells at least a cutoff wide, then for each point i in id order the points j > i of the
// 27 cells around it, so that each point's pairs come out already in (i, j) order and no
// comparator, image or global sort is needed. A candidate passes a quick test (the distance as
// bpx__within computes it, against the cutoff widened past rounding) before the exact one
// (bpx__within itself, as the image search decides: the two give the same bits).
#include <float.h>
#include <string.h>

#include "../core/alloc.h"
#include "../core/validate.h"
#include "search.h"

// Cells per axis at most, and in all at most about two per point (a tiny cutoff would make
// empty cells by the million).
#define MAX_CELLS_PER_AXIS (1 << 20)

typedef struct grid {
    int count[3];      // cells on each axis
    double origin[3];  // open axes: the least coordinate; periodic: 0
    double inverse[3]; // cells per unit of length
    double slack;      // added to the cutoff in the quick test: more than its rounding
} grid;

// One point in cell order: its coordinates as given, which it is, and its wrap.
typedef struct slot {
    double x[3];
    uint32_t id;
    int32_t wrap[3];
} slot;

// A candidate of point i: j, the image's shift, the distance.
typedef struct hit {
    uint32_t j;
    int32_t shift[3];
    double distance;
} hit;

// Lays out the cells; false when a periodic axis cannot have 3 cells of the cutoff (then two
// cells around a point would be one, and the image search is the one to use).
static bool plan(const search *s, grid *g)
{
    const double *points64 = s->in.format == BPX_POINTS_F64 ? s->in.data : NULL;
    const float *points32 = points64 ? NULL : s->in.data;
    double least[3] = {INFINITY, INFINITY, INFINITY}, most[3] = {-INFINITY, -INFINITY, -INFINITY};
    double magnitude = 0;
    for (size_t k = 0; k < 3 * (size_t)s->n; k++) {
        double v = points64 ? points64[k] : points32[k];
        least[k % 3] = v < least[k % 3] ? v : least[k % 3];
        most[k % 3] = v > most[k % 3] ? v : most[k % 3];
    }
    for (int a = 0; a < 3; a++) {
        magnitude = fmax(magnitude, fmax(fabs(least[a]), fabs(most[a])));
        magnitude = fmax(magnitude, s->period[a]);
    }
    double c = s->def->cutoff;
    // Wrapping and scaling round by a few ulps of the largest magnitude; cells wider than the
    // cutoff by far more than that keep every pair within adjacent cells.
    g->slack = 0x1p-40 * (magnitude + c);
    double width = c + 4 * g->slack;
    if (!(width > 0)) // every point at 0 and no cutoff: any width will do
        width = 1;
    double cells = 1;
    for (int a = 0; a < 3; a++) {
        double L = s->period[a], extent = most[a] - least[a];
        g->origin[a] = L > 0 ? 0 : least[a];
        if (L > 0) {
            double count = fmin(floor(L / width), MAX_CELLS_PER_AXIS);
            if (count < 3)
                return false;
            g->count[a] = (int)count;
            g->inverse[a] = count / L;
        } else {
            g->inverse[a] = fmin(1 / width, (MAX_CELLS_PER_AXIS - 1) / fmax(extent, DBL_MIN));
            g->count[a] = (int)floor(extent * g->inverse[a]) + 1;
        }
        cells *= g->count[a];
    }
    // Too many cells for the points: halve the longest axis until there are not.
    double enough = 2.0 * s->n + 64;
    while (cells > enough) {
        int a = 0;
        for (int b = 1; b < 3; b++)
            if (g->count[b] > g->count[a])
                a = b;
        double L = s->period[a];
        int fewer = L > 0 ? g->count[a] / 2 : (int)floor((most[a] - least[a]) * g->inverse[a] / 2) + 1;
        if (fewer >= g->count[a] || (L > 0 && fewer < 3))
            break;
        cells = cells / g->count[a] * fewer;
        g->count[a] = fewer;
        g->inverse[a] = L > 0 ? fewer / L : g->inverse[a] / 2;
    }
    return true;
}

static void point_of(const search *s, uint32_t k, double x[3])
{
    if (s->in.format == BPX_POINTS_F64)
        memcpy(x, (const double *)s->in.data + 3 * (size_t)k, 3 * sizeof(double));
    else
        for (int a = 0; a < 3; a++)
            x[a] = ((const float *)s->in.data)[3 * (size_t)k + a];
}

// The cell of point k on each axis, its coordinates and its wrap (periodic axes).
static void locate(const search *s, const grid *g, uint32_t k, int cell[3], double x[3],
                   int32_t wrap[3])
{
    point_of(s, k, x);
    for (int a = 0; a < 3; a++) {
        double L = s->period[a];
        if (L == 0) {
            wrap[a] = 0;
            int c = (int)floor((x[a] - g->origin[a]) * g->inverse[a]);
            cell[a] = c < 0 ? 0 : (c >= g->count[a] ? g->count[a] - 1 : c);
            continue;
        }
        double w = floor(x[a] / L);
        double in_cell = x[a] - w * L;
        int c = (int)floor(in_cell * g->inverse[a]);
        // Rounding can put a point a cell past either end; it is then the same point one
        // period over, so move its wrap with it rather than clamp.
        if (c >= g->count[a]) {
            c -= g->count[a];
            w += 1;
        } else if (c < 0) {
            c += g->count[a];
            w -= 1;
        }
        wrap[a] = (int32_t)w;
        cell[a] = c;
    }
}

static bpx_status no_memory(const search *s)
{
    return bpx__error(s->err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                      "no memory for the cells of %u points", s->n);
}

// Appends point i's hits, sorted by j, to the list.
static bool append(const search *s, hit *hits, size_t count, uint32_t i, bpx_neighbor_list *list)
{
    for (size_t a = 1; a < count; a++) { // a handful each: insertion sort
        hit h = hits[a];
        size_t b = a;
        for (; b > 0 && hits[b - 1].j > h.j; b--)
            hits[b] = hits[b - 1];
        hits[b] = h;
    }
    bool want = s->def->want_distances;
    if (!bpx__neighbors_reserve(list, list->count + count, want))
        return false;
    for (size_t a = 0; a < count; a++) {
        bpx_image_pair *p = &list->pairs[list->count + a];
        p->i = i;
        p->j = hits[a].j;
        memcpy(p->shift, hits[a].shift, sizeof p->shift);
        if (want)
            list->distances[list->count + a] = hits[a].distance;
    }
    list->count += count;
    return true;
}

// A neighbour cell of the cell being searched: its slots, and the periods it is moved by.
typedef struct neighbour {
    uint32_t begin, end;
    int32_t t[3];
} neighbour;

// The (up to 27) cells around cell (x, y, z), each once.
static int neighbours_of(const search *s, const grid *g, const uint32_t *start, const int cell[3],
                         neighbour out[27])
{
    int count = 0;
    for (int dz = -1; dz <= 1; dz++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                int offset[3] = {dx, dy, dz}, at[3];
                neighbour nb = {0};
                bool inside = true;
                for (int a = 0; a < 3; a++) {
                    at[a] = cell[a] + offset[a];
                    if (at[a] < 0 || at[a] >= g->count[a]) {
                        if (s->period[a] == 0) {
                            inside = false;
                            break;
                        }
                        nb.t[a] = at[a] < 0 ? -1 : 1;
                        at[a] -= nb.t[a] * g->count[a];
                    }
                }
                if (!inside)
                    continue;
                size_t index = ((size_t)at[2] * g->count[1] + at[1]) * g->count[0] + at[0];
                nb.begin = start[index];
                nb.end = start[index + 1];
                if (nb.begin < nb.end)
                    out[count++] = nb;
            }
    return count;
}

// Point i's hits among the neighbour cells' points j > i.
static size_t search_point(const search *s, const grid *g, const slot *i, const slot *slots,
                           const neighbour *near, int near_count, hit *hits)
{
    double c = s->def->cutoff;
    double reach = c + g->slack; // the quick test's cutoff: never below the exact one's
    bool euclidean = s->def->metric == BPX_METRIC_EUCLIDEAN;
    size_t count = 0;
    for (int n = 0; n < near_count; n++) {
        double base[3]; // the periods between i and this cell's points, but for their wraps
        for (int a = 0; a < 3; a++)
            base[a] = near[n].t[a] + i->wrap[a];
        for (uint32_t k = near[n].begin; k < near[n].end; k++) {
            const slot *j = &slots[k];
            if (j->id <= i->id)
                continue;
            // The gap as bpx__within computes it, against the widened cutoff.
            double far = 0, squares = 0;
            for (int a = 0; a < 3; a++) {
                double d = (j->x[a] + (base[a] - j->wrap[a]) * s->period[a]) - i->x[a];
                d = d < 0 ? -d : d;
                far = d > far ? d : far;
                squares += d * d;
            }
            if (euclidean ? squares > reach * reach : far > reach)
                continue;
            hit h = {.j = j->id};
            for (int a = 0; a < 3; a++)
                h.shift[a] = near[n].t[a] + i->wrap[a] - j->wrap[a];
            if (bpx__within(s, i->x, i->x, j->x, j->x, h.shift, &h.distance))
                hits[count++] = h;
        }
    }
    return count;
}

bpx_status bpx__neighbors_cells(const search *s, bpx_neighbor_list *list)
{
    grid g;
    if (!plan(s, &g))
        return BPX_ERR_BAD_STATE;
    size_t cells = (size_t)g.count[0] * g.count[1] * g.count[2];
    uint32_t *start = bpx__alloc((cells + 1) * sizeof *start);
    uint32_t *home = bpx__alloc((size_t)s->n * sizeof *home); // each point's cell
    slot *slots = bpx__alloc((size_t)s->n * sizeof *slots);
    size_t *first = bpx__alloc((size_t)s->n * sizeof *first); // each point's hits in `found`
    bpx_neighbor_list found = {0}; // the hits in cell order, gathered into id order at the end
    bpx_status status = BPX_OK;
    hit *hits = NULL;
    size_t hits_capacity = 0;
    if (!start || !home || !slots || !first) {
        status = no_memory(s);
        goto done;
    }
    // Counting sort of the points into cells.
    memset(start, 0, (cells + 1) * sizeof *start);
    for (uint32_t k = 0; k < s->n; k++) {
        int cell[3];
        double x[3];
        int32_t wrap[3];
        locate(s, &g, k, cell, x, wrap);
        home[k] = (uint32_t)(((size_t)cell[2] * g.count[1] + cell[1]) * g.count[0] + cell[0]);
        start[home[k] + 1]++;
    }
    uint32_t fullest = 0;
    for (size_t c = 0; c < cells; c++) {
        fullest = start[c + 1] > fullest ? start[c + 1] : fullest;
        start[c + 1] += start[c];
    }
    for (uint32_t k = 0; k < s->n; k++) {
        int cell[3];
        slot *to = &slots[start[home[k]]++];
        locate(s, &g, k, cell, to->x, to->wrap);
        to->id = k;
    }
    for (size_t c = cells; c > 0; c--) // start[c] ran to the end of cell c: shift back
        start[c] = start[c - 1];
    start[0] = 0;
    hits_capacity = 27 * (size_t)fullest;
    hits = bpx__alloc(hits_capacity * sizeof *hits);
    if (!hits) {
        status = no_memory(s);
        goto done;
    }
    // Cell by cell, so that the points searched stay in cache from one point to the next.
    int cell[3];
    for (cell[2] = 0; cell[2] < g.count[2]; cell[2]++)
        for (cell[1] = 0; cell[1] < g.count[1]; cell[1]++)
            for (cell[0] = 0; cell[0] < g.count[0]; cell[0]++) {
                size_t index = ((size_t)cell[2] * g.count[1] + cell[1]) * g.count[0] + cell[0];
                if (start[index] == start[index + 1])
                    continue;
                neighbour near[27];
                int near_count = neighbours_of(s, &g, start, cell, near);
                for (uint32_t k = start[index]; k < start[index + 1]; k++) {
                    size_t count = search_point(s, &g, &slots[k], slots, near, near_count, hits);
                    first[slots[k].id] = found.count;
                    home[slots[k].id] = (uint32_t)count; // home is free now: the hit counts
                    if (!append(s, hits, count, slots[k].id, &found)) {
                        status = no_memory(s);
                        goto done;
                    }
                }
            }
    // Gathered into (i, j) order.
    bool want = s->def->want_distances;
    if (found.count && !bpx__neighbors_reserve(list, found.count, want)) {
        status = no_memory(s);
        goto done;
    }
    for (uint32_t i = 0; i < s->n; i++) {
        memcpy(list->pairs + list->count, found.pairs + first[i], home[i] * sizeof *list->pairs);
        if (want)
            memcpy(list->distances + list->count, found.distances + first[i],
                   home[i] * sizeof *list->distances);
        list->count += home[i];
    }
done:
    bpx__free(start, (cells + 1) * sizeof *start);
    bpx__free(home, (size_t)s->n * sizeof *home);
    bpx__free(slots, (size_t)s->n * sizeof *slots);
    bpx__free(first, (size_t)s->n * sizeof *first);
    bpx__free(hits, hits_capacity * sizeof *hits);
    bpx_neighbor_list_free(&found);
    if (status != BPX_OK)
        bpx_neighbor_list_free(list);
    return status;
}
