// bpx_find_neighbors and bpx_find_pairs_f64 against a brute-force reference over every periodic
// image, written for the purpose: every pair of objects and every shift in a range wide enough
// for the pair, tested as the definition says. Coordinates, periods and cutoffs lie on a dyadic
// grid (multiples of 1/64 below 2^12), so the reference's double arithmetic is exact and the
// two must agree byte for byte, distances included. Then the cases that grid cannot reach
// (float64 boxes one ulp apart, integers above 2^24, coordinates far outside the cell) and bad
// input.
#include <float.h>
#include <math.h>

#include "check.h"
#include "neighbors_util.h"

typedef struct objects {
    uint32_t n;
    double lo[400][3], hi[400][3];
} objects;

// Every (i <= j, shift) within the cutoff: the shifts tried on each periodic axis cover those
// that can bring j's interval within c of i's, with one more on each side.
static size_t reference(const objects *o, const double period[3], double c, bpx_metric metric,
                        ref_pair *out, size_t capacity)
{
    size_t count = 0;
    for (uint32_t i = 0; i < o->n; i++)
        for (uint32_t j = i; j < o->n; j++) {
            int32_t first[3], last[3];
            for (int a = 0; a < 3; a++) {
                first[a] = last[a] = 0;
                if (period[a] > 0) {
                    first[a] = (int32_t)ceil((o->lo[i][a] - o->hi[j][a] - c) / period[a]) - 1;
                    last[a] = (int32_t)floor((o->hi[i][a] - o->lo[j][a] + c) / period[a]) + 1;
                }
            }
            int32_t s[3];
            for (s[0] = first[0]; s[0] <= last[0]; s[0]++)
                for (s[1] = first[1]; s[1] <= last[1]; s[1]++)
                    for (s[2] = first[2]; s[2] <= last[2]; s[2]++) {
                        if (i == j) { // once per image pair, the shift's first non-zero > 0
                            int sign = s[0] ? s[0] : s[1] ? s[1] : s[2];
                            if (sign <= 0)
                                continue;
                        }
                        double gap_max = -INFINITY, squares = 0;
                        for (int a = 0; a < 3; a++) {
                            double shifted_lo = o->lo[j][a] + s[a] * period[a];
                            double shifted_hi = o->hi[j][a] + s[a] * period[a];
                            double gap = fmax(shifted_lo - o->hi[i][a], o->lo[i][a] - shifted_hi);
                            gap_max = fmax(gap_max, gap);
                            if (gap > 0)
                                squares += gap * gap;
                        }
                        bool in = metric == BPX_METRIC_BOX ? gap_max <= c : squares <= c * c;
                        if (!in)
                            continue;
                        if (count < capacity)
                            out[count] = (ref_pair){i, j, {s[0], s[1], s[2]},
                                                    metric == BPX_METRIC_BOX ? fmax(gap_max, 0)
                                                                             : sqrt(squares)};
                        count++;
                    }
        }
    if (count <= capacity)
        qsort(out, count, sizeof *out, compare_ref);
    return count;
}

static uint64_t rng_state;
static uint64_t next_random(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return rng_state;
}
// A multiple of 1/64 in [lo, hi] (both multiples of 1/64).
static double grid_value(double lo, double hi)
{
    uint64_t steps = (uint64_t)((hi - lo) * 64);
    return lo + (double)(next_random() % (steps + 1)) / 64;
}

// The objects in the layout of a format.
static void *pack(const objects *o, bpx_input_format format)
{
    size_t n = o->n ? o->n : 1;
    switch (format) {
    case BPX_BOXES_F32: {
        bpx_box *b = calloc(n, sizeof *b);
        for (uint32_t k = 0; k < o->n; k++)
            for (int a = 0; a < 3; a++) {
                b[k].min[a] = (float)o->lo[k][a];
                b[k].max[a] = (float)o->hi[k][a];
            }
        return b;
    }
    case BPX_BOXES_F64: {
        bpx_box64 *b = calloc(n, sizeof *b);
        for (uint32_t k = 0; k < o->n; k++)
            for (int a = 0; a < 3; a++) {
                b[k].min[a] = o->lo[k][a];
                b[k].max[a] = o->hi[k][a];
            }
        return b;
    }
    case BPX_POINTS_F32: {
        float *p = calloc(3 * n, sizeof *p);
        for (uint32_t k = 0; k < o->n; k++)
            for (int a = 0; a < 3; a++)
                p[3 * k + a] = (float)o->lo[k][a];
        return p;
    }
    default: {
        double *p = calloc(3 * n, sizeof *p);
        for (uint32_t k = 0; k < o->n; k++)
            for (int a = 0; a < 3; a++)
                p[3 * k + a] = o->lo[k][a];
        return p;
    }
    }
}

static ref_pair expected[200000];

// One configuration on every CPU backend and both worker counts.
static void check_against_reference(const objects *o, const double period[3], double cutoff,
                                    bpx_metric metric, bpx_input_format format, const char *what)
{
    size_t want = reference(o, period, cutoff, metric, expected,
                            sizeof expected / sizeof expected[0]);
    CHECK_MSG(want <= sizeof expected / sizeof expected[0], "%s: %zu pairs", what, want);
    if (want > sizeof expected / sizeof expected[0])
        return;
    if (getenv("BPX_TEST_VERBOSE"))
        printf("%s: %zu pairs\n", what, want);
    void *data = pack(o, format);
    static const bpx_backend backends[] = {BPX_BACKEND_AUTO, BPX_BACKEND_REFERENCE,
                                           BPX_BACKEND_BRUTE, BPX_BACKEND_PRUNE, BPX_BACKEND_SAP,
                                           BPX_BACKEND_GRID};
    for (size_t b = 0; b < sizeof backends / sizeof backends[0]; b++)
        for (int workers = 1; workers <= 3; workers += 2) {
            if (check_quick() && workers == 1) // TSan: the threaded runs only
                continue;
            check_set_context("%s format=%d metric=%d cutoff=%g period=%g,%g,%g backend=%s "
                              "workers=%d n=%u",
                              what, format, metric, cutoff, period[0], period[1], period[2],
                              bpx_backend_name(backends[b]), workers, o->n);
            bpx_neighbor_def def = bpx_default_neighbor_def();
            def.format = format;
            memcpy(def.period, period, sizeof def.period);
            def.cutoff = cutoff;
            def.metric = metric;
            def.want_distances = true;
            def.backend = backends[b];
            def.worker_count = workers;
            bpx_neighbor_list list;
            bpx_error err;
            CHECK_STATUS(bpx_find_neighbors(&def, data, o->n, &list, &err), BPX_OK);
            CHECK_EQ_U64(list.count, want);
            size_t first_wrong = SIZE_MAX;
            for (size_t k = 0; k < list.count && k < want && first_wrong == SIZE_MAX; k++) {
                const bpx_image_pair *p = &list.pairs[k];
                const ref_pair *r = &expected[k];
                if (p->i != r->i || p->j != r->j || memcmp(p->shift, r->shift, sizeof p->shift) ||
                    list.distances[k] != r->distance)
                    first_wrong = k;
            }
            CHECK_MSG(first_wrong == SIZE_MAX, "pair %zu: got (%u, %u, %d %d %d) %.17g, want "
                      "(%u, %u, %d %d %d) %.17g", first_wrong,
                      first_wrong < list.count ? list.pairs[first_wrong].i : 0,
                      first_wrong < list.count ? list.pairs[first_wrong].j : 0,
                      first_wrong < list.count ? list.pairs[first_wrong].shift[0] : 0,
                      first_wrong < list.count ? list.pairs[first_wrong].shift[1] : 0,
                      first_wrong < list.count ? list.pairs[first_wrong].shift[2] : 0,
                      first_wrong < list.count ? list.distances[first_wrong] : 0,
                      first_wrong < want ? expected[first_wrong].i : 0,
                      first_wrong < want ? expected[first_wrong].j : 0,
                      first_wrong < want ? expected[first_wrong].shift[0] : 0,
                      first_wrong < want ? expected[first_wrong].shift[1] : 0,
                      first_wrong < want ? expected[first_wrong].shift[2] : 0,
                      first_wrong < want ? expected[first_wrong].distance : 0);
            bpx_neighbor_list_free(&list);
        }
    free(data);
}

// Random objects in a cell of these periods (an open axis spans 16): sizes up to `size`
// (points when 0), placed anywhere within `spread` cells of the origin, some on the faces.
static void random_objects(objects *o, uint32_t n, const double period[3], double size,
                           int spread)
{
    o->n = n;
    for (uint32_t k = 0; k < n; k++)
        for (int a = 0; a < 3; a++) {
            double L = period[a] > 0 ? period[a] : 16;
            double lo;
            if (next_random() % 5 == 0) // on a face: k * L exactly
                lo = L * (double)((int)(next_random() % (2 * spread + 1)) - spread);
            else
                lo = grid_value(-spread * L, (spread + 1) * L);
            o->lo[k][a] = lo;
            o->hi[k][a] = lo + (size > 0 ? grid_value(0, size) : 0);
        }
}

static void random_configurations(void)
{
    static objects o;
    static const double cells[][3] = {
        {8, 8, 8}, {8, 0, 8}, {0, 0, 4}, {0, 0, 0}, {4, 6.5, 3.25}, {1, 1, 1},
    };
    for (int round = 0; round < 40; round++) {
        check_set_seed((uint64_t)round);
        rng_state = 0x9E3779B97F4A7C15ull * (uint64_t)(round + 1);
        const double *period = cells[round % 6];
        double smallest = 1e9;
        for (int a = 0; a < 3; a++)
            if (period[a] > 0 && period[a] < smallest)
                smallest = period[a];
        if (smallest == 1e9)
            smallest = 16;
        // Points and boxes; boxes up to a quarter cell, or past a whole cell.
        bool points = round % 4 == 0;
        double size = points ? 0 : (round % 3 == 0 ? 1.5 * smallest : smallest / 4);
        int spread = round % 5 == 0 ? 3 : 0; // unwrapped coordinates, several cells out
        uint32_t n = smallest < 2 ? 24 : (points ? 160 : 90);
        random_objects(&o, n, period, size, spread);
        // Cutoffs: none, small, exactly half the cell, past the cell.
        double cutoffs[4] = {0, 0.75, smallest / 2, 1.25 * smallest};
        double cutoff = cutoffs[round % 4 == 0 ? 1 + round / 4 % 3 : round % 4];
        bpx_metric metric = round % 2 ? BPX_METRIC_BOX : BPX_METRIC_EUCLIDEAN;
        bpx_input_format format = points ? (round % 8 == 0 ? BPX_POINTS_F64 : BPX_POINTS_F32)
                                         : (round % 3 == 1 ? BPX_BOXES_F32 : BPX_BOXES_F64);
        check_against_reference(&o, period, cutoff, metric, format, "random");
    }
}

// Cutoff 0 (Algorithm 1's closed-interval test), which random_configurations leaves out: on the
// 1/64 grid boxes touch often, and images that are the boxes themselves are kept as the
// comparator finds them; in float64 some faces are moved out by 2^-40 (no float32 holds them)
// so that others are decided.
static void touching_configurations(void)
{
    static objects o;
    static const double cells[][3] = {{8, 8, 8}, {0, 0, 0}, {4, 6.5, 3.25}, {0, 5, 0}};
    for (int round = 0; round < 24; round++) {
        check_set_seed(1000 + (uint64_t)round);
        rng_state = 0x9E3779B97F4A7C15ull * (uint64_t)(round + 1001);
        const double *period = cells[round % 4];
        int spread = round % 3 == 2 ? 2 : 0;
        bpx_input_format format = round % 3 == 0   ? BPX_BOXES_F32
                                  : round % 3 == 1 ? BPX_BOXES_F64
                                                   : BPX_POINTS_F64;
        bool points = format == BPX_POINTS_F64;
        random_objects(&o, 120, period, points ? 0 : 2, spread);
        if (format != BPX_BOXES_F32 && round % 2)
            for (uint32_t k = 0; k < o.n; k++)
                for (int a = 0; a < 3; a++) {
                    uint64_t r = next_random() % 4;
                    if (points && r == 0)
                        o.lo[k][a] = o.hi[k][a] = o.lo[k][a] + 0x1p-40;
                    else if (!points && r == 0)
                        o.lo[k][a] -= 0x1p-40;
                    else if (!points && r == 1)
                        o.hi[k][a] += 0x1p-40;
                }
        for (uint32_t k = 7; points && k < o.n; k += 8) // coinciding points: pairs at distance 0
            for (int a = 0; a < 3; a++)
                o.lo[k][a] = o.hi[k][a] = o.lo[k - 7][a];
        bpx_metric metric = round / 2 % 2 ? BPX_METRIC_BOX : BPX_METRIC_EUCLIDEAN;
        check_against_reference(&o, period, 0, metric, format, "touching");
    }
}

// Hand-made cases: objects on the faces and at exactly half a period.
static void walls(void)
{
    static objects o;
    double period[3] = {10, 10, 10};
    // Points at 0, 5 (half a period), 10 (the same as 0 shifted), -10, 9.5, 0.5.
    double xs[] = {0, 5, 10, -10, 9.5, 0.5, 20, 4.75};
    o.n = sizeof xs / sizeof xs[0];
    for (uint32_t k = 0; k < o.n; k++)
        for (int a = 0; a < 3; a++)
            o.lo[k][a] = o.hi[k][a] = a == 0 ? xs[k] : 1;
    for (int metric = 0; metric < 2; metric++) {
        check_against_reference(&o, period, 0, metric, BPX_POINTS_F64, "walls cutoff 0");
        check_against_reference(&o, period, 1, metric, BPX_POINTS_F64, "walls cutoff 1");
        check_against_reference(&o, period, 5, metric, BPX_POINTS_F64, "walls half period");
        check_against_reference(&o, period, 12, metric, BPX_POINTS_F64, "walls past the cell");
    }
    // One box wider than two cells: it meets its own images.
    o.n = 2;
    for (int a = 0; a < 3; a++) {
        o.lo[0][a] = -1;
        o.hi[0][a] = a == 0 ? 21 : 2;
        o.lo[1][a] = o.hi[1][a] = 5;
    }
    check_against_reference(&o, period, 0, BPX_METRIC_BOX, BPX_BOXES_F64, "box wider than the cell");
    check_against_reference(&o, period, 3, BPX_METRIC_EUCLIDEAN, BPX_BOXES_F32,
                            "box wider than the cell, cutoff 3");
    // The lone point with a cutoff past the cell pairs with its own images only.
    o.n = 1;
    for (int a = 0; a < 3; a++)
        o.lo[0][a] = o.hi[0][a] = 5;
    check_against_reference(&o, period, 10, BPX_METRIC_EUCLIDEAN, BPX_POINTS_F64,
                            "one point, its own images");
}

// Float64 cases the grid cannot reach: bpx_find_pairs_f64 must not round them to float32.
static void float64_exact(void)
{
    check_set_context("float64");
    double scales[] = {1e6, 1e-30, 16777216.0, 3.0e300};
    for (size_t s = 0; s < sizeof scales / sizeof scales[0]; s++) {
        double x = scales[s];
        double up = nextafter(x, INFINITY);
        // Box 0 ends at x; box 1 starts one ulp above (apart); box 2 starts at x (touching);
        // box 3 is an integer point 2^24 + 1 when x is 2^24 (float32 would merge it with x).
        bpx_box64 boxes[4] = {
            {{x / 2, 0, 0}, {x, 1, 1}},
            {{up, 0, 0}, {up * 2, 1, 1}},
            {{x, 0, 0}, {x, 1, 1}},
            {{x + 1, 0, 0}, {x + 1, 1, 1}},
        };
        bpx_pair out[16];
        size_t count = 0;
        bpx_error err;
        CHECK_STATUS(bpx_find_pairs_f64(boxes, 4, BPX_BACKEND_AUTO, out, 16, &count, &err),
                     BPX_OK);
        // Brute force in double: exact, as comparisons are.
        bpx_pair want[16];
        size_t wanted = 0;
        for (uint32_t i = 0; i < 4; i++)
            for (uint32_t j = i + 1; j < 4; j++) {
                bool overlap = true;
                for (int a = 0; a < 3; a++)
                    overlap &= boxes[i].min[a] <= boxes[j].max[a] &&
                               boxes[j].min[a] <= boxes[i].max[a];
                if (overlap)
                    want[wanted++] = (bpx_pair){i, j};
            }
        CHECK_MSG(count == wanted && memcmp(out, want, count * sizeof *out) == 0,
                  "scale %g: %zu pairs, want %zu", x, count, wanted);
        // And that float32 would have got it wrong: boxes 0 and 1 round to touching.
        if (x == 1e6 || x == 1e-30)
            CHECK((float)x == (float)up);
        // CAPACITY: the count, nothing written.
        CHECK_STATUS(bpx_find_pairs_f64(boxes, 4, BPX_BACKEND_AUTO, out, 0, &count, &err),
                     wanted ? BPX_ERR_CAPACITY : BPX_OK);
        CHECK_EQ_U64(count, wanted);
        // Room for the pairs but not for every candidate (at 1e6 and 1e-30, boxes 0 and 1
        // are one in float32): the pairs all the same.
        bpx_pair tight[16];
        CHECK_STATUS(bpx_find_pairs_f64(boxes, 4, BPX_BACKEND_AUTO, tight, wanted, &count, &err),
                     BPX_OK);
        CHECK_MSG(count == wanted && memcmp(tight, want, count * sizeof *tight) == 0,
                  "scale %g, capacity %zu: %zu pairs", x, wanted, count);
    }
    // The same, periodic: point 0 at just under L and point 1 at 0 are one ulp apart across the
    // face; with cutoff 0 they do not pair, with the ulp as cutoff they do.
    double L = 1e6;
    double points[6] = {nextafter(L, 0), 0, 0, 0, 0, 0};
    bpx_neighbor_def def = bpx_default_neighbor_def();
    def.format = BPX_POINTS_F64;
    def.period[0] = L;
    bpx_neighbor_list list;
    CHECK_STATUS(bpx_find_neighbors(&def, points, 2, &list, NULL), BPX_OK);
    CHECK_EQ_U64(list.count, 0);
    bpx_neighbor_list_free(&list);
    def.cutoff = L - nextafter(L, 0);
    CHECK_STATUS(bpx_find_neighbors(&def, points, 2, &list, NULL), BPX_OK);
    CHECK_EQ_U64(list.count, 1);
    if (list.count == 1)
        CHECK(list.pairs[0].i == 0 && list.pairs[0].j == 1 && list.pairs[0].shift[0] == 1);
    bpx_neighbor_list_free(&list);
}

static void bad_input(void)
{
    check_set_context("bad input");
    bpx_neighbor_def def = bpx_default_neighbor_def();
    bpx_box box = {{0, 0, 0}, {1, 1, 1}};
    bpx_neighbor_list list;
    bpx_error err;
    double bad_periods[] = {-1, NAN, INFINITY};
    for (int k = 0; k < 3; k++) {
        def.period[1] = bad_periods[k];
        CHECK_STATUS(bpx_find_neighbors(&def, &box, 1, &list, &err), BPX_ERR_INVALID_ARGUMENT);
        CHECK(err.axis == 1 && strstr(err.message, "period[1]"));
        CHECK(list.count == 0 && list.pairs == NULL);
    }
    def = bpx_default_neighbor_def();
    def.cutoff = -0.5;
    CHECK_STATUS(bpx_find_neighbors(&def, &box, 1, &list, &err), BPX_ERR_INVALID_ARGUMENT);
    def.cutoff = NAN;
    CHECK_STATUS(bpx_find_neighbors(&def, &box, 1, &list, &err), BPX_ERR_INVALID_ARGUMENT);
    CHECK(strstr(err.message, "cutoff") != NULL);
    def = bpx_default_neighbor_def();
    def.format = (bpx_input_format)7;
    CHECK_STATUS(bpx_find_neighbors(&def, &box, 1, &list, &err), BPX_ERR_INVALID_ARGUMENT);
    def = bpx_default_neighbor_def();
    def.metric = (bpx_metric)-1;
    CHECK_STATUS(bpx_find_neighbors(&def, &box, 1, &list, &err), BPX_ERR_INVALID_ARGUMENT);
    def = bpx_default_neighbor_def();
    CHECK_STATUS(bpx_find_neighbors(NULL, &box, 1, &list, &err), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_find_neighbors(&def, NULL, 1, &list, &err), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_find_neighbors(&def, &box, 1, NULL, &err), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_find_neighbors(&def, NULL, 0, &list, &err), BPX_OK);
    CHECK(list.count == 0);
    CHECK_STATUS(bpx_find_neighbors(&def, &box, BPX_MAX_BOXES + 1, &list, &err),
                 BPX_ERR_TOO_MANY_BOXES);
    // Objects: the first bad one named, non-finite before min > max.
    double points[9] = {0, 0, 0, 1, NAN, 1, 2, 2, 2};
    def.format = BPX_POINTS_F64;
    CHECK_STATUS(bpx_find_neighbors(&def, points, 3, &list, &err), BPX_ERR_NOT_FINITE);
    CHECK(err.index == 1 && err.axis == 1);
    bpx_box64 boxes[2] = {{{0, 0, 0}, {1, 1, 1}}, {{0, 3, 0}, {1, 2, 1}}};
    def.format = BPX_BOXES_F64;
    CHECK_STATUS(bpx_find_neighbors(&def, boxes, 2, &list, &err), BPX_ERR_MIN_GREATER_THAN_MAX);
    CHECK(err.index == 1 && err.axis == 1);
    // A cell so small against the objects that the images or shifts cannot be counted.
    boxes[1] = (bpx_box64){{0, 0, 0}, {1, 1, 1}};
    def.period[0] = 1e-12;
    CHECK_STATUS(bpx_find_neighbors(&def, boxes, 2, &list, &err), BPX_ERR_TOO_MANY_BOXES);
    CHECK(strstr(err.message, "periods") != NULL);
    def.period[0] = 1e-5; // 10^5 images of each box on x
    def.period[1] = 1e-5;
    CHECK_STATUS(bpx_find_neighbors(&def, boxes, 2, &list, &err), BPX_ERR_TOO_MANY_BOXES);
    CHECK(strstr(err.message, "images") != NULL);
    // bpx_find_pairs_f64's own checks.
    size_t count;
    CHECK_STATUS(bpx_find_pairs_f64(boxes, 2, BPX_BACKEND_AUTO, NULL, 4, &count, &err),
                 BPX_ERR_NULL_ARGUMENT);
    boxes[0].max[2] = INFINITY;
    CHECK_STATUS(bpx_find_pairs_f64(boxes, 2, BPX_BACKEND_AUTO, NULL, 0, &count, &err),
                 BPX_ERR_NOT_FINITE);
    CHECK(err.index == 0 && err.axis == 2);
    bpx_neighbor_list_free(NULL);
}

// Inputs a review found wrong once: a wrap rounded to a whole period with the partner's image
// then never made; an image count past 2^64; squares that underflow or overflow; coordinates so
// small that cells as wide as the cutoff would be subnormal.
static void review_cases(void)
{
    check_set_context("review cases");
    bpx_neighbor_def def = bpx_default_neighbor_def();
    bpx_neighbor_list list;
    bpx_error err;
    // 2^28 - 2^-30 rounds to 2^28: object 1 lies a hair below its computed cell.
    bpx_box64 wrap[3] = {{{0x1p-30, 0, 0}, {0x1p-30, 0, 0}},
                         {{0x1p28, 0, 0}, {0x1p28, 0, 0}},
                         {{1, 0, 0}, {1, 0, 0}}};
    def.format = BPX_BOXES_F64;
    def.period[0] = 1;
    for (int b = 0; b < 3; b++) {
        static const bpx_backend backends[3] = {BPX_BACKEND_AUTO, BPX_BACKEND_BRUTE,
                                                BPX_BACKEND_SAP};
        def.backend = backends[b];
        CHECK_STATUS(bpx_find_neighbors(&def, wrap, 3, &list, &err), BPX_OK);
        CHECK_EQ_U64(list.count, 1);
        if (list.count == 1)
            CHECK(list.pairs[0].i == 1 && list.pairs[0].j == 2 &&
                  list.pairs[0].shift[0] == (1 << 28) - 1);
        bpx_neighbor_list_free(&list);
    }
    def.backend = BPX_BACKEND_AUTO;
    // 769546 * 494770 * 48448661 images is 2^64 + 4.
    bpx_box64 huge = {{0, 0, 0}, {769545.5, 494769.5, 48448660.5}};
    def.period[0] = def.period[1] = def.period[2] = 1;
    CHECK_STATUS(bpx_find_neighbors(&def, &huge, 1, &list, &err), BPX_ERR_TOO_MANY_BOXES);
    // Squares below double's range, and past it.
    def = bpx_default_neighbor_def();
    def.format = BPX_POINTS_F64;
    def.metric = BPX_METRIC_EUCLIDEAN;
    def.want_distances = true;
    for (int search = 0; search < 2; search++) {
        def.backend = search ? BPX_BACKEND_BRUTE : BPX_BACKEND_AUTO;
        double apart[6] = {0, 0, 0, 1e-170, 0, 0};
        def.cutoff = 0;
        CHECK_STATUS(bpx_find_neighbors(&def, apart, 2, &list, &err), BPX_OK);
        CHECK_EQ_U64(list.count, 0);
        bpx_neighbor_list_free(&list);
        double diagonal[6] = {0, 0, 0, 1e-170, 1e-170, 1e-170}; // 1.732e-170 apart
        def.cutoff = 1.5e-170;
        CHECK_STATUS(bpx_find_neighbors(&def, diagonal, 2, &list, &err), BPX_OK);
        CHECK_EQ_U64(list.count, 0);
        bpx_neighbor_list_free(&list);
        def.cutoff = 1.8e-170;
        CHECK_STATUS(bpx_find_neighbors(&def, diagonal, 2, &list, &err), BPX_OK);
        CHECK_EQ_U64(list.count, 1);
        if (list.count == 1)
            CHECK(fabs(list.distances[0] / (sqrt(3) * 1e-170) - 1) < 1e-12);
        bpx_neighbor_list_free(&list);
        double far[6] = {0, 0, 0, 0x1p700, 0, 0};
        def.cutoff = 0x1p600;
        CHECK_STATUS(bpx_find_neighbors(&def, far, 2, &list, &err), BPX_OK);
        CHECK_EQ_U64(list.count, 0);
        bpx_neighbor_list_free(&list);
        def.cutoff = 0x1p701;
        CHECK_STATUS(bpx_find_neighbors(&def, far, 2, &list, &err), BPX_OK);
        CHECK_EQ_U64(list.count, 1);
        if (list.count == 1)
            CHECK(list.distances[0] == 0x1p700);
        bpx_neighbor_list_free(&list);
        // Every point within 2^-900 of 0, no cutoff: the cells must not be subnormal.
        double tiny[6] = {1e-300, 0, 0, 0, 0, 0};
        def.cutoff = 0;
        CHECK_STATUS(bpx_find_neighbors(&def, tiny, 2, &list, &err), BPX_OK);
        CHECK_EQ_U64(list.count, 0);
        bpx_neighbor_list_free(&list);
        def.cutoff = 1e-300;
        CHECK_STATUS(bpx_find_neighbors(&def, tiny, 2, &list, &err), BPX_OK);
        CHECK_EQ_U64(list.count, 1);
        bpx_neighbor_list_free(&list);
    }
}

int main(void)
{
    int64_t start = bpx_allocated_bytes();
    random_configurations();
    touching_configurations();
    walls();
    float64_exact();
    bad_input();
    review_cases();
    CHECK(bpx_allocated_bytes() == start);
    return check_finish("test_neighbors", 1);
}
