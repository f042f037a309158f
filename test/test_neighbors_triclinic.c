// bpx_find_neighbors with a triclinic cell (bpx_neighbor_def.cell) against a brute force written
// for the purpose: every pair i <= j and every image shift S in a range wide enough for the
// pair (from the fractional coordinates, two periods more each way), the vector
// x_j + S_0 a + S_1 b + S_2 c - x_i in double in the order the header states, kept when its
// length is within the cutoff. Both compute the same double operations, so pairs, shifts and
// distances must agree bit for bit, at any thread count. Cells: general, strongly sheared,
// left-handed, thinner than the cutoff, with open axes; points on the walls and corners,
// outside the cell, n of 0, 1 and 2, random clouds; then the bad cells and points.
#include <float.h>
#include <math.h>

#include "check.h"
#include "neighbors_util.h"

typedef struct ref_list {
    ref_pair *items;
    size_t count, capacity;
} ref_list;

static void push(ref_list *l, ref_pair p)
{
    if (l->count == l->capacity) {
        l->capacity = l->capacity ? 2 * l->capacity : 1024;
        l->items = realloc(l->items, l->capacity * sizeof *l->items);
        if (!l->items)
            abort();
    }
    l->items[l->count++] = p;
}

static void invert(const double H[3][3], double G[3][3])
{
    double det = H[0][0] * (H[1][1] * H[2][2] - H[1][2] * H[2][1]) -
                 H[0][1] * (H[1][0] * H[2][2] - H[1][2] * H[2][0]) +
                 H[0][2] * (H[1][0] * H[2][1] - H[1][1] * H[2][0]);
    // G[c][a]: s_a = sum_c x_c G[c][a]; column a is (b x c) / det for a, etc.
    const double *r[3] = {H[0], H[1], H[2]};
    for (int a = 0; a < 3; a++) {
        const double *u = r[(a + 1) % 3], *v = r[(a + 2) % 3];
        G[0][a] = (u[1] * v[2] - u[2] * v[1]) / det;
        G[1][a] = (u[2] * v[0] - u[0] * v[2]) / det;
        G[2][a] = (u[0] * v[1] - u[1] * v[0]) / det;
    }
}

// Every (i <= j, S) with |x_j + S H - x_i| <= c, as the definition says, sorted.
static void reference(const double *x, uint32_t n, const double H[3][3], const bool open[3],
                      double c, ref_list *out)
{
    out->count = 0;
    double G[3][3];
    invert(H, G);
    double reach[3];
    for (int a = 0; a < 3; a++)
        reach[a] = c * sqrt(G[0][a] * G[0][a] + G[1][a] * G[1][a] + G[2][a] * G[2][a]);
    for (uint32_t i = 0; i < n; i++)
        for (uint32_t j = i; j < n; j++) {
            int32_t first[3], last[3];
            for (int a = 0; a < 3; a++) {
                double d = 0;
                for (int k = 0; k < 3; k++)
                    d += (x[3 * i + k] - x[3 * j + k]) * G[k][a];
                first[a] = last[a] = 0;
                if (!open[a]) {
                    first[a] = (int32_t)floor(d - reach[a]) - 2;
                    last[a] = (int32_t)ceil(d + reach[a]) + 2;
                }
            }
            int32_t S[3];
            for (S[0] = first[0]; S[0] <= last[0]; S[0]++)
                for (S[1] = first[1]; S[1] <= last[1]; S[1]++)
                    for (S[2] = first[2]; S[2] <= last[2]; S[2]++) {
                        if (i == j) { // once per image pair: S's first non-zero > 0
                            int sign = S[0] ? S[0] : S[1] ? S[1] : S[2];
                            if (sign <= 0)
                                continue;
                        }
                        double g[3];
                        for (int k = 0; k < 3; k++) {
                            double p = (double)S[0] * H[0][k] + (double)S[1] * H[1][k] +
                                       (double)S[2] * H[2][k];
                            double image = x[3 * j + k] + p;
                            g[k] = fabs(image - x[3 * i + k]);
                        }
                        double largest = fmax(g[0], fmax(g[1], g[2]));
                        double squares = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
                        if (largest > c || !(squares <= c * c))
                            continue;
                        push(out, (ref_pair){i, j, {S[0], S[1], S[2]}, sqrt(squares)});
                    }
        }
    qsort(out->items, out->count, sizeof *out->items, compare_ref);
}

static uint64_t rng_state = 0x9e3779b97f4a7c15ull;
static double uniform(double lo, double hi)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return lo + (hi - lo) * (double)(rng_state >> 11) * 0x1p-53;
}

static ref_list expected;
static size_t most_images; // the most images of one pair (i, j) seen in any reference
static bool float32_grid;  // points as float32 (they are made float32-exact first)

static void note_images(const ref_list *l)
{
    size_t run = 0;
    for (size_t k = 0; k < l->count; k++) {
        bool same = k > 0 && l->items[k].i == l->items[k - 1].i &&
                    l->items[k].j == l->items[k - 1].j;
        run = same ? run + 1 : 1;
        most_images = run > most_images ? run : most_images;
    }
}

// One configuration at 1 and 3 workers (and as float32 when float32_grid), against the
// reference; returns the pair count.
static size_t check_config(const char *what, const double *x, uint32_t n, const double H[3][3],
                           const bool open[3], double cutoff)
{
    reference(x, n, H, open, cutoff, &expected);
    note_images(&expected);
    if (getenv("BPX_TEST_VERBOSE"))
        printf("%s: n %u cutoff %g: %zu pairs\n", what, n, cutoff, expected.count);
    float *x32 = NULL;
    if (float32_grid) {
        x32 = malloc((3 * (size_t)n + 1) * sizeof *x32);
        for (size_t k = 0; k < 3 * (size_t)n; k++)
            x32[k] = (float)x[k];
    }
    for (int workers = 1; workers <= 3; workers += 2) {
        if (check_quick() && workers == 1)
            continue;
        check_set_context("%s: n %u cutoff %g workers %d %s", what, n, cutoff, workers,
                          x32 ? "float32" : "float64");
        bpx_neighbor_def def = bpx_default_neighbor_def();
        def.format = x32 ? BPX_POINTS_F32 : BPX_POINTS_F64;
        def.metric = BPX_METRIC_EUCLIDEAN;
        def.cutoff = cutoff;
        def.want_distances = true;
        def.worker_count = workers;
        memcpy(def.cell, H, sizeof def.cell);
        memcpy(def.cell_open, open, sizeof def.cell_open);
        bpx_neighbor_list list;
        bpx_error err;
        CHECK_STATUS(bpx_find_neighbors(&def, x32 ? (const void *)x32 : (const void *)x, n,
                                        &list, &err),
                     BPX_OK);
        CHECK_EQ_U64(list.count, expected.count);
        size_t wrong = SIZE_MAX;
        for (size_t k = 0; k < list.count && k < expected.count && wrong == SIZE_MAX; k++) {
            const bpx_image_pair *p = &list.pairs[k];
            const ref_pair *r = &expected.items[k];
            if (p->i != r->i || p->j != r->j || memcmp(p->shift, r->shift, sizeof p->shift) ||
                list.distances[k] != r->distance)
                wrong = k;
        }
        CHECK_MSG(wrong == SIZE_MAX, "pair %zu: got (%u, %u, %d %d %d) %.17g, want (%u, %u, "
                  "%d %d %d) %.17g", wrong,
                  wrong < list.count ? list.pairs[wrong].i : 0,
                  wrong < list.count ? list.pairs[wrong].j : 0,
                  wrong < list.count ? list.pairs[wrong].shift[0] : 0,
                  wrong < list.count ? list.pairs[wrong].shift[1] : 0,
                  wrong < list.count ? list.pairs[wrong].shift[2] : 0,
                  wrong < list.count ? list.distances[wrong] : 0,
                  wrong < expected.count ? expected.items[wrong].i : 0,
                  wrong < expected.count ? expected.items[wrong].j : 0,
                  wrong < expected.count ? expected.items[wrong].shift[0] : 0,
                  wrong < expected.count ? expected.items[wrong].shift[1] : 0,
                  wrong < expected.count ? expected.items[wrong].shift[2] : 0,
                  wrong < expected.count ? expected.items[wrong].distance : 0);
        bpx_neighbor_list_free(&list);
    }
    free(x32);
    return expected.count;
}

// Points at fractional coordinates f (rows) of the cell: x = f H.
static void from_fractional(const double H[3][3], const double *f, uint32_t n, double *x)
{
    for (uint32_t k = 0; k < n; k++)
        for (int c = 0; c < 3; c++)
            x[3 * k + c] = f[3 * k] * H[0][c] + f[3 * k + 1] * H[1][c] + f[3 * k + 2] * H[2][c];
}

static double points[3 * 1500], fractions[3 * 1500];

// The cells, each with the face distances its cutoffs are picked against.
typedef struct cell_case {
    const char *name;
    double H[3][3];
    bool open[3];
} cell_case;

static const cell_case cells[] = {
    {"general", {{5.0, 0.0, 0.0}, {1.25, 4.5, 0.0}, {-0.75, 1.5, 4.0}}, {0, 0, 0}},
    // face distances about 0.6, 1.3 and 2.1 against vectors of length 4 to 9
    {"sheared", {{4.0, 0.0, 0.0}, {7.5, 3.0, 0.0}, {-5.0, 6.25, 2.5}}, {0, 0, 0}},
    {"rotated", {{3.1, 1.7, -0.4}, {-1.2, 3.9, 0.8}, {0.9, -0.6, 4.4}}, {0, 0, 0}},
    {"left-handed", {{1.25, 4.5, 0.0}, {5.0, 0.0, 0.0}, {-0.75, 1.5, 4.0}}, {0, 0, 0}},
    {"thin", {{6.0, 0.0, 0.0}, {2.0, 5.0, 0.0}, {0.5, 0.25, 0.375}}, {0, 0, 0}},
    {"slab (c open)", {{5.0, 0.0, 0.0}, {2.5, 4.25, 0.0}, {0.0, 0.0, 1.0}}, {0, 0, 1}},
    {"wire (a, b open)", {{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.5, -0.75, 3.0}}, {1, 1, 0}},
    {"hexagonal", {{3.0, 0.0, 0.0}, {-1.5, 2.598076211353316, 0.0}, {0.0, 0.0, 4.9}}, {0, 0, 0}},
    // reduced to a near-cube by shifts of up to 20 periods: S' U back in this cell
    {"very sheared", {{1.5, 0.0, 0.0}, {30.375, 1.5, 0.0}, {-20.625, 12.75, 1.5}}, {0, 0, 0}},
    {"sheared slab", {{1.5, 0.0, 0.0}, {30.375, 1.5, 0.0}, {-20.625, 12.75, 1.5}}, {0, 0, 1}},
};

static double smallest_face(const double H[3][3])
{
    double G[3][3], most = 0;
    invert(H, G);
    for (int a = 0; a < 3; a++)
        most = fmax(most, sqrt(G[0][a] * G[0][a] + G[1][a] * G[1][a] + G[2][a] * G[2][a]));
    return 1 / most;
}

// Random clouds (inside the cell, and spread up to 3 cells out) in every cell, at cutoffs
// from a fraction of the thinnest face to twice the thickest.
static void random_clouds(void)
{
    for (size_t c = 0; c < sizeof cells / sizeof cells[0]; c++) {
        const cell_case *cell = &cells[c];
        double face = smallest_face(cell->H);
        double cutoffs[] = {0.3 * face, 0.5 * face, 0.75 * face, 1.6 * face, 2.6};
        for (size_t k = 0; k < sizeof cutoffs / sizeof cutoffs[0]; k++)
            for (int spread = 0; spread < 2; spread++) {
                uint32_t n = spread ? 90 : 160;
                if (strstr(cell->name, "very") || strstr(cell->name, "sheared slab"))
                    n = spread ? 16 : 40; // the reference tries some 10^5 shifts a pair here
                for (uint32_t p = 0; p < 3 * n; p++)
                    fractions[p] = spread ? uniform(-3, 4) : uniform(0, 1);
                from_fractional(cell->H, fractions, n, points);
                char what[96];
                snprintf(what, sizeof what, "random %s%s", cell->name, spread ? " spread" : "");
                float32_grid = false;
                check_config(what, points, n, cell->H, cell->open, cutoffs[k]);
            }
    }
}

// Points on the walls, edges and corners (fractions 0, 1/2, 1, -1, 2 of dyadic cells, so
// x = f H is exact), as float64 and float32, cutoffs that reach exactly the neighbours.
static void walls(void)
{
    static const double dyadic[][3][3] = {
        {{4.0, 0.0, 0.0}, {1.5, 3.0, 0.0}, {-0.5, 0.75, 2.5}},
        {{4.0, 0.0, 0.0}, {7.5, 3.0, 0.0}, {-5.0, 6.25, 2.5}},
    };
    static const double values[] = {0, 0.5, 1, -1, 2, 0.25};
    for (int c = 0; c < 2; c++) {
        uint32_t n = 0;
        for (int x = 0; x < 6; x++)
            for (int y = 0; y < 6; y++)
                for (int z = 0; z < 6; z++)
                    if ((x + 2 * y + 3 * z) % 4 == 0) { // a quarter of them
                        fractions[3 * n] = values[x];
                        fractions[3 * n + 1] = values[y];
                        fractions[3 * n + 2] = values[z];
                        n++;
                    }
        from_fractional(dyadic[c], fractions, n, points);
        static const bool periodic[3] = {0, 0, 0};
        double cutoffs[] = {0, 0.75, 1.5, 2.5, 3.0};
        for (int k = 0; k < 5; k++)
            for (int f32 = 0; f32 < 2; f32++) {
                float32_grid = f32;
                check_config(c ? "walls, sheared" : "walls", points, n, dyadic[c], periodic,
                             cutoffs[k]);
            }
        float32_grid = false;
    }
}

// n of 0, 1 (only its own images) and 2; a point far outside; cutoff 0 with coincident images.
static void tiny(void)
{
    const cell_case *cell = &cells[1]; // sheared
    double face = smallest_face(cell->H);
    double one[3] = {0.3, -0.2, 0.1};
    CHECK(check_config("n = 0", one, 0, cell->H, cell->open, 3.0) == 0);
    CHECK(check_config("n = 1, below the thinnest face", one, 1, cell->H, cell->open,
                       0.9 * face) == 0);
    CHECK(check_config("n = 1, its own images", one, 1, cell->H, cell->open, 6.0) > 4);
    double two[6] = {0.3, -0.2, 0.1, 0.3 + 4.0 * 1000, -0.2, 0.1}; // 1000 periods of a apart
    CHECK(check_config("n = 2, 1000 periods apart", two, 2, cell->H, cell->open, 0.5) == 1);
    if (expected.count == 1)
        CHECK(expected.items[0].shift[0] == -1000 && expected.items[0].distance < 1e-9);
    check_config("n = 2, cutoff 0", two, 2, cell->H, cell->open, 0.0);
}

// A diagonal cell is the orthorhombic cell: the same bytes as period[].
static void diagonal_is_orthorhombic(void)
{
    uint32_t n = 400;
    for (uint32_t p = 0; p < 3 * n; p++)
        points[p] = uniform(-2, 9);
    bpx_neighbor_def a = bpx_default_neighbor_def();
    a.format = BPX_POINTS_F64;
    a.metric = BPX_METRIC_EUCLIDEAN;
    a.cutoff = 1.7;
    a.want_distances = true;
    bpx_neighbor_def b = a;
    a.period[0] = 5;
    a.period[1] = 6;
    b.cell[0][0] = 5;
    b.cell[1][1] = 6;
    b.cell[2][2] = 7;
    b.cell_open[2] = true;
    bpx_neighbor_list la, lb;
    check_set_context("diagonal cell");
    CHECK_STATUS(bpx_find_neighbors(&a, points, n, &la, NULL), BPX_OK);
    CHECK_STATUS(bpx_find_neighbors(&b, points, n, &lb, NULL), BPX_OK);
    CHECK(la.count == lb.count && la.count > 0 &&
          memcmp(la.pairs, lb.pairs, la.count * sizeof *la.pairs) == 0 &&
          memcmp(la.distances, lb.distances, la.count * sizeof *la.distances) == 0);
    // and the triclinic search itself on that cell, through the reference
    double H[3][3] = {{5, 0, 0}, {0, 6, 0}, {0, 0, 7}};
    bool open[3] = {0, 0, 1};
    check_config("diagonal cell, the reference", points, n, H, open, 1.7);
    CHECK(expected.count == la.count);
    bpx_neighbor_list_free(&la);
    bpx_neighbor_list_free(&lb);
}

static bpx_status run_one(bpx_neighbor_def *def, const double *x, uint32_t n, bpx_error *err)
{
    bpx_neighbor_list list;
    bpx_status status = bpx_find_neighbors(def, x, n, &list, err);
    CHECK(status == BPX_OK || (list.count == 0 && list.pairs == NULL));
    bpx_neighbor_list_free(&list);
    return status;
}

static void bad_input(void)
{
    check_set_context("bad input");
    double x[6] = {0.1, 0.2, 0.3, 1.0, 1.0, 1.0};
    bpx_neighbor_def base = bpx_default_neighbor_def();
    base.format = BPX_POINTS_F64;
    base.metric = BPX_METRIC_EUCLIDEAN;
    base.cutoff = 1;
    double good[3][3] = {{3, 0, 0}, {1, 3, 0}, {0.5, 0.5, 3}};
    memcpy(base.cell, good, sizeof good);
    bpx_error err;
    bpx_neighbor_def d = base;
    CHECK_STATUS(run_one(&d, x, 2, &err), BPX_OK);
    // singular: b = 2 a; a zero vector; c in the plane of a and b
    d = base;
    d.cell[1][0] = 6;
    d.cell[1][1] = 0;
    CHECK_STATUS(run_one(&d, x, 2, &err), BPX_ERR_INVALID_ARGUMENT);
    CHECK(strstr(err.message, "singular") != NULL);
    d = base;
    memset(d.cell[2], 0, sizeof d.cell[2]);
    CHECK_STATUS(run_one(&d, x, 2, &err), BPX_ERR_INVALID_ARGUMENT);
    d = base;
    d.cell[2][0] = 4; // c = a + b
    d.cell[2][1] = 3;
    d.cell[2][2] = 0;
    CHECK_STATUS(run_one(&d, x, 2, &err), BPX_ERR_INVALID_ARGUMENT);
    // an open axis still needs its vector
    d = base;
    memset(d.cell[2], 0, sizeof d.cell[2]);
    d.cell_open[2] = true;
    CHECK_STATUS(run_one(&d, x, 2, &err), BPX_ERR_INVALID_ARGUMENT);
    // nearly singular: c a hair off the plane of a and b
    d = base;
    d.cell[2][2] = 1e-9;
    CHECK_STATUS(run_one(&d, x, 2, &err), BPX_ERR_INVALID_ARGUMENT);
    CHECK(strstr(err.message, "close to singular") != NULL);
    // NaN, infinite, huge entries
    double bad[] = {NAN, INFINITY, -INFINITY, 0x1p961};
    for (int k = 0; k < 4; k++) {
        d = base;
        d.cell[1][2] = bad[k];
        CHECK_STATUS(run_one(&d, x, 2, &err), BPX_ERR_INVALID_ARGUMENT);
        CHECK(strstr(err.message, "cell[1][2]") != NULL);
    }
    // a period beside the cell; boxes; the box metric
    d = base;
    d.period[0] = 3;
    CHECK_STATUS(run_one(&d, x, 2, &err), BPX_ERR_INVALID_ARGUMENT);
    d = base;
    d.format = BPX_BOXES_F64;
    CHECK_STATUS(run_one(&d, x, 1, &err), BPX_ERR_INVALID_ARGUMENT);
    d = base;
    d.metric = BPX_METRIC_BOX;
    CHECK_STATUS(run_one(&d, x, 2, &err), BPX_ERR_INVALID_ARGUMENT);
    // bad cutoffs, as without a cell
    double cutoffs[] = {-1, NAN, INFINITY};
    for (int k = 0; k < 3; k++) {
        d = base;
        d.cutoff = cutoffs[k];
        CHECK_STATUS(run_one(&d, x, 2, &err), BPX_ERR_INVALID_ARGUMENT);
    }
    // a cutoff past 2^20 face distances; one whose images around a bin pass 2^24
    d = base;
    d.cutoff = 0x1p23;
    CHECK_STATUS(run_one(&d, x, 2, &err), BPX_ERR_TOO_MANY_BOXES);
    d.cutoff = 3000;
    CHECK_STATUS(run_one(&d, x, 2, &err), BPX_ERR_TOO_MANY_BOXES);
    // a checked cell even with no points
    d = base;
    d.cell[0][0] = NAN;
    CHECK_STATUS(run_one(&d, x, 0, &err), BPX_ERR_INVALID_ARGUMENT);
    // points: not finite (named), beyond 2^1000, past 2^29 cells
    d = base;
    double nan_point[6] = {0, 0, 0, 1, NAN, 1};
    CHECK_STATUS(run_one(&d, nan_point, 2, &err), BPX_ERR_NOT_FINITE);
    CHECK(err.index == 1 && err.axis == 1);
    double huge[6] = {0, 0, 0, 0x1p1001, 0, 0};
    CHECK_STATUS(run_one(&d, huge, 2, &err), BPX_ERR_INVALID_ARGUMENT);
    double far[6] = {0, 0, 0, 0x1p32, 0, 0};
    CHECK_STATUS(run_one(&d, far, 2, &err), BPX_ERR_TOO_MANY_BOXES);
    CHECK(err.index == 1);
    d.cell_open[0] = d.cell_open[1] = d.cell_open[2] = true; // far is fine on open axes
    CHECK_STATUS(run_one(&d, far, 2, &err), BPX_OK);
}

int main(void)
{
    int64_t start = bpx_allocated_bytes();
    random_clouds();
    walls();
    tiny();
    diagonal_is_orthorhombic();
    bad_input();
    // The configurations above include pairs met at several images.
    CHECK_MSG(most_images >= 4, "at most %zu images of one pair", most_images);
    printf("test_neighbors_triclinic: up to %zu images of one pair\n", most_images);
    free(expected.items);
    CHECK(bpx_allocated_bytes() == start);
    return check_finish("test_neighbors_triclinic", 1);
}
