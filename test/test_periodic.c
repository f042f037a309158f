// Periodic worlds (bpx_world_def.period): pairs and image pairs against a brute force over the
// images written here (not the library's search), on every CPU backend with 1 and 3 workers;
// events, filters, groups, exclusions and the pair filter across cycles of moving, added and
// removed boxes; the two-phase mode; snapshots; bad periods; allocation failure.
//
// Coordinates and periods are dyadic (multiples of 1/8, small), so the brute force's double
// arithmetic is exact and it must agree with the library bit for bit.
#include <math.h>
#include <stdatomic.h>

#include "check.h"
#include "scenes.h"

// ---------------------------------------------------------------------------------------------
// The brute force

typedef struct image_list {
    bpx_image_pair *pairs;
    size_t count, capacity;
} image_list;

static void push(image_list *l, bpx_image_pair p)
{
    if (l->count == l->capacity) {
        l->capacity = l->capacity ? 2 * l->capacity : 256;
        l->pairs = realloc(l->pairs, l->capacity * sizeof *l->pairs);
        if (!l->pairs)
            exit(2);
    }
    l->pairs[l->count++] = p;
}

// Whether box j moved by s periods overlaps box i on axis a (closed intervals).
static bool meet(const bpx_box *bi, const bpx_box *bj, int a, double L, int32_t s)
{
    double t = (double)s * L;
    return (double)bj->min[a] + t <= (double)bi->max[a] && (double)bi->min[a] <= (double)bj->max[a] + t;
}

// Every image pair of the live boxes (alive NULL: all), in (i, j, shift) order.
static void brute(const bpx_box *boxes, uint32_t n, const uint8_t *alive, const double period[3],
                  image_list *out)
{
    out->count = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (alive && !alive[i])
            continue;
        for (uint32_t j = i; j < n; j++) {
            if (alive && !alive[j])
                continue;
            int32_t lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
            for (int a = 0; a < 3; a++) {
                double L = period[a];
                if (L == 0)
                    continue;
                // Every shift that can matter, and one more each way.
                lo[a] = (int32_t)floor(((double)boxes[i].min[a] - boxes[j].max[a]) / L) - 1;
                hi[a] = (int32_t)ceil(((double)boxes[i].max[a] - boxes[j].min[a]) / L) + 1;
            }
            int32_t s[3];
            for (s[0] = lo[0]; s[0] <= hi[0]; s[0]++)
                for (s[1] = lo[1]; s[1] <= hi[1]; s[1]++)
                    for (s[2] = lo[2]; s[2] <= hi[2]; s[2]++) {
                        if (i == j) { // first non-zero component positive
                            int first = s[0] ? s[0] : s[1] ? s[1] : s[2];
                            if (first <= 0)
                                continue;
                        }
                        bool yes = true;
                        for (int a = 0; a < 3; a++)
                            yes &= meet(&boxes[i], &boxes[j], a, period[a], s[a]);
                        if (yes)
                            push(out, (bpx_image_pair){i, j, {s[0], s[1], s[2]}});
                    }
        }
    }
}

// The distinct pairs (i < j) of image pairs.
static size_t distinct(const image_list *l, bpx_pair *out)
{
    size_t count = 0;
    for (size_t k = 0; k < l->count; k++) {
        bpx_pair p = {l->pairs[k].i, l->pairs[k].j};
        if (p.i == p.j || (count && out[count - 1].i == p.i && out[count - 1].j == p.j))
            continue;
        out[count++] = p;
    }
    return count;
}

static bool same_images(const bpx_image_pair *a, size_t na, const image_list *want)
{
    return na == want->count && (na == 0 || memcmp(a, want->pairs, na * sizeof *a) == 0);
}

static bool same_pairs(const bpx_pair *a, size_t na, const bpx_pair *b, size_t nb)
{
    return na == nb && (na == 0 || memcmp(a, b, na * sizeof *a) == 0);
}

// A dyadic coordinate in [lo, hi]: a multiple of 1/8.
static float dyadic(scene_rng *r, double lo, double hi)
{
    int32_t k0 = (int32_t)ceil(lo * 8), k1 = (int32_t)floor(hi * 8);
    return (float)((k0 + (int32_t)scene_rng_below(r, (uint32_t)(k1 - k0 + 1))) / 8.0);
}

static const bpx_backend cpu_backends[] = {BPX_BACKEND_AUTO, BPX_BACKEND_REFERENCE,
                                           BPX_BACKEND_BRUTE, BPX_BACKEND_PRUNE,
                                           BPX_BACKEND_SAP,  BPX_BACKEND_GRID,
                                           BPX_BACKEND_MODEL};
enum { BACKENDS = sizeof cpu_backends / sizeof cpu_backends[0] };

static bpx_world *make(bpx_backend backend, int workers, const double period[3], bool events)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.worker_count = workers;
    def.track_events = events;
    memcpy(def.period, period, sizeof def.period);
    bpx_world *w = NULL;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    return w;
}

// ---------------------------------------------------------------------------------------------
// Random cells and boxes on every backend

typedef struct config {
    double period[3];
    uint32_t n;
    double widest; // in periods (of the smallest periodic axis)
} config;

static void random_boxes(scene_rng *r, const config *c, bpx_box *boxes)
{
    for (uint32_t k = 0; k < c->n; k++) {
        for (int a = 0; a < 3; a++) {
            double L = c->period[a] > 0 ? c->period[a] : 6;
            double side;
            uint32_t kind = scene_rng_below(r, 10);
            if (kind == 0)
                side = 0; // a point or a plane
            else if (kind == 1)
                side = L / 2; // exactly half a period
            else if (kind == 2)
                side = c->widest > 0.5 ? dyadic(r, L / 2, L * c->widest) : L / 2; // past half
            else
                side = dyadic(r, 0, L / 6);
            double lo;
            uint32_t where = scene_rng_below(r, 6);
            if (where == 0 && c->period[a] > 0) // on a wall: a whole number of periods
                lo = L * ((int32_t)scene_rng_below(r, 5) - 2);
            else if (where == 1 && c->period[a] > 0) // reaching exactly a wall
                lo = L * ((int32_t)scene_rng_below(r, 3)) - side;
            else // anywhere, unwrapped: up to two cells out either way
                lo = dyadic(r, -2 * L, 3 * L);
            boxes[k].min[a] = (float)lo;
            boxes[k].max[a] = (float)(lo + side);
        }
    }
}

static void test_random(void)
{
    static const config configs[] = {
        {{8, 8, 8}, 150, 0.3},   {{8, 8, 8}, 200, 1.2},  {{8, 0, 5.5}, 180, 0.6},
        {{0, 4, 0}, 120, 0.9},   {{3, 3, 3}, 60, 1.6},   {{16, 8, 0.5}, 100, 0.4},
        {{8, 8, 8}, 1, 2.0},     {{2, 2, 2}, 40, 0.5},
    };
    image_list want = {0};
    bpx_pair *want_pairs = NULL;
    for (size_t ci = 0; ci < sizeof configs / sizeof configs[0]; ci++) {
        for (uint64_t seed = 1; seed <= 4; seed++) {
            const config *c = &configs[ci];
            scene_rng r;
            scene_rng_seed(&r, 1000 * ci + seed);
            check_set_seed(1000 * ci + seed);
            bpx_box *boxes = check_alloc(c->n * sizeof *boxes);
            random_boxes(&r, c, boxes);
            brute(boxes, c->n, NULL, c->period, &want);
            want_pairs = realloc(want_pairs, (want.count + 1) * sizeof *want_pairs);
            size_t want_count = distinct(&want, want_pairs);
            if (getenv("BPX_TEST_VERBOSE"))
                printf("config %zu seed %llu: %zu images, %zu pairs\n", ci,
                       (unsigned long long)seed, want.count, want_count);
            for (int b = 0; b < BACKENDS; b++) {
                if (!bpx_backend_query(cpu_backends[b]).available)
                    continue;
                for (int workers = 1; workers <= 3; workers += 2) {
                    if (check_quick() && workers == 1)
                        continue;
                    check_set_context("config %zu period %g,%g,%g n %u backend %s workers %d", ci,
                                      c->period[0], c->period[1], c->period[2], c->n,
                                      bpx_backend_name(cpu_backends[b]), workers);
                    bpx_world *w = make(cpu_backends[b], workers, c->period, false);
                    if (!w)
                        continue;
                    CHECK_STATUS(bpx_world_set_boxes(w, boxes, c->n), BPX_OK);
                    for (int again = 0; again < 2; again++) { // a second cycle reuses the state
                        CHECK_STATUS(bpx_world_collide(w), BPX_OK);
                        size_t count = 0, images = 0;
                        const bpx_pair *pairs = bpx_world_pairs(w, &count);
                        const bpx_image_pair *got = bpx_world_image_pairs(w, &images);
                        CHECK_MSG(same_images(got, images, &want), "%zu images, want %zu",
                                  images, want.count);
                        CHECK_MSG(same_pairs(pairs, count, want_pairs, want_count),
                                  "%zu pairs, want %zu", count, want_count);
                        CHECK_EQ_U64(bpx_world_stats(w).pair_count, want_count);
                        // collide_into gives the same distinct pairs.
                        bpx_pair *into = check_alloc((want_count + 1) * sizeof *into);
                        size_t into_count = 0;
                        CHECK_STATUS(bpx_world_collide_into(w, into, want_count, &into_count),
                                     BPX_OK);
                        CHECK(same_pairs(into, into_count, want_pairs, want_count));
                        free(into);
                    }
                    bpx_world_destroy(w);
                }
            }
            free(boxes);
        }
    }
    free(want.pairs);
    free(want_pairs);
}

// ---------------------------------------------------------------------------------------------
// Filters, groups, exclusions, the pair filter and events across cycles

typedef struct rules {
    uint32_t category[64], mask[64];
    int32_t group[64];
    bool excluded[64][64];
} rules;

static bool rule_pair(const rules *r, uint32_t i, uint32_t j)
{
    if (i != j && r->excluded[i][j])
        return false;
    if (r->group[i] == r->group[j] && r->group[i] != 0)
        return r->group[i] > 0;
    return (r->category[i] & r->mask[j]) && (r->category[j] & r->mask[i]);
}

static bool refuse_some(uint32_t i, uint32_t j, uint64_t ui, uint64_t uj, void *context)
{
    (void)context;
    (void)ui;
    (void)uj;
    return (i * 7 + j * 3) % 5 != 0;
}

static void test_rules_and_events(void)
{
    enum { N = 64, CYCLES = 8 };
    const double period[3] = {6, 6, 4};
    image_list all = {0};
    bpx_image_pair want_images[N * N * 8];
    for (int b = 0; b < BACKENDS; b++) {
        if (!bpx_backend_query(cpu_backends[b]).available)
            continue;
        for (int workers = 1; workers <= 3; workers += 2) {
            check_set_context("rules and events, backend %s workers %d",
                              bpx_backend_name(cpu_backends[b]), workers);
            scene_rng r;
            scene_rng_seed(&r, 77);
            check_set_seed(77);
            bpx_box boxes[N];
            uint8_t alive[N];
            rules rl;
            memset(&rl, 0, sizeof rl);
            config c = {{6, 6, 4}, N, 0.7};
            random_boxes(&r, &c, boxes);
            bpx_world *w = make(cpu_backends[b], workers, period, true);
            if (!w)
                continue;
            CHECK_STATUS(bpx_world_set_boxes(w, boxes, N), BPX_OK);
            uint32_t ids[N], cats[N], masks[N];
            int32_t groups[N];
            for (uint32_t k = 0; k < N; k++) {
                ids[k] = k;
                alive[k] = 1;
                cats[k] = rl.category[k] = 1u << scene_rng_below(&r, 3);
                masks[k] = rl.mask[k] = ~(1u << scene_rng_below(&r, 4));
                groups[k] = rl.group[k] = (int32_t)scene_rng_below(&r, 5) - 2;
            }
            CHECK_STATUS(bpx_world_set_filters(w, ids, cats, masks, N), BPX_OK);
            CHECK_STATUS(bpx_world_set_groups(w, ids, groups, N), BPX_OK);
            bpx_pair ex[12];
            for (int k = 0; k < 12; k++) {
                uint32_t i = scene_rng_below(&r, N), j = (i + 1 + scene_rng_below(&r, N - 1)) % N;
                ex[k] = (bpx_pair){i, j};
                rl.excluded[i][j] = rl.excluded[j][i] = true;
            }
            CHECK_STATUS(bpx_world_exclude_pairs(w, ex, 12), BPX_OK);
            CHECK_STATUS(bpx_world_set_pair_filter(w, refuse_some, NULL), BPX_OK);
            bpx_pair before[N * N], now[N * N];
            size_t before_count = 0;
            for (int cycle = 0; cycle < CYCLES; cycle++) {
                check_set_context("rules and events, backend %s workers %d cycle %d",
                                  bpx_backend_name(cpu_backends[b]), workers, cycle);
                if (cycle > 0) { // move some, remove one, add one back (its id comes back)
                    uint32_t moved[8];
                    bpx_box to[8];
                    uint32_t count = 0;
                    for (uint32_t k = 0; k < N && count < 8; k += 1 + scene_rng_below(&r, 12)) {
                        if (!alive[k])
                            continue;
                        bpx_box box = boxes[k];
                        for (int a = 0; a < 3; a++) {
                            float step = dyadic(&r, -1.5, 1.5);
                            box.min[a] += step;
                            box.max[a] += step;
                        }
                        moved[count] = k;
                        to[count++] = box;
                        boxes[k] = box;
                    }
                    CHECK_STATUS(bpx_world_move_boxes(w, moved, to, count), BPX_OK);
                    if (cycle % 3 == 1) {
                        uint32_t gone = scene_rng_below(&r, N);
                        if (alive[gone]) {
                            CHECK_STATUS(bpx_world_remove_boxes(w, &gone, 1), BPX_OK);
                            alive[gone] = 0;
                            for (uint32_t k = 0; k < N; k++)
                                rl.excluded[gone][k] = rl.excluded[k][gone] = false;
                        }
                    } else if (cycle % 3 == 2) {
                        for (uint32_t k = 0; k < N; k++) {
                            if (alive[k])
                                continue;
                            uint32_t id = UINT32_MAX;
                            CHECK_STATUS(bpx_world_add_boxes(w, &boxes[k], 1, &id), BPX_OK);
                            CHECK(id == k);
                            alive[k] = 1;
                            // A reused id starts unfiltered.
                            rl.category[k] = 1;
                            rl.mask[k] = 0xFFFFFFFFu;
                            rl.group[k] = 0;
                            break;
                        }
                    }
                }
                CHECK_STATUS(bpx_world_collide(w), BPX_OK);
                brute(boxes, N, alive, period, &all);
                // The expected pairs: distinct, by the rules, then the pair filter.
                size_t now_count = distinct(&all, now), kept = 0;
                for (size_t k = 0; k < now_count; k++) {
                    bpx_pair p = now[k];
                    now[kept] = p;
                    kept += rule_pair(&rl, p.i, p.j) && refuse_some(p.i, p.j, 0, 0, NULL);
                }
                now_count = kept;
                size_t images_count = 0, at = 0;
                for (size_t k = 0; k < all.count; k++) {
                    bpx_image_pair q = all.pairs[k];
                    bool keep;
                    if (q.i == q.j) {
                        keep = rule_pair(&rl, q.i, q.i);
                    } else {
                        while (at < now_count &&
                               (now[at].i < q.i || (now[at].i == q.i && now[at].j < q.j)))
                            at++;
                        keep = at < now_count && now[at].i == q.i && now[at].j == q.j;
                    }
                    if (keep)
                        want_images[images_count++] = q;
                }
                size_t count = 0, images = 0;
                const bpx_pair *pairs = bpx_world_pairs(w, &count);
                CHECK_MSG(same_pairs(pairs, count, now, now_count), "%zu pairs, want %zu", count,
                          now_count);
                const bpx_image_pair *got = bpx_world_image_pairs(w, &images);
                image_list want = {want_images, images_count, images_count};
                CHECK_MSG(same_images(got, images, &want), "%zu images, want %zu", images,
                          images_count);
                // Events: began = now - before, ended = before - now.
                bpx_pair_events ev;
                CHECK_STATUS(bpx_world_pair_events(w, &ev), BPX_OK);
                size_t began = 0, ended = 0, x = 0, y = 0;
                bool events_ok = true;
                while (x < before_count || y < now_count) {
                    bool take_before = y == now_count ||
                                       (x < before_count &&
                                        (before[x].i < now[y].i ||
                                         (before[x].i == now[y].i && before[x].j < now[y].j)));
                    bool take_now = x == before_count ||
                                    (y < now_count &&
                                     (now[y].i < before[x].i ||
                                      (now[y].i == before[x].i && now[y].j < before[x].j)));
                    if (take_before) {
                        events_ok &= ended < ev.ended_count && ev.ended[ended].i == before[x].i &&
                                     ev.ended[ended].j == before[x].j;
                        ended++, x++;
                    } else if (take_now) {
                        events_ok &= began < ev.began_count && ev.began[began].i == now[y].i &&
                                     ev.began[began].j == now[y].j;
                        began++, y++;
                    } else {
                        x++, y++;
                    }
                }
                CHECK(events_ok && began == ev.began_count && ended == ev.ended_count);
                memcpy(before, now, now_count * sizeof *now);
                before_count = now_count;
            }
            bpx_world_destroy(w);
        }
    }
    free(all.pairs);
}

// ---------------------------------------------------------------------------------------------
// The two-phase mode

static void test_two_phase(void)
{
    enum { N = 90 };
    const double period[3] = {5, 0, 5};
    scene_rng r;
    scene_rng_seed(&r, 5);
    check_set_seed(5);
    float minima[3 * N], centres[3 * N];
    bpx_box boxes[N];
    for (uint32_t k = 0; k < 3 * N; k++)
        minima[k] = -dyadic(&r, 0, 1.5);
    image_list want = {0};
    for (int b = 0; b < BACKENDS; b++) {
        if (!bpx_backend_query(cpu_backends[b]).available)
            continue;
        check_set_context("two-phase, backend %s", bpx_backend_name(cpu_backends[b]));
        bpx_world *w = make(cpu_backends[b], 3, period, false);
        if (!w)
            continue;
        CHECK_STATUS(bpx_world_load_extents(w, minima, N), BPX_OK);
        scene_rng_seed(&r, 6);
        for (int cycle = 0; cycle < 4; cycle++) {
            for (uint32_t k = 0; k < N; k++)
                for (int a = 0; a < 3; a++) {
                    centres[3 * k + a] = dyadic(&r, -6, 12);
                    boxes[k].min[a] = centres[3 * k + a] + minima[3 * k + a];
                    boxes[k].max[a] = centres[3 * k + a] - minima[3 * k + a];
                }
            CHECK_STATUS(bpx_world_update_centres(w, centres), BPX_OK);
            CHECK_STATUS(bpx_world_collide(w), BPX_OK);
            brute(boxes, N, NULL, period, &want);
            size_t images = 0;
            const bpx_image_pair *got = bpx_world_image_pairs(w, &images);
            CHECK_MSG(same_images(got, images, &want), "%zu images, want %zu", images,
                      want.count);
        }
        bpx_world_destroy(w);
    }
    free(want.pairs);
}

// ---------------------------------------------------------------------------------------------
// Snapshots carry the period

static void test_snapshot(void)
{
    check_set_context("snapshot");
    enum { N = 50 };
    const double period[3] = {4, 4, 4}, open[3] = {0, 0, 0};
    scene_rng r;
    scene_rng_seed(&r, 11);
    config c = {{4, 4, 4}, N, 0.4};
    bpx_box boxes[N];
    random_boxes(&r, &c, boxes);
    bpx_world *w = make(BPX_BACKEND_AUTO, 1, period, true);
    bpx_world *other = make(BPX_BACKEND_SAP, 3, open, true);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, N), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    size_t size = 0;
    CHECK_STATUS(bpx_world_snapshot(w, NULL, 0, &size), BPX_ERR_CAPACITY);
    uint8_t *bytes = check_alloc(size);
    CHECK_STATUS(bpx_world_snapshot(w, bytes, size, &size), BPX_OK);
    CHECK_STATUS(bpx_world_restore(other, bytes, size), BPX_OK);
    double got[3];
    bpx_world_period(other, got);
    CHECK(got[0] == 4 && got[1] == 4 && got[2] == 4);
    // Both move alike and report the same pairs, images and events.
    for (int cycle = 0; cycle < 3; cycle++) {
        for (uint32_t k = 0; k < N; k += 3)
            for (int a = 0; a < 3; a++) {
                boxes[k].min[a] += 0.75f;
                boxes[k].max[a] += 0.75f;
            }
        CHECK_STATUS(bpx_world_set_boxes(w, boxes, N), BPX_OK);
        CHECK_STATUS(bpx_world_set_boxes(other, boxes, N), BPX_OK);
        CHECK_STATUS(bpx_world_collide(w), BPX_OK);
        CHECK_STATUS(bpx_world_collide(other), BPX_OK);
        size_t a = 0, b = 0;
        const bpx_image_pair *ia = bpx_world_image_pairs(w, &a);
        const bpx_image_pair *ib = bpx_world_image_pairs(other, &b);
        CHECK(a == b && a > 0 && memcmp(ia, ib, a * sizeof *ia) == 0);
        bpx_pair_events ea, eb;
        CHECK_STATUS(bpx_world_pair_events(w, &ea), BPX_OK);
        CHECK_STATUS(bpx_world_pair_events(other, &eb), BPX_OK);
        CHECK(ea.began_count == eb.began_count && ea.ended_count == eb.ended_count);
    }
    // A version-1 snapshot is refused, naming the version.
    uint32_t one = 1;
    memcpy(bytes + 8, &one, sizeof one);
    CHECK_STATUS(bpx_world_restore(other, bytes, size), BPX_ERR_INVALID_ARGUMENT);
    CHECK(strstr(bpx_world_error(other)->message, "version 1") != NULL);
    // A periodic snapshot into a world with contact margins is refused.
    CHECK_STATUS(bpx_world_snapshot(w, bytes, size, &size), BPX_OK);
    bpx_world_def def = bpx_default_world_def();
    def.begin_margin = 0.5f;
    bpx_world *margins = NULL;
    CHECK_STATUS(bpx_world_create(&def, &margins), BPX_OK);
    CHECK_STATUS(bpx_world_restore(margins, bytes, size), BPX_ERR_INVALID_ARGUMENT);
    CHECK(strstr(bpx_world_error(margins)->message, "margins") != NULL);
    bpx_world_destroy(margins);
    free(bytes);
    bpx_world_destroy(w);
    bpx_world_destroy(other);
}

// ---------------------------------------------------------------------------------------------
// Bad input

static void test_bad(void)
{
    check_set_context("bad periods");
    const double bad[] = {-1, NAN, INFINITY, -INFINITY, 0x1p1001};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++)
        for (int a = 0; a < 3; a++) {
            bpx_world_def def = bpx_default_world_def();
            def.period[a] = bad[k];
            bpx_world *w = (bpx_world *)&def;
            CHECK_STATUS(bpx_world_create(&def, &w), BPX_ERR_INVALID_ARGUMENT);
            CHECK(w == NULL);
            bpx_error err;
            CHECK_STATUS(bpx_world_def_check(&def, &err), BPX_ERR_INVALID_ARGUMENT);
            char name[16];
            snprintf(name, sizeof name, "period[%d]", a);
            CHECK_MSG(strstr(err.message, name) != NULL && err.axis == a, "%s", err.message);
            if (getenv("BPX_TEST_VERBOSE") && k == 0 && a == 1)
                printf("bad period: %s\n", err.message);
        }
    bpx_world_def def = bpx_default_world_def();
    def.period[0] = 10;
    def.end_margin = 0.5f;
    bpx_error err;
    CHECK_STATUS(bpx_world_def_check(&def, &err), BPX_ERR_INVALID_ARGUMENT);
    CHECK(strstr(err.message, "margins") != NULL);
    bpx_world *w = NULL;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_ERR_INVALID_ARGUMENT);
    def.end_margin = 0;
    CHECK_STATUS(bpx_world_def_check(&def, &err), BPX_OK);

    // A cell too small for its boxes: the error at collide, naming the box.
    check_set_context("cell too small");
    const double tiny[3] = {1e-6, 1e-6, 1e-6};
    w = make(BPX_BACKEND_AUTO, 1, tiny, true);
    bpx_box boxes[3] = {{{0, 0, 0}, {0.5f, 1, 1}}, {{3, 3, 3}, {4, 4, 4}}, {{0, 0, 0}, {1, 1, 1}}};
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 3), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_ERR_TOO_MANY_BOXES);
    const bpx_error *e = bpx_world_error(w);
    if (getenv("BPX_TEST_VERBOSE"))
        printf("cell too small: %s\n", e->message);
    CHECK_MSG(strstr(e->message, "periodic") != NULL && e->index == 0, "%s (index %u)",
              e->message, e->index);
    size_t count = 99;
    CHECK(bpx_world_pairs(w, &count) == NULL && count == 0);
    CHECK(bpx_world_image_pairs(w, &count) == NULL && count == 0);
    bpx_pair_events ev;
    CHECK_STATUS(bpx_world_pair_events(w, &ev), BPX_ERR_BAD_STATE);
    // With removed ids the error names the id, not the search's count of live boxes.
    bpx_box three[3] = {{{0.5f, 0.5f, 0.5f}, {0.5f, 0.5f, 0.5f}},
                        {{0.25f, 0.25f, 0.25f}, {0.25f, 0.25f, 0.25f}},
                        {{0, 0, 0}, {1, 1, 1}}};
    CHECK_STATUS(bpx_world_set_boxes(w, three, 3), BPX_OK);
    uint32_t gone = 0;
    CHECK_STATUS(bpx_world_remove_boxes(w, &gone, 1), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_ERR_TOO_MANY_BOXES);
    CHECK_MSG(bpx_world_error(w)->index == 2 && strstr(bpx_world_error(w)->message, "box id 2"),
              "%s (index %u)", bpx_world_error(w)->message, bpx_world_error(w)->index);
    // With a sensible cell it works again.
    bpx_world_destroy(w);
    const double fine[3] = {10, 0, 0};
    w = make(BPX_BACKEND_AUTO, 1, fine, true);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 3), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    bpx_world_pairs(w, &count);
    CHECK(count == 1);
    bpx_world_destroy(w);
}


// ---------------------------------------------------------------------------------------------
// Float64 boxes (bpx_world_set_boxes64): the exact answer where float32 would round

// Every image pair of float64 boxes, each test in long double (64 bits of mantissa at least:
// a coordinate plus a shift of a few periods is exact at these scales).
static void brute64(const bpx_box64 *boxes, uint32_t n, const double period[3], image_list *out)
{
    out->count = 0;
    for (uint32_t i = 0; i < n; i++)
        for (uint32_t j = i; j < n; j++) {
            int32_t lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
            for (int a = 0; a < 3; a++)
                if (period[a] > 0) {
                    lo[a] = (int32_t)floor((boxes[i].min[a] - boxes[j].max[a]) / period[a]) - 1;
                    hi[a] = (int32_t)ceil((boxes[i].max[a] - boxes[j].min[a]) / period[a]) + 1;
                }
            int32_t s[3];
            for (s[0] = lo[0]; s[0] <= hi[0]; s[0]++)
                for (s[1] = lo[1]; s[1] <= hi[1]; s[1]++)
                    for (s[2] = lo[2]; s[2] <= hi[2]; s[2]++) {
                        int first = s[0] ? s[0] : s[1] ? s[1] : s[2];
                        if (i == j && first <= 0)
                            continue;
                        bool yes = true;
                        for (int a = 0; a < 3; a++) {
                            long double t = (long double)s[a] * period[a];
                            yes &= (long double)boxes[j].min[a] + t <= boxes[i].max[a] &&
                                   (long double)boxes[i].min[a] <= (long double)boxes[j].max[a] + t;
                        }
                        if (yes)
                            push(out, (bpx_image_pair){i, j, {s[0], s[1], s[2]}});
                    }
        }
}

// Boxes at scale S in chains: each box's min on an axis 1 ulp below, at or 1 ulp above its
// predecessor's max, so that float32 rounding would merge many that do not touch.
static void chain_boxes64(scene_rng *r, double S, bool integers, uint32_t n, bpx_box64 *out)
{
    for (uint32_t k = 0; k < n; k++)
        for (int a = 0; a < 3; a++) {
            double size = integers ? (double)(1 + scene_rng_below(r, 40)) : S * 0.01 * (1 + scene_rng_below(r, 8));
            double lo;
            uint32_t how = scene_rng_below(r, 4);
            if (k > 0 && how < 3) {
                double edge = out[k - 1].max[a];
                lo = how == 0 ? nextafter(edge, -INFINITY) : how == 1 ? edge : nextafter(edge, INFINITY);
                if (integers)
                    lo = how == 0 ? edge - 1 : how == 1 ? edge : edge + 1;
            } else {
                lo = integers ? 0x1p25 + 2 * scene_rng_below(r, 64) + 1 : S * (1 + 0.002 * scene_rng_below(r, 100));
            }
            out[k].min[a] = lo;
            out[k].max[a] = lo + size;
        }
}

static void test_float64(void)
{
    enum { N = 70 };
    static const struct {
        double scale;
        bool integers;
    } scales[] = {{1e6, false}, {1e-30, false}, {0x1p25, true}};
    image_list want = {0};
    bpx_pair want_pairs[N * N];
    bpx_pair found[N * N];
    bpx_box64 boxes[N];
    for (size_t sc = 0; sc < sizeof scales / sizeof scales[0]; sc++)
        for (int periodic = 0; periodic < 2; periodic++) {
            scene_rng r;
            scene_rng_seed(&r, 300 + sc);
            check_set_seed(300 + sc);
            chain_boxes64(&r, scales[sc].scale, scales[sc].integers, N, boxes);
            double S = scales[sc].integers ? 0x1p25 : scales[sc].scale;
            double period[3] = {0, 0, 0};
            if (periodic) { // a cell about as wide as the chains, so some pairs are images
                period[0] = 0.5 * S;
                period[2] = scales[sc].integers ? 256 : 0.25 * S;
            }
            brute64(boxes, N, period, &want);
            size_t want_count = distinct(&want, want_pairs);
            // Float32 rounding would pair more: the test means something.
            size_t rounded = 0;
            for (uint32_t i = 0; i < N && !periodic; i++)
                for (uint32_t j = i + 1; j < N; j++) {
                    bool yes = true;
                    for (int a = 0; a < 3; a++)
                        yes &= (float)boxes[j].min[a] <= (float)boxes[i].max[a] &&
                               (float)boxes[i].min[a] <= (float)boxes[j].max[a];
                    rounded += yes;
                }
            if (getenv("BPX_TEST_VERBOSE"))
                printf("float64 scale %g periodic %d: %zu pairs, %zu images; float32 rounding "
                       "%zu\n", S, periodic, want_count, want.count, rounded);
            CHECK(periodic || rounded > want_count);
            if (!periodic) { // the one-shot call agrees
                size_t count = 0;
                CHECK_STATUS(bpx_find_pairs_f64(boxes, N, BPX_BACKEND_AUTO, found, N * N, &count,
                                                NULL),
                             BPX_OK);
                CHECK(same_pairs(found, count, want_pairs, want_count));
            }
            for (int b = 0; b < BACKENDS; b++) {
                if (!bpx_backend_query(cpu_backends[b]).available)
                    continue;
                for (int workers = 1; workers <= 3; workers += 2) {
                    check_set_context("float64 scale %g periodic %d backend %s workers %d", S,
                                      periodic, bpx_backend_name(cpu_backends[b]), workers);
                    bpx_world *w = make(cpu_backends[b], workers, period, true);
                    if (!w)
                        continue;
                    CHECK_STATUS(bpx_world_set_boxes64(w, boxes, N), BPX_OK);
                    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
                    size_t count = 0, images = 0;
                    const bpx_pair *pairs = bpx_world_pairs(w, &count);
                    CHECK_MSG(same_pairs(pairs, count, want_pairs, want_count),
                              "%zu pairs, want %zu", count, want_count);
                    const bpx_image_pair *got = bpx_world_image_pairs(w, &images);
                    if (periodic)
                        CHECK_MSG(same_images(got, images, &want), "%zu images, want %zu",
                                  images, want.count);
                    bpx_pair_events ev;
                    CHECK_STATUS(bpx_world_pair_events(w, &ev), BPX_OK);
                    CHECK(ev.began_count == want_count && ev.ended_count == 0);
                    // Float64 boxes are set whole; float32 boxes by id come back with set_boxes.
                    uint32_t id = 0;
                    bpx_box one = {{0, 0, 0}, {1, 1, 1}};
                    CHECK_STATUS(bpx_world_add_boxes(w, &one, 1, &id), BPX_ERR_BAD_STATE);
                    CHECK_STATUS(bpx_world_remove_boxes(w, &id, 1), BPX_ERR_BAD_STATE);
                    CHECK_STATUS(bpx_world_move_boxes(w, &id, &one, 1), BPX_ERR_BAD_STATE);
                    size_t size = 0;
                    CHECK_STATUS(bpx_world_snapshot(w, NULL, 0, &size), BPX_ERR_BAD_STATE);
                    // The same boxes again: nothing begins or ends.
                    CHECK_STATUS(bpx_world_set_boxes64(w, boxes, N), BPX_OK);
                    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
                    CHECK_STATUS(bpx_world_pair_events(w, &ev), BPX_OK);
                    CHECK(ev.began_count == 0 && ev.ended_count == 0);
                    CHECK_STATUS(bpx_world_set_boxes(w, &one, 1), BPX_OK);
                    CHECK_STATUS(bpx_world_add_boxes(w, &one, 1, &id), BPX_OK);
                    bpx_world_destroy(w);
                }
            }
        }
    // Bad float64 boxes are named; a world with margins refuses them.
    check_set_context("float64 bad boxes");
    bpx_world *w = make(BPX_BACKEND_AUTO, 1, (double[3]){0, 0, 0}, false);
    boxes[3].min[1] = NAN;
    CHECK_STATUS(bpx_world_set_boxes64(w, boxes, N), BPX_ERR_NOT_FINITE);
    CHECK(bpx_world_error(w)->index == 3 && bpx_world_error(w)->axis == 1);
    boxes[3].min[1] = boxes[3].max[1] + 1;
    CHECK_STATUS(bpx_world_set_boxes64(w, boxes, N), BPX_ERR_MIN_GREATER_THAN_MAX);
    CHECK(bpx_world_error(w)->index == 3 && bpx_world_error(w)->axis == 1);
    CHECK_STATUS(bpx_world_set_boxes64(w, NULL, 2), BPX_ERR_NULL_ARGUMENT);
    bpx_world_destroy(w);
    bpx_world_def def = bpx_default_world_def();
    def.begin_margin = 1;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    CHECK_STATUS(bpx_world_set_boxes64(w, boxes, 2), BPX_ERR_BAD_STATE);
    bpx_world_destroy(w);
    free(want.pairs);
}

// ---------------------------------------------------------------------------------------------
// Allocation failure: every allocation fails in turn, with no crash and no leak

static atomic_llong budget_left; // negative: unlimited
static atomic_llong live_blocks;

static void *failing_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    if (atomic_load(&budget_left) >= 0 && atomic_fetch_sub(&budget_left, 1) <= 0)
        return NULL;
    size_t align = alignment < 16 ? 16 : alignment;
    void *p = aligned_alloc(align, (size + align - 1) / align * align);
    if (p)
        atomic_fetch_add(&live_blocks, 1);
    return p;
}

static void failing_free(void *memory, void *user)
{
    (void)user;
    if (memory)
        atomic_fetch_sub(&live_blocks, 1);
    free(memory);
}

static void test_out_of_memory(void)
{
    enum { N = 120 };
    const double period[3] = {6, 6, 6};
    scene_rng r;
    scene_rng_seed(&r, 3);
    config c = {{6, 6, 6}, N, 0.8};
    bpx_box boxes[N];
    random_boxes(&r, &c, boxes);
    image_list want = {0};
    brute(boxes, N, NULL, period, &want);
    int64_t start = bpx_allocated_bytes();
    bpx_set_allocator(failing_alloc, failing_free, NULL);
    for (int workers = 1; workers <= 3; workers += 2) {
        long long budget = 0;
        for (; budget < 100000; budget++) {
            check_set_context("out of memory after %lld allocations, %d workers", budget, workers);
            atomic_store(&budget_left, budget);
            bpx_world_def def = bpx_default_world_def();
            def.worker_count = workers;
            def.track_events = true;
            memcpy(def.period, period, sizeof def.period);
            bpx_world *w = NULL;
            bpx_status s = bpx_world_create(&def, &w);
            bool done = false;
            if (s == BPX_OK) {
                bpx_status set = bpx_world_set_boxes(w, boxes, N);
                bpx_status collide = set == BPX_OK ? bpx_world_collide(w) : set;
                CHECK(collide == BPX_OK || collide == BPX_ERR_OUT_OF_MEMORY);
                size_t images = 0;
                const bpx_image_pair *got = bpx_world_image_pairs(w, &images);
                if (collide == BPX_OK)
                    CHECK(same_images(got, images, &want));
                else
                    CHECK(got == NULL && images == 0);
                done = collide == BPX_OK;
                // Memory back: the world recovers.
                atomic_store(&budget_left, -1);
                CHECK_STATUS(bpx_world_set_boxes(w, boxes, N), BPX_OK);
                CHECK_STATUS(bpx_world_collide(w), BPX_OK);
                got = bpx_world_image_pairs(w, &images);
                CHECK(same_images(got, images, &want));
                bpx_world_destroy(w);
            } else {
                CHECK(s == BPX_ERR_OUT_OF_MEMORY);
            }
            atomic_store(&budget_left, -1);
            CHECK(bpx_allocated_bytes() == start);
            CHECK_EQ_U64(atomic_load(&live_blocks), 0);
            if (done)
                break;
        }
        printf("  periodic world, %d workers: a cycle needs %lld allocations; every shorter "
               "budget failed cleanly\n",
               workers, budget);
        CHECK(budget > 0);
    }
    bpx_set_allocator(NULL, NULL, NULL);
    free(want.pairs);
}

// ---------------------------------------------------------------------------------------------
// Boxes moving across the faces over many cycles (they wrap, unwrap, gain and lose ghosts, and
// the count changes), each cycle against the brute force; then the allocations of a steady cycle

static atomic_llong allocations; // counted by counting_alloc

static void *counting_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    atomic_fetch_add(&allocations, 1);
    size_t align = alignment < 16 ? 16 : alignment;
    return aligned_alloc(align, (size + align - 1) / align * align);
}

static void counting_free(void *memory, void *user)
{
    (void)user;
    free(memory);
}

static void test_moving(void)
{
    enum { N = 160, CYCLES = 12 };
    config c = {{8, 8, 5}, N, 0.4};
    image_list want = {0};
    bpx_pair *want_pairs = malloc((size_t)N * N * 27 * sizeof *want_pairs);
    for (int b = 0; b < BACKENDS; b++) {
        if (!bpx_backend_query(cpu_backends[b]).available)
            continue;
        for (int workers = 1; workers <= 3; workers += 2) {
            scene_rng r;
            scene_rng_seed(&r, 77);
            bpx_box boxes[N];
            random_boxes(&r, &c, boxes);
            bpx_world *w = make(cpu_backends[b], workers, c.period, true);
            for (int cycle = 0; cycle < CYCLES; cycle++) {
                check_set_context("moving, backend %s workers %d cycle %d",
                                  bpx_backend_name(cpu_backends[b]), workers, cycle);
                uint32_t n = cycle == 5 ? N - 30 : cycle == 6 ? N - 31 : N;
                for (uint32_t k = 0; k < N && cycle > 0; k++)
                    for (int a = 0; a < 3; a++) { // up to a period's fifth, in 1/8 steps
                        float d = dyadic(&r, -c.period[a] / 5, c.period[a] / 5);
                        boxes[k].min[a] += d;
                        boxes[k].max[a] += d;
                    }
                brute(boxes, n, NULL, c.period, &want);
                size_t want_count = distinct(&want, want_pairs);
                CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
                CHECK_STATUS(bpx_world_collide(w), BPX_OK);
                size_t count = 0, images = 0;
                const bpx_pair *pairs = bpx_world_pairs(w, &count);
                const bpx_image_pair *got = bpx_world_image_pairs(w, &images);
                CHECK_MSG(same_images(got, images, &want), "%zu images, want %zu", images,
                          want.count);
                CHECK_MSG(same_pairs(pairs, count, want_pairs, want_count),
                          "%zu pairs, want %zu", count, want_count);
            }
            bpx_world_destroy(w);
        }
    }
    // A steady cycle of the image search allocates nothing: the world of images' box sets, the
    // wraps, flags, ghosts and pair lists are kept. Brute force as the backend (it keeps no
    // per-cycle memory of its own either), boxes that move a little and cross the faces.
    bpx_set_allocator(counting_alloc, counting_free, NULL);
    for (int workers = 1; workers <= 3; workers += 2) {
        check_set_context("steady cycle allocations, %d workers", workers);
        scene_rng r;
        scene_rng_seed(&r, 78);
        bpx_box boxes[N];
        random_boxes(&r, &c, boxes);
        bpx_world *w = make(BPX_BACKEND_BRUTE, workers, c.period, false);
        long long last = -1;
        for (int cycle = 0; cycle < 8; cycle++) {
            for (uint32_t k = 0; k < N; k++)
                for (int a = 0; a < 3; a++) {
                    float d = cycle % 2 ? 0.125f : -0.125f; // back and forth across
                    boxes[k].min[a] += d;
                    boxes[k].max[a] += d;
                }
            atomic_store(&allocations, 0);
            CHECK_STATUS(bpx_world_set_boxes(w, boxes, N), BPX_OK);
            CHECK_STATUS(bpx_world_collide(w), BPX_OK);
            last = atomic_load(&allocations);
        }
        CHECK_MSG(last == 0, "a steady cycle made %lld allocations", last);
        bpx_world_destroy(w);
    }
    bpx_set_allocator(NULL, NULL, NULL);
    free(want.pairs);
    free(want_pairs);
}

int main(void)
{
    int64_t start = bpx_allocated_bytes();
    test_bad();
    test_random();
    test_moving();
    test_rules_and_events();
    test_two_phase();
    test_snapshot();
    test_float64();
    test_out_of_memory();
    CHECK(bpx_allocated_bytes() == start);
    return check_finish("test_periodic", 1);
}
