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
#include "../parallel/pool.h"
#include "search.h"

// Cells per axis at most, and in all at most about two per point (a tiny cutoff would make
// empty cells by the million).
#define MAX_CELLS_PER_AXIS (1 << 20)

typedef struct grid {
    int cells_each_way; // cells searched each way (cells 1 / cells_each_way of the cutoff)
    int count[3];      // cells on each axis
    double origin[3];  // open axes: the least coordinate; periodic: 0
    double inverse[3]; // cells per unit of length
    double slack;      // more than the rounding of wrapping and cell indices
    float reach;       // the quick test's cutoff in float: past the cutoff by its rounding
    float reach2;      // reach squared, rounded up
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

// The cells for g->cells_each_way (g->slack set); false when a periodic axis is too short for them.
static bool lay_out(const search *s, grid *g, const double least[3], const double most[3])
{
    int fewest = 2 * g->cells_each_way + 1;
    double width = (s->def->cutoff + 4 * g->slack) / g->cells_each_way;
    // Cells far narrower than this would take 1 / width past double's range (all the points
    // within 2^-900 of 0 and no cutoff); wider cells are always right.
    if (!(width > 0x1p-900))
        width = 0x1p-900;
    double cells = 1;
    for (int a = 0; a < 3; a++) {
        double L = s->period[a], extent = most[a] - least[a];
        g->origin[a] = L > 0 ? 0 : least[a];
        if (L > 0) {
            double count = fmin(floor(L / width), MAX_CELLS_PER_AXIS);
            if (count < fewest)
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
        int fewer = L > 0 ? g->count[a] / 2
                          : (int)floor((most[a] - least[a]) * g->inverse[a] / 2) + 1;
        if (fewer >= g->count[a] || (L > 0 && fewer < fewest))
            break;
        cells = cells / g->count[a] * fewer;
        g->count[a] = fewer;
        g->inverse[a] = L > 0 ? fewer / L : g->inverse[a] / 2;
    }
    return true;
}

// Lays out the cells; false when a periodic axis cannot have 3 cells of the cutoff (then two
// cells around a point would be one cell, and the image search is the one to use).
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
    // Wrapping and scaling round by a few ulps of the largest magnitude; cells wider (all
    // `reach` of them together) than the cutoff by far more than that keep every pair within
    // `reach` cells of each other on each axis.
    g->slack = 0x1p-40 * (magnitude + s->def->cutoff);
    // The quick test runs in float on wrapped coordinates (at most `magnitude`): its error is a
    // few float ulps of that, far under 2^-18 of it. Past 2^60 float's range gets near.
    if (!(magnitude < 0x1p60))
        return false;
    double reach = s->def->cutoff + 0x1p-18 * (magnitude + s->def->cutoff);
    g->reach2 = (float)(reach * reach);
    g->reach2 = nextafterf(g->reach2, INFINITY);
    g->reach = nextafterf((float)reach, INFINITY);
    // Cells as wide as the cutoff, searched 1 each way. (Cells half as wide, searched 2 each
    // way, hold fewer points too far away, but their runs along x are too short for the quick
    // test's SIMD loop: 1.6 times slower at 100k points, 1.2 at 1M.)
    g->cells_each_way = 1;
    return lay_out(s, g, least, most);
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
static bool append(const search *s, const hit *hits, uint64_t *keys, size_t count, uint32_t i,
                   bpx_neighbor_list *list)
{
    // Sorted as (j, position) keys, a handful each: insertion sort of 8 bytes, not of the hits.
    for (size_t a = 0; a < count; a++) {
        uint64_t key = (uint64_t)hits[a].j << 32 | a;
        size_t b = a;
        for (; b > 0 && keys[b - 1] > key; b--)
            keys[b] = keys[b - 1];
        keys[b] = key;
    }
    bool want = s->def->want_distances;
    if (!bpx__neighbors_reserve(list, list->count + count, want))
        return false;
    for (size_t a = 0; a < count; a++) {
        const hit *h = &hits[(uint32_t)keys[a]];
        bpx_image_pair *p = &list->pairs[list->count + a];
        p->i = i;
        p->j = h->j;
        memcpy(p->shift, h->shift, sizeof p->shift);
        if (want)
            list->distances[list->count + a] = h->distance;
    }
    list->count += count;
    return true;
}

// A run of points to search for the points of one cell: neighbour cells next to each other in
// slot order (x - 1 .. x + 1 on a row, when no face of the cell is crossed between them), and
// the periods they are moved by.
typedef struct run {
    uint32_t begin, end;
    int32_t t[3];
} run;

// Most runs around a cell: (2 reach + 1)^2 rows, each split in at most 2 reach + 1 cells.
enum { MAX_RUNS = 125 };

// The runs covering the cells within g->cells_each_way of cell (x, y, z), each cell once.
static int runs_around(const search *s, const grid *g, const uint32_t *start, const int cell[3],
                       run out[MAX_RUNS])
{
    int count = 0, R = g->cells_each_way;
    for (int dz = -R; dz <= R; dz++)
        for (int dy = -R; dy <= R; dy++) {
            int row[3] = {0, cell[1] + dy, cell[2] + dz};
            int32_t t[3] = {0, 0, 0};
            bool inside = true;
            for (int a = 1; a < 3; a++)
                if (row[a] < 0 || row[a] >= g->count[a]) {
                    if (s->period[a] == 0)
                        inside = false;
                    t[a] = row[a] < 0 ? -1 : 1;
                    row[a] -= t[a] * g->count[a];
                }
            if (!inside)
                continue;
            size_t row_start = ((size_t)row[2] * g->count[1] + row[1]) * g->count[0];
            int lo = cell[0] - R, hi = cell[0] + R;
            if (lo >= 0 && hi < g->count[0]) { // one run, no face crossed
                run r = {start[row_start + lo], start[row_start + hi + 1], {0, t[1], t[2]}};
                if (r.begin < r.end)
                    out[count++] = r;
                continue;
            }
            for (int x = lo; x <= hi; x++) {
                run r = {0, 0, {0, t[1], t[2]}};
                int at = x;
                if (at < 0 || at >= g->count[0]) {
                    if (s->period[0] == 0)
                        continue;
                    r.t[0] = at < 0 ? -1 : 1;
                    at -= r.t[0] * g->count[0];
                }
                r.begin = start[row_start + at];
                r.end = start[row_start + at + 1];
                if (r.begin < r.end)
                    out[count++] = r;
            }
        }
    return count;
}

// The points in cell order: wrapped coordinates for the quick test (structure of arrays), and
// the slots, with the input coordinates, for the exact one.
typedef struct cell_points {
    float *wrapped[3];
    slot *slots;
} cell_points;

// bpx__within for two points and the Euclidean metric, the same operations in the same order
// (for a point the gap is |j + shift L - i|, and squaring drops the sign), without the box
// metric's exact sums.
static inline bool points_within(const search *s, const double xi[3], const double xj[3],
                                 const int32_t shift[3], double *distance)
{
    double gaps[3];
    for (int a = 0; a < 3; a++) {
        double p = (double)shift[a] * s->period[a];
        double image = xj[a] + p;
        double gap = image - xi[a];
        gaps[a] = gap < 0 ? -gap : gap;
    }
    return bpx__euclidean_within(gaps, s->def->cutoff, distance);
}

// Point k's hits among the runs' points j > i. near, passed: room for a run's points.
static size_t search_point(const search *s, const grid *g, const cell_points *p, uint32_t k,
                           const run *runs, int run_count, float *near, uint32_t *passed,
                           hit *hits)
{
    bool euclidean = s->def->metric == BPX_METRIC_EUCLIDEAN;
    const slot *i = &p->slots[k];
    const float *x = p->wrapped[0], *y = p->wrapped[1], *z = p->wrapped[2];
    size_t count = 0;
    for (int r = 0; r < run_count; r++) {
        // j's wrapped position plus these is its offset from i, to within float rounding.
        float o[3];
        for (int a = 0; a < 3; a++)
            o[a] = (float)(runs[r].t[a] * s->period[a]) - p->wrapped[a][k];
        uint32_t begin = runs[r].begin, length = runs[r].end - runs[r].begin;
        // The quick test over the whole run first: a loop the compiler turns into SIMD.
        float limit;
        if (euclidean) {
            for (uint32_t m = 0; m < length; m++) {
                float dx = x[begin + m] + o[0], dy = y[begin + m] + o[1], dz = z[begin + m] + o[2];
                near[m] = dx * dx + dy * dy + dz * dz;
            }
            limit = g->reach2;
        } else {
            for (uint32_t m = 0; m < length; m++) {
                float dx = fabsf(x[begin + m] + o[0]), dy = fabsf(y[begin + m] + o[1]);
                float dz = fabsf(z[begin + m] + o[2]);
                float far = dx > dy ? dx : dy;
                near[m] = far > dz ? far : dz;
            }
            limit = g->reach;
        }
        // The few that pass, listed without a branch per point (which would mispredict).
        uint32_t passed_count = 0;
        for (uint32_t m = 0; m < length; m++) {
            bool pass = near[m] <= limit;
            passed[passed_count] = m;
            passed_count += pass;
        }
        for (uint32_t q = 0; q < passed_count; q++) {
            uint32_t m = passed[q];
            const slot *j = &p->slots[begin + m];
            if (j->id <= i->id)
                continue;
            hit h = {.j = j->id};
            for (int a = 0; a < 3; a++)
                h.shift[a] = runs[r].t[a] + i->wrap[a] - j->wrap[a];
            if (euclidean ? points_within(s, i->x, j->x, h.shift, &h.distance)
                          : bpx__within(s, i->x, i->x, j->x, j->x, h.shift, &h.distance))
                hits[count++] = h;
        }
    }
    return count;
}

// Pairs (i < j) per point were the points spread evenly over the cell, or over their bounds on
// open axes: a guess to size the lists by, at most 64.
static double expected_pairs(const search *s, const grid *g)
{
    double volume = 1;
    for (int a = 0; a < 3; a++)
        volume *= s->period[a] > 0 ? s->period[a] : g->count[a] / fmax(g->inverse[a], DBL_MIN);
    double c = s->def->cutoff;
    double reach = s->def->metric == BPX_METRIC_EUCLIDEAN ? 4.18879 * c * c * c : 8 * c * c * c;
    double per_point = 0.5 * s->n * reach / volume;
    return per_point < 64 ? per_point : 64;
}

// One share of the search: rows of cells (a row: the cells along x at one y and z), their
// points' hits in cell order in `found`, each point's place in it in `first` and `counts`.
typedef struct share {
    bpx_neighbor_list found;
    bpx_status status;
} share;

typedef struct search_job {
    const search *s;
    const grid *g;
    const uint32_t *start;
    const cell_points *points;
    size_t hits_capacity; // most hits of one point: points in the cells around the fullest
    size_t run_capacity;  // most points in one run
    double pairs_per_point; // expected, were the points uniform
    int share_count;
    share *shares;
    size_t *first;    // per point: where its hits begin in its share's list
    uint32_t *counts; // per point: how many
    uint16_t *owner;  // per point: its share
} search_job;

static void search_share(int begin, int end, int worker, void *context)
{
    (void)worker;
    const search_job *job = context;
    const search *s = job->s;
    const grid *g = job->g;
    size_t rows = (size_t)g->count[1] * g->count[2];
    hit *hits = bpx__alloc(job->hits_capacity * sizeof *hits);
    uint64_t *keys = bpx__alloc(job->hits_capacity * sizeof *keys);
    float *near = bpx__alloc(job->run_capacity * sizeof *near);
    uint32_t *passed = bpx__alloc(job->run_capacity * sizeof *passed);
    for (int k = begin; k < end; k++) {
        share *sh = &job->shares[k];
        if (!hits || !keys || !near || !passed) {
            sh->status = BPX_ERR_OUT_OF_MEMORY;
            continue;
        }
        size_t row_begin = rows * (size_t)k / job->share_count;
        size_t row_end = rows * (size_t)(k + 1) / job->share_count;
        // Room for the pairs expected, so that the list rarely grows by copying.
        size_t points = job->start[row_end * g->count[0]] - job->start[row_begin * g->count[0]];
        double expected = points * job->pairs_per_point * 1.1 + 256;
        if (!bpx__neighbors_reserve(&sh->found, (size_t)fmin(expected, 1e9),
                                    s->def->want_distances)) {
            sh->status = BPX_ERR_OUT_OF_MEMORY;
            continue;
        }
        for (size_t row = row_begin; row < row_end; row++) {
            int cell[3] = {0, (int)(row % g->count[1]), (int)(row / g->count[1])};
            for (cell[0] = 0; cell[0] < g->count[0]; cell[0]++) {
                size_t index = row * g->count[0] + cell[0];
                if (job->start[index] == job->start[index + 1])
                    continue;
                run runs[MAX_RUNS];
                int run_count = runs_around(s, g, job->start, cell, runs);
                for (uint32_t m = job->start[index]; m < job->start[index + 1]; m++) {
                    size_t count =
                        search_point(s, g, job->points, m, runs, run_count, near, passed, hits);
                    uint32_t id = job->points->slots[m].id;
                    job->first[id] = sh->found.count;
                    job->counts[id] = (uint32_t)count;
                    job->owner[id] = (uint16_t)k;
                    if (!append(s, hits, keys, count, id, &sh->found)) {
                        sh->status = BPX_ERR_OUT_OF_MEMORY;
                        goto next_share;
                    }
                }
            }
        }
    next_share:;
    }
    bpx__free(hits, job->hits_capacity * sizeof *hits);
    bpx__free(keys, job->hits_capacity * sizeof *keys);
    bpx__free(near, job->run_capacity * sizeof *near);
    bpx__free(passed, job->run_capacity * sizeof *passed);
}

bpx_status bpx__neighbors_cells(const search *s, bpx_neighbor_list *list)
{
    grid g;
    if (!plan(s, &g))
        return BPX_ERR_BAD_STATE;
    size_t cells = (size_t)g.count[0] * g.count[1] * g.count[2];
    size_t rows = (size_t)g.count[1] * g.count[2];
    int workers = s->def->worker_count > 1 ? s->def->worker_count : 1;
    // Shares: a few per worker, for balance; one on one thread.
    int share_count = workers == 1 ? 1 : (int)(rows < 8u * workers ? rows : 8u * workers);
    uint32_t *start = bpx__alloc((cells + 1) * sizeof *start);
    uint32_t *home = bpx__alloc((size_t)s->n * sizeof *home); // each point's cell
    slot *slots = bpx__alloc((size_t)s->n * sizeof *slots);
    float *wrapped = bpx__alloc(3 * (size_t)s->n * sizeof *wrapped);
    size_t *first = bpx__alloc((size_t)s->n * sizeof *first);
    uint32_t *counts = bpx__alloc((size_t)s->n * sizeof *counts);
    uint16_t *owner = bpx__alloc((size_t)s->n * sizeof *owner);
    share *shares = bpx__alloc((size_t)share_count * sizeof *shares);
    bpx_pool *pool = NULL;
    bpx_status status = BPX_OK;
    if (shares)
        memset(shares, 0, (size_t)share_count * sizeof *shares);
    if (!start || !home || !slots || !wrapped || !first || !counts || !owner || !shares) {
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
    cell_points points = {{wrapped, wrapped + s->n, wrapped + 2 * (size_t)s->n}, slots};
    for (uint32_t k = 0; k < s->n; k++) {
        int cell[3];
        uint32_t at = start[home[k]]++;
        slot *to = &slots[at];
        locate(s, &g, k, cell, to->x, to->wrap);
        to->id = k;
        for (int a = 0; a < 3; a++)
            points.wrapped[a][at] = (float)(to->x[a] - (double)to->wrap[a] * s->period[a]);
    }
    for (size_t c = cells; c > 0; c--) // start[c] ran to the end of cell c: shift back
        start[c] = start[c - 1];
    start[0] = 0;
    // The search, share by share; cells in order within one, so that the points searched stay
    // in cache from one point to the next.
    int side = 2 * g.cells_each_way + 1;
    search_job job = {s,
                      &g,
                      start,
                      &points,
                      (size_t)side * side * side * fullest < s->n
                          ? (size_t)side * side * side * fullest
                          : s->n,
                      (size_t)side * fullest,
                      expected_pairs(s, &g),
                      share_count,
                      shares,
                      first,
                      counts,
                      owner};
    bpx_executor executor = {.worker_count = 1};
    if (workers > 1) {
        if (!(pool = bpx__pool_create(workers - 1, -1))) {
            status = bpx__error(s->err, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                                "no memory or threads for %d workers", workers);
            goto done;
        }
        executor = (bpx_executor){.pool = pool, .worker_count = workers};
    }
    bpx__parallel_for(&executor, search_share, share_count, &job);
    for (int k = 0; k < share_count; k++)
        if (shares[k].status != BPX_OK) {
            status = no_memory(s);
            goto done;
        }
    // Gathered into (i, j) order.
    size_t total = 0;
    for (int k = 0; k < share_count; k++)
        total += shares[k].found.count;
    bool want = s->def->want_distances;
    if (total && !bpx__neighbors_reserve(list, total, want)) {
        status = no_memory(s);
        goto done;
    }
    for (uint32_t i = 0; i < s->n; i++) {
        if (counts[i] == 0)
            continue;
        const bpx_neighbor_list *from = &shares[owner[i]].found;
        memcpy(list->pairs + list->count, from->pairs + first[i], counts[i] * sizeof *list->pairs);
        if (want)
            memcpy(list->distances + list->count, from->distances + first[i],
                   counts[i] * sizeof *list->distances);
        list->count += counts[i];
    }
done:
    bpx__pool_destroy(pool);
    bpx__free(start, (cells + 1) * sizeof *start);
    bpx__free(home, (size_t)s->n * sizeof *home);
    bpx__free(slots, (size_t)s->n * sizeof *slots);
    bpx__free(wrapped, 3 * (size_t)s->n * sizeof *wrapped);
    bpx__free(first, (size_t)s->n * sizeof *first);
    bpx__free(counts, (size_t)s->n * sizeof *counts);
    bpx__free(owner, (size_t)s->n * sizeof *owner);
    if (shares)
        for (int k = 0; k < share_count; k++)
            bpx_neighbor_list_free(&shares[k].found);
    bpx__free(shares, (size_t)share_count * sizeof *shares);
    if (status != BPX_OK)
        bpx_neighbor_list_free(list);
    return status;
}
