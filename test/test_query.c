// Queries against an oracle that applies include/bpx/query.h's definitions to every box, on
// every scene kind and on adversarial rays; batches at every worker count byte for byte;
// filters, removed ids, moves (refits), bad queries, CAPACITY and allocation failure.
#include <float.h>
#include <math.h>

#include "check.h"
#include "scenes.h"

// ---------------------------------------------------------------------------------------------
// The oracle: the header's definitions, box by box, written without the library's code.

typedef struct world_copy {
    const bpx_box *boxes;
    uint32_t n;
    const uint8_t *live;       // NULL: every box
    const uint32_t *category;  // NULL: 1
    const uint32_t *mask;      // NULL: all ones
} world_copy;

static bool oracle_seen(const world_copy *w, const bpx_query *q, uint32_t id)
{
    if (w->live && !w->live[id])
        return false;
    uint32_t category = w->category ? w->category[id] : 1u;
    uint32_t mask = w->mask ? w->mask[id] : 0xFFFFFFFFu;
    return (q->filter.category & mask) && (category & q->filter.mask);
}

// Whether box b is hit, and at what fraction.
static bool oracle_hit(const bpx_query *q, const bpx_box *b, float *fraction)
{
    *fraction = 0.0f;
    if (q->kind == BPX_QUERY_BOX) {
        for (int a = 0; a < 3; a++)
            if (!(b->min[a] <= q->box.max[a] && b->max[a] >= q->box.min[a]))
                return false;
        return true;
    }
    if (q->kind == BPX_QUERY_SPHERE) {
        double d2 = 0.0;
        for (int a = 0; a < 3; a++) {
            double g = fmax(fmax((double)b->min[a] - q->centre[a], q->centre[a] - (double)b->max[a]),
                            0.0);
            d2 += g * g;
        }
        return d2 <= (double)q->radius * (double)q->radius;
    }
    float qlo[3], qhi[3];
    for (int a = 0; a < 3; a++) {
        qlo[a] = q->kind == BPX_QUERY_RAY ? q->origin[a] : q->box.min[a];
        qhi[a] = q->kind == BPX_QUERY_RAY ? q->origin[a] : q->box.max[a];
    }
    double enter = -INFINITY, exit = INFINITY;
    for (int a = 0; a < 3; a++) {
        if (q->direction[a] == 0.0f) {
            if (!(b->min[a] <= qhi[a] && b->max[a] >= qlo[a]))
                return false;
            continue;
        }
        double inv = 1.0 / (double)q->direction[a];
        double t1 = ((double)b->min[a] - (double)qhi[a]) * inv;
        double t2 = ((double)b->max[a] - (double)qlo[a]) * inv;
        enter = fmax(enter, fmin(t1, t2));
        exit = fmin(exit, fmax(t1, t2));
    }
    double from = fmax(enter, 0.0);
    if (!(from <= fmin(exit, (double)q->max_fraction)))
        return false;
    *fraction = (float)from;
    return true;
}

static int hit_by_id(const void *a, const void *b)
{
    uint32_t x = ((const bpx_hit *)a)->id, y = ((const bpx_hit *)b)->id;
    return (x > y) - (x < y);
}

static int hit_by_fraction(const void *a, const void *b)
{
    const bpx_hit *x = a, *y = b;
    if (x->fraction != y->fraction)
        return x->fraction < y->fraction ? -1 : 1;
    return hit_by_id(a, b);
}

// The query's hits into out (room for n), in the defined order; returns their number.
static size_t oracle(const world_copy *w, const bpx_query *q, bpx_hit *out)
{
    size_t count = 0;
    for (uint32_t i = 0; i < w->n; i++) {
        float f;
        if (oracle_seen(w, q, i) && oracle_hit(q, &w->boxes[i], &f))
            out[count++] = (bpx_hit){i, f};
    }
    bool cast = q->kind == BPX_QUERY_RAY || q->kind == BPX_QUERY_SWEEP;
    qsort(out, count, sizeof *out, cast ? hit_by_fraction : hit_by_id);
    return cast && q->closest && count ? 1 : count;
}

// ---------------------------------------------------------------------------------------------
// Queries made from a scene: near its boxes, through their faces and corners, of every kind.

static float pick(scene_rng *r, const bpx_box *boxes, uint32_t n, int a)
{
    const bpx_box *b = &boxes[scene_rng_below(r, n)];
    switch (scene_rng_below(r, 4)) {
    case 0: return b->min[a];
    case 1: return b->max[a];
    case 2: return scene_rng_range(r, b->min[a], b->max[a]);
    default: return scene_rng_range(r, -4.0f, 4.0f) + b->min[a];
    }
}

static float direction_component(scene_rng *r)
{
    switch (scene_rng_below(r, 8)) {
    case 0: return 0.0f;
    case 1: return -0.0f;
    case 2: return 1.0e-42f; // denormal
    case 3: return -1.0f;
    case 4: return 1.0f;
    default: return scene_rng_range(r, -10.0f, 10.0f);
    }
}

static bpx_query random_query(scene_rng *r, const bpx_box *boxes, uint32_t n)
{
    bpx_query q = {.filter = bpx_default_query_filter()};
    q.kind = (bpx_query_kind)scene_rng_below(r, BPX_QUERY_SWEEP + 1); // the oracle's kinds
    q.closest = scene_rng_below(r, 2);
    for (int a = 0; a < 3; a++) {
        float x = pick(r, boxes, n, a), y = pick(r, boxes, n, a);
        q.box.min[a] = fminf(x, y);
        q.box.max[a] = fmaxf(x, y);
        q.centre[a] = pick(r, boxes, n, a);
        q.origin[a] = pick(r, boxes, n, a);
        q.direction[a] = direction_component(r);
    }
    q.radius = scene_rng_below(r, 4) ? scene_rng_range(r, 0.0f, 3.0f) : 0.0f;
    switch (scene_rng_below(r, 4)) {
    case 0: q.max_fraction = INFINITY; break;
    case 1: q.max_fraction = 1.0f; break;
    case 2: q.max_fraction = 0.0f; break;
    default: q.max_fraction = scene_rng_range(r, 0.0f, 50.0f);
    }
    bool zero = q.direction[0] == 0.0f && q.direction[1] == 0.0f && q.direction[2] == 0.0f;
    if (zero)
        q.max_fraction = 0.0f;
    return q;
}

// ---------------------------------------------------------------------------------------------

// The walks' instruction set: the widest (AUTO) or the portable one, the same results.
static bpx_simd query_simd = BPX_SIMD_AUTO;

static bpx_world *make_world(int workers)
{
    bpx_world_def def = bpx_default_world_def();
    def.worker_count = workers;
    def.simd = query_simd;
    bpx_world *w = NULL;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    return w;
}

static bpx_hit *expect_buf, *got_buf;
static size_t buf_cap;

// bpx_world_query_each's callbacks for the tests: collect every hit (and its user data), or
// keep the closest so far and clip the cast to it.
typedef struct collected {
    bpx_hit *hits;
    size_t count;
    size_t capacity;
    bool user_data_ok;
    const uint64_t *user_data; // per id, or NULL (every box's 0)
    bpx_hit best;
} collected;

static float collect(const bpx_hit *hit, uint64_t user_data, void *context)
{
    collected *c = context;
    if (c->count < c->capacity)
        c->hits[c->count] = *hit;
    c->count++;
    c->user_data_ok &= user_data == (c->user_data ? c->user_data[hit->id] : 0);
    return INFINITY;
}

static float keep_closest(const bpx_hit *hit, uint64_t user_data, void *context)
{
    (void)user_data;
    collected *c = context;
    c->count++;
    if (hit->fraction < c->best.fraction ||
        (hit->fraction == c->best.fraction && hit->id < c->best.id))
        c->best = *hit;
    // Hits entering later cannot be closer; 0 would stop the walk, and a tie at 0 may still
    // have a lower id: the least positive float keeps those.
    return c->best.fraction > 0.0f ? c->best.fraction : FLT_TRUE_MIN;
}

static bpx_hit *all_buf;

// The read-only calls on the same world (its tree is current: a query just ran): query_shared
// gives the same bytes; any gives one of all's hits (or none when there are none); query_each
// visits all's hits, and, clipping, ends on the closest.
static void check_read_only(bpx_world *w, const world_copy *copy, const bpx_query *q, int k,
                            const bpx_hit *want, size_t want_count, const uint64_t *user_data)
{
    size_t got = 0;
    bpx_error err;
    bpx_status s = bpx_world_query_shared(w, q, got_buf, buf_cap, &got, &err);
    CHECK_MSG(s == BPX_OK && got == want_count &&
                  memcmp(got_buf, want, sizeof(bpx_hit) * want_count) == 0,
              "query %d kind %d: shared %zu hits (%s), query %zu", k, q->kind, got, err.message,
              want_count);
    bpx_query all = *q;
    all.closest = false;
    size_t all_count = oracle(copy, &all, all_buf);
    bpx_query any = all;
    any.any = true;
    CHECK_STATUS(bpx_world_query(w, &any, got_buf, buf_cap, &got), BPX_OK);
    bool found = false;
    for (size_t h = 0; got == 1 && h < all_count; h++)
        found |= all_buf[h].id == got_buf[0].id && all_buf[h].fraction == got_buf[0].fraction;
    CHECK_MSG(all_count ? got == 1 && found : got == 0, "query %d kind %d: any gave %zu hits (%s), all %zu",
              k, q->kind, got, got ? "listed" : "-", all_count);
    collected c = {got_buf, 0, buf_cap, true, user_data, {UINT32_MAX, INFINITY}};
    CHECK_STATUS(bpx_world_query_each(w, &all, collect, &c, NULL), BPX_OK);
    bool same = c.count == all_count && c.user_data_ok;
    if (same && c.count > 1) // walk order: sort as the oracle does
        qsort(got_buf, c.count, sizeof(bpx_hit),
              q->kind == BPX_QUERY_RAY || q->kind == BPX_QUERY_SWEEP ? hit_by_fraction : hit_by_id);
    same = same && memcmp(got_buf, all_buf, sizeof(bpx_hit) * all_count) == 0;
    CHECK_MSG(same, "query %d kind %d: each visited %zu, all %zu", k, q->kind, c.count, all_count);
    if (q->kind == BPX_QUERY_RAY || q->kind == BPX_QUERY_SWEEP) {
        c = (collected){NULL, 0, 0, true, NULL, {UINT32_MAX, INFINITY}};
        CHECK_STATUS(bpx_world_query_each(w, &all, keep_closest, &c, NULL), BPX_OK);
        CHECK_MSG(all_count ? c.best.id == all_buf[0].id && c.best.fraction == all_buf[0].fraction
                            : c.count == 0,
                  "query %d kind %d: clipping callback ended on %u@%g, closest %u@%g", k, q->kind,
                  c.best.id, (double)c.best.fraction, all_count ? all_buf[0].id : 0,
                  all_count ? (double)all_buf[0].fraction : 0.0);
        CHECK(c.count <= all_count);
    }
}

static void compare_one(bpx_world *w, const world_copy *copy, const bpx_query *q, int k)
{
    size_t want = oracle(copy, q, expect_buf), got = 0;
    bpx_status s = bpx_world_query(w, q, got_buf, buf_cap, &got);
    CHECK_MSG(s == BPX_OK, "query %d kind %d: %s", k, q->kind, bpx_world_error(w)->message);
    CHECK_MSG(got == want && memcmp(got_buf, expect_buf, sizeof(bpx_hit) * want) == 0,
              "query %d kind %d closest %d: %zu hits, oracle %zu (first %u@%g vs %u@%g)", k,
              q->kind, q->closest, got, want, got ? got_buf[0].id : 0,
              got ? (double)got_buf[0].fraction : 0.0, want ? expect_buf[0].id : 0,
              want ? (double)expect_buf[0].fraction : 0.0);
    check_read_only(w, copy, q, k, expect_buf, want, NULL);
}

// Every scene kind at several sizes: single queries against the oracle, with the walks of one
// instruction set (the widest, or the portable ones).
static void test_scenes(bpx_simd simd)
{
    query_simd = simd;
    const uint32_t sizes[] = {0, 1, 2, 5, 17, 100, 1000};
    // After the kinds: boxes 50 times longer on x, then on random axes.
    for (int kind = 0; kind < SCENE_KIND_COUNT + 2; kind++)
        for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
            uint32_t n = sizes[s];
            uint64_t seed = 1000u * (uint64_t)kind + s;
            bool elongated = kind >= SCENE_KIND_COUNT;
            check_set_seed(seed);
            check_set_context("scene %s n=%u simd %s",
                              elongated ? (kind == SCENE_KIND_COUNT ? "long" : "long_any")
                                        : scene_kind_name((scene_kind)kind),
                              n, bpx_simd_name(simd));
            bpx_box *boxes = malloc(sizeof(bpx_box) * (n ? n : 1));
            if (elongated)
                scene_elongated_density(n, 50.0f, kind > SCENE_KIND_COUNT, seed, boxes);
            else
                CHECK(scene_generate((scene_kind)kind, n, seed, boxes) == 0);
            bpx_world *w = make_world(1);
            CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
            world_copy copy = {boxes, n, NULL, NULL, NULL};
            scene_rng r;
            scene_rng_seed(&r, seed);
            bpx_box origin_box = {{0, 0, 0}, {0, 0, 0}};
            for (int k = 0; k < 300; k++) {
                bpx_query q = random_query(&r, n ? boxes : &origin_box, n ? n : 1);
                compare_one(w, &copy, &q, k);
            }
            bpx_world_destroy(w);
            free(boxes);
        }
    query_simd = BPX_SIMD_AUTO;
}

// A world big enough that the tree is built and refitted in parallel passes and subtrees: at
// every worker count the same results, against the oracle; then every box moves (a refit) and
// a few are removed (a rebuild). Heavy-tailed sizes, or boxes long on random axes (the keys'
// subtrees by shape and their own bit orders).
static void test_parallel_tree(bool elongated)
{
    enum { N = 150000, Q = 200 };
    bpx_box *boxes = malloc(sizeof(bpx_box) * N);
    uint8_t *live = malloc(N);
    if (elongated)
        scene_elongated_density(N, 50.0f, true, 21, boxes);
    else
        scene_heavy_tailed_density(N, 21, boxes);
    memset(live, 1, N);
    bpx_query *queries = malloc(sizeof(bpx_query) * Q);
    scene_rng r;
    scene_rng_seed(&r, 23);
    for (int k = 0; k < Q; k++)
        queries[k] = random_query(&r, boxes, N);
    bpx_world *worlds[3];
    for (int k = 0; k < 3; k++) {
        worlds[k] = make_world(k == 0 ? 1 : k + 1);
        CHECK_STATUS(bpx_world_set_boxes(worlds[k], boxes, N), BPX_OK);
    }
    world_copy copy = {boxes, N, live, NULL, NULL};
    for (int phase = 0; phase < 3; phase++) {
        check_set_context("parallel tree phase %d elongated %d", phase, (int)elongated);
        if (phase == 1) { // every box moves: a refit
            scene_move(boxes, N, 0.5f, &r);
            for (int k = 0; k < 3; k++)
                CHECK_STATUS(bpx_world_set_boxes(worlds[k], boxes, N), BPX_OK);
        } else if (phase == 2) { // some leave: a rebuild
            uint32_t ids[100];
            for (uint32_t k = 0; k < 100; k++) {
                ids[k] = (k * 1499u + 7u) % N;
                live[ids[k]] = 0;
            }
            for (int k = 0; k < 3; k++)
                CHECK_STATUS(bpx_world_remove_boxes(worlds[k], ids, 100), BPX_OK);
        }
        for (int q = 0; q < Q; q++) {
            size_t want = oracle(&copy, &queries[q], expect_buf);
            for (int k = 0; k < 3; k++) {
                size_t got = 0;
                CHECK_STATUS(bpx_world_query(worlds[k], &queries[q], got_buf, buf_cap, &got),
                             BPX_OK);
                CHECK_MSG(got == want && memcmp(got_buf, expect_buf, sizeof(bpx_hit) * want) == 0,
                          "query %d kind %d world %d: %zu hits, oracle %zu", q, queries[q].kind,
                          k, got, want);
            }
        }
        bpx_query_stats first = bpx_world_query_stats(worlds[0]);
        for (int k = 1; k < 3; k++) {
            bpx_query_stats st = bpx_world_query_stats(worlds[k]);
            CHECK(st.nodes == first.nodes && st.builds == first.builds &&
                  st.refits == first.refits);
        }
        CHECK(first.builds == (phase == 2 ? 2u : 1u) && first.refits == (phase >= 1 ? 1u : 0u));
    }
    for (int k = 0; k < 3; k++)
        bpx_world_destroy(worlds[k]);
    free(queries);
    free(live);
    free(boxes);
}

// A lattice of unit boxes whose faces touch: rays along shared faces and edges, through
// corners, from inside, parallel to faces, across -0.0 planes, of zero length.
static void test_adversarial_rays(void)
{
    enum { SIDE = 6 };
    bpx_box boxes[SIDE * SIDE * SIDE];
    uint32_t n = 0;
    for (int x = -SIDE / 2; x < SIDE / 2; x++)
        for (int y = -SIDE / 2; y < SIDE / 2; y++)
            for (int z = -SIDE / 2; z < SIDE / 2; z++)
                boxes[n++] = (bpx_box){{(float)x, (float)y, (float)z},
                                       {(float)x + 1, (float)y + 1, (float)z + 1}};
    // Signed zeros on some of the boxes at the origin's planes.
    for (uint32_t i = 0; i < n; i += 2)
        for (int a = 0; a < 3; a++)
            if (boxes[i].min[a] == 0.0f)
                boxes[i].min[a] = -0.0f;
    bpx_world *w = make_world(1);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
    world_copy copy = {boxes, n, NULL, NULL, NULL};
    const float coords[] = {-3.0f, -1.0f, -0.5f, -0.0f, 0.0f, 0.5f, 1.0f, 3.0f, 2.999999f};
    const float dirs[] = {0.0f, -0.0f, 1.0f, -1.0f, 1e-42f, -1e-42f, 0.5f};
    const float fractions[] = {0.0f, 1.0f, 2.5f, INFINITY};
    size_t nc = sizeof coords / sizeof coords[0], nd = sizeof dirs / sizeof dirs[0];
    int k = 0;
    check_set_context("lattice rays");
    for (size_t ox = 0; ox < nc; ox++)
        for (size_t oy = 0; oy < nc; oy += 2)
            for (size_t oz = 0; oz < nc; oz += 3)
                for (size_t d = 0; d < nd * nd; d++) {
                    float o[3] = {coords[ox], coords[oy], coords[oz]};
                    float dir[3] = {dirs[d % nd], dirs[d / nd], dirs[(d + ox) % nd]};
                    float f = fractions[(d + oy) % 4];
                    bool zero = dir[0] == 0.0f && dir[1] == 0.0f && dir[2] == 0.0f;
                    bpx_query q = bpx_query_ray(o, dir, zero ? 0.0f : f, (d + oz) % 2 == 0);
                    compare_one(w, &copy, &q, k++);
                    bpx_box moving = {{o[0] - 0.5f, o[1], o[2]}, {o[0], o[1] + 0.25f, o[2]}};
                    bpx_query s = bpx_query_sweep(moving, dir, zero ? 0.0f : f, (d + oz) % 2);
                    compare_one(w, &copy, &s, k++);
                }
    // Spheres centred on corners with radii that just reach a neighbour's face.
    for (size_t c = 0; c < nc; c++) {
        float centre[3] = {coords[c], coords[(c + 3) % nc], coords[(c + 5) % nc]};
        const float radii[] = {0.0f, 0.5f, 1.0f, nextafterf(1.0f, 0.0f)};
        for (int r = 0; r < 4; r++) {
            bpx_query q = bpx_query_sphere(centre, radii[r]);
            compare_one(w, &copy, &q, k++);
        }
    }
    bpx_world_destroy(w);
}

// Filters, removed and added boxes, moves: the tree refits or rebuilds, the oracle follows.
static void test_objects_and_moves(void)
{
    enum { N = 2000, ROUNDS = 12 };
    bpx_box *boxes = malloc(sizeof(bpx_box) * N);
    uint8_t live[N];
    uint32_t category[N], mask[N];
    scene_uniform_density(N, 2.0f, 7, boxes);
    bpx_world *w = make_world(2);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, N), BPX_OK);
    memset(live, 1, sizeof live);
    scene_rng r;
    scene_rng_seed(&r, 99);
    for (uint32_t i = 0; i < N; i++) {
        category[i] = 1u << scene_rng_below(&r, 4);
        mask[i] = scene_rng_below(&r, 8) ? 0xFFFFFFFFu : 0x5u;
    }
    CHECK_STATUS(bpx_world_set_filters(w, NULL, category, mask, N), BPX_OK);
    world_copy copy = {boxes, N, live, category, mask};
    for (int round = 0; round < ROUNDS; round++) {
        check_set_context("objects round %d", round);
        if (round % 3 == 1) { // remove a few, then add them back (ids come back after collide)
            uint32_t ids[20];
            for (int k = 0; k < 20; k++)
                ids[k] = (uint32_t)(round * 37 + k * 11) % N;
            CHECK_STATUS(bpx_world_remove_boxes(w, ids, 20), BPX_OK);
            for (int k = 0; k < 20; k++)
                live[ids[k]] = 0;
        } else if (round % 3 == 2) {
            CHECK_STATUS(bpx_world_collide(w), BPX_OK);
            uint32_t ids[20], dead[20], d = 0;
            for (uint32_t i = 0; i < N && d < 20; i++)
                if (!live[i])
                    dead[d++] = i;
            bpx_box added[20];
            for (uint32_t k = 0; k < d; k++)
                added[k] = boxes[dead[k]];
            CHECK_STATUS(bpx_world_add_boxes(w, added, d, ids), BPX_OK);
            for (uint32_t k = 0; k < d; k++) {
                CHECK(ids[k] < N);
                if (ids[k] < N) {
                    boxes[ids[k]] = added[k];
                    live[ids[k]] = 1;
                    category[ids[k]] = 1; // added ids start unfiltered
                    mask[ids[k]] = 0xFFFFFFFFu;
                }
            }
        } else { // everything moves a little: a refit
            scene_move(boxes, N, 0.3f, &r);
            uint32_t ids[N];
            uint32_t m = 0;
            bpx_box moved[N];
            for (uint32_t i = 0; i < N; i++)
                if (live[i]) {
                    ids[m] = i;
                    moved[m++] = boxes[i];
                }
            CHECK_STATUS(bpx_world_move_boxes(w, ids, moved, m), BPX_OK);
        }
        for (int k = 0; k < 150; k++) {
            bpx_query q = random_query(&r, boxes, N);
            q.filter.category = scene_rng_below(&r, 3) ? 0xFFFFFFFFu : 1u << scene_rng_below(&r, 4);
            q.filter.mask = scene_rng_below(&r, 3) ? 0xFFFFFFFFu : 0x6u;
            compare_one(w, &copy, &q, k);
        }
    }
    bpx_query_stats st = bpx_world_query_stats(w);
    CHECK_MSG(st.refits > 0 && st.builds > 1, "builds %llu refits %llu",
              (unsigned long long)st.builds, (unsigned long long)st.refits);
    bpx_world_destroy(w);
    free(boxes);
}

// The paper's two phases: centres move every cycle, the tree refits.
static void test_centres(void)
{
    enum { N = 500 };
    float minima[3 * N], centres[3 * N];
    bpx_box boxes[N];
    scene_rng r;
    scene_rng_seed(&r, 5);
    for (int i = 0; i < 3 * N; i++) {
        minima[i] = -scene_rng_range(&r, 0.1f, 1.0f);
        centres[i] = scene_rng_range(&r, -10.0f, 10.0f);
    }
    bpx_world *w = make_world(1);
    CHECK_STATUS(bpx_world_load_extents(w, minima, N), BPX_OK);
    world_copy copy = {boxes, N, NULL, NULL, NULL};
    for (int cycle = 0; cycle < 5; cycle++) {
        check_set_context("centres cycle %d", cycle);
        for (int i = 0; i < 3 * N; i++)
            centres[i] += scene_rng_range(&r, -0.2f, 0.2f);
        CHECK_STATUS(bpx_world_update_centres(w, centres), BPX_OK);
        for (int i = 0; i < N; i++)
            for (int a = 0; a < 3; a++) {
                boxes[i].min[a] = centres[3 * i + a] + minima[3 * i + a];
                boxes[i].max[a] = centres[3 * i + a] - minima[3 * i + a];
            }
        for (int k = 0; k < 100; k++) {
            bpx_query q = random_query(&r, boxes, N);
            compare_one(w, &copy, &q, k);
        }
    }
    CHECK(bpx_world_query_stats(w).refits >= 3);
    bpx_world_destroy(w);
}

// Batches: the CSR result equals the single queries', byte for byte, at every worker count.
static void test_batches(void)
{
    enum { N = 20000, Q = 3000 };
    bpx_box *boxes = malloc(sizeof(bpx_box) * N);
    scene_heavy_tailed_density(N, 3, boxes);
    bpx_query *queries = malloc(sizeof(bpx_query) * Q);
    scene_rng r;
    scene_rng_seed(&r, 11);
    for (int k = 0; k < Q; k++)
        queries[k] = random_query(&r, boxes, N);
    size_t *first_offsets = NULL;
    bpx_hit *first_hits = NULL;
    size_t first_total = 0;
    for (int workers = 1; workers <= 4; workers++) {
        check_set_context("batch workers=%d", workers);
        bpx_world *w = make_world(workers);
        CHECK_STATUS(bpx_world_set_boxes(w, boxes, N), BPX_OK);
        size_t *offsets = malloc(sizeof(size_t) * (Q + 1));
        size_t total = 0;
        // Too small first: CAPACITY with the count, nothing lost.
        bpx_hit probe = {12345u, 6.0f};
        CHECK_STATUS(bpx_world_query_batch(w, queries, Q, offsets, &probe, 1, &total),
                     BPX_ERR_CAPACITY);
        CHECK(probe.id == 12345u && total > 1 && offsets[Q] == total);
        const size_t *kept_offsets;
        uint32_t kept_queries;
        size_t kept_total;
        const bpx_hit *kept = bpx_world_query_hits(w, &kept_offsets, &kept_queries, &kept_total);
        CHECK(kept && kept_queries == Q && kept_total == total);
        bpx_hit *hits = malloc(sizeof(bpx_hit) * (total ? total : 1));
        CHECK_STATUS(bpx_world_query_batch(w, queries, Q, offsets, hits, total, &total), BPX_OK);
        CHECK(kept && memcmp(kept, hits, sizeof(bpx_hit) * total) == 0);
        if (!first_hits) {
            first_offsets = offsets;
            first_hits = hits;
            first_total = total;
            for (int k = 0; k < Q; k += 7) { // each query alone gives its slice
                size_t got = 0;
                CHECK_STATUS(bpx_world_query(w, &queries[k], got_buf, buf_cap, &got), BPX_OK);
                CHECK(got == offsets[k + 1] - offsets[k] &&
                      memcmp(got_buf, hits + offsets[k], sizeof(bpx_hit) * got) == 0);
            }
        } else {
            CHECK(total == first_total &&
                  memcmp(offsets, first_offsets, sizeof(size_t) * (Q + 1)) == 0 &&
                  memcmp(hits, first_hits, sizeof(bpx_hit) * total) == 0);
            free(offsets);
            free(hits);
        }
        bpx_world_destroy(w);
    }
    free(first_offsets);
    free(first_hits);
    free(queries);
    free(boxes);
}

// Bad queries: refused with a status naming the query and axis; nothing written.
static void test_errors(void)
{
    check_set_context("errors");
    bpx_box boxes[3] = {{{0, 0, 0}, {1, 1, 1}}, {{2, 0, 0}, {3, 1, 1}}, {{0, 2, 0}, {1, 3, 1}}};
    bpx_world *w = make_world(1);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 3), BPX_OK);
    float o[3] = {0.5f, 0.5f, -5.0f}, d[3] = {0, 0, 1}, zero[3] = {0, 0, 0};
    struct {
        bpx_query q;
        bpx_status want;
        uint32_t index;
        int axis;
    } bad[] = {
        {bpx_query_ray((float[3]){NAN, 0, 0}, d, 1, true), BPX_ERR_NOT_FINITE, 0, 0},
        {bpx_query_ray(o, (float[3]){0, INFINITY, 0}, 1, true), BPX_ERR_NOT_FINITE, 0, 1},
        {bpx_query_ray(o, zero, 1.0f, true), BPX_ERR_INVALID_ARGUMENT, 0, -1},
        {bpx_query_ray(o, d, -1.0f, true), BPX_ERR_INVALID_ARGUMENT, 0, -1},
        {bpx_query_ray(o, d, NAN, false), BPX_ERR_NOT_FINITE, 0, -1},
        {bpx_query_sphere(o, -1.0f), BPX_ERR_INVALID_ARGUMENT, 0, -1},
        {bpx_query_sphere(o, NAN), BPX_ERR_NOT_FINITE, 0, -1},
        {bpx_query_sphere((float[3]){0, 0, -INFINITY}, 1), BPX_ERR_NOT_FINITE, 0, 2},
        {bpx_query_box((bpx_box){{0, 2, 0}, {1, 1, 1}}), BPX_ERR_MIN_GREATER_THAN_MAX, 0, 1},
        {bpx_query_box((bpx_box){{0, 0, 0}, {1, 1, NAN}}), BPX_ERR_NOT_FINITE, 0, 2},
        {bpx_query_sweep((bpx_box){{1, 0, 0}, {0, 1, 1}}, d, 1, true),
         BPX_ERR_MIN_GREATER_THAN_MAX, 0, 0},
        {bpx_query_sweep(boxes[0], zero, 2.0f, true), BPX_ERR_INVALID_ARGUMENT, 0, -1},
    };
    bpx_query unknown = bpx_query_box(boxes[0]);
    unknown.kind = BPX_QUERY_KIND_COUNT;
    size_t count = 77;
    bpx_hit hit = {999, 9.0f};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        check_set_context("errors case %zu", k);
        CHECK_STATUS(bpx_world_query(w, &bad[k].q, &hit, 1, &count), bad[k].want);
        CHECK(count == 77 && hit.id == 999);
        const bpx_error *e = bpx_world_error(w);
        CHECK(e->index == bad[k].index && e->axis == bad[k].axis && strstr(e->message, "query 0"));
    }
    CHECK_STATUS(bpx_world_query(w, &unknown, &hit, 1, &count), BPX_ERR_INVALID_ARGUMENT);
    // In a batch the error names the bad query's position.
    bpx_query batch[3] = {bpx_query_box(boxes[0]), bpx_query_box(boxes[1]), bad[0].q};
    size_t offsets[4] = {5, 5, 5, 5}, total = 0;
    CHECK_STATUS(bpx_world_query_batch(w, batch, 3, offsets, &hit, 1, &total), BPX_ERR_NOT_FINITE);
    CHECK(bpx_world_error(w)->index == 2 && offsets[0] == 5 && strstr(bpx_world_error(w)->message,
                                                                       "query 2"));
    CHECK_STATUS(bpx_world_query(NULL, &batch[0], &hit, 1, &count), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_world_query(w, NULL, &hit, 1, &count), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_world_query(w, &batch[0], NULL, 1, &count), BPX_ERR_NULL_ARGUMENT);
    // A zero-length ray with a zero direction is a point query; a closest ray from inside box 0
    // hits it at 0.
    CHECK_STATUS(bpx_world_query(w, &(bpx_query){.kind = BPX_QUERY_RAY,
                                                 .filter = bpx_default_query_filter(),
                                                 .origin = {0.5f, 0.5f, 0.5f}},
                                 &hit, 1, &count),
                 BPX_OK);
    CHECK(count == 1 && hit.id == 0 && hit.fraction == 0.0f);
    bpx_query ray = bpx_query_ray(o, d, INFINITY, true);
    CHECK_STATUS(bpx_world_query(w, &ray, &hit, 1, &count), BPX_OK);
    CHECK(count == 1 && hit.id == 0 && hit.fraction == 5.0f);
    bpx_world_destroy(w);
}

// The read-only calls' rules: prepared or BAD_STATE; closest with any refused; CAPACITY with the
// count; a callback that stops; user data; a callback that changes the world gets BAD_STATE and
// the walk goes on unharmed.
typedef struct meddler {
    bpx_world *world;
    bpx_status set, query, collide;
    int calls;
} meddler;

static float meddle(const bpx_hit *hit, uint64_t user_data, void *context)
{
    (void)hit, (void)user_data;
    meddler *m = context;
    bpx_box b = {{0, 0, 0}, {1, 1, 1}};
    size_t count;
    m->set = bpx_world_set_boxes(m->world, &b, 1);
    m->query = bpx_world_query(m->world, &(bpx_query){.kind = BPX_QUERY_BOX, .box = b,
                                                     .filter = bpx_default_query_filter()},
                               NULL, 0, &count);
    m->collide = bpx_world_collide(m->world);
    m->calls++;
    return INFINITY;
}

static float stop_at_first(const bpx_hit *hit, uint64_t user_data, void *context)
{
    (void)hit, (void)user_data;
    ++*(int *)context;
    return 0.0f;
}

static void test_read_only_rules(void)
{
    check_set_context("read-only rules");
    bpx_box boxes[4] = {{{0, 0, 0}, {1, 1, 1}}, {{2, 0, 0}, {3, 1, 1}}, {{4, 0, 0}, {5, 1, 1}},
                        {{0.5f, 0, 0}, {2.5f, 1, 1}}};
    bpx_world *w = make_world(1);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 4), BPX_OK);
    bpx_query region = bpx_query_box((bpx_box){{0, 0, 0}, {5, 1, 1}});
    bpx_hit hits[4];
    size_t count = 0;
    bpx_error err;
    CHECK_STATUS(bpx_world_query_shared(w, &region, hits, 4, &count, &err), BPX_ERR_BAD_STATE);
    CHECK(strstr(err.message, "prepare_queries") != NULL);
    CHECK_STATUS(bpx_world_prepare_queries(w), BPX_OK);
    CHECK_STATUS(bpx_world_query_shared(w, &region, hits, 4, &count, &err), BPX_OK);
    CHECK(count == 4 && hits[0].id == 0 && hits[3].id == 3);
    CHECK_STATUS(bpx_world_query_shared(w, &region, hits, 2, &count, NULL), BPX_ERR_CAPACITY);
    CHECK(count == 4);
    bpx_query both = bpx_query_ray((float[3]){-1, 0.5f, 0.5f}, (float[3]){1, 0, 0}, 10, true);
    both.any = true;
    CHECK_STATUS(bpx_world_query_shared(w, &both, hits, 4, &count, &err),
                 BPX_ERR_INVALID_ARGUMENT);
    CHECK_STATUS(bpx_world_query(w, &both, hits, 4, &count), BPX_ERR_INVALID_ARGUMENT);
    both.any = false;
    int calls = 0;
    CHECK_STATUS(bpx_world_query_each(w, &both, stop_at_first, &calls, &err),
                 BPX_ERR_INVALID_ARGUMENT); // closest: the callback decides
    both.closest = false;
    CHECK_STATUS(bpx_world_query_each(w, &both, stop_at_first, &calls, &err), BPX_OK);
    CHECK(calls == 1);
    CHECK_STATUS(bpx_world_query_each(w, &both, NULL, NULL, &err), BPX_ERR_NULL_ARGUMENT);

    uint64_t data[4] = {10, 11, 12, 13};
    CHECK_STATUS(bpx_world_set_user_data(w, NULL, data, 4), BPX_OK);
    collected c = {hits, 0, 4, true, data, {UINT32_MAX, INFINITY}};
    CHECK_STATUS(bpx_world_query_each(w, &region, collect, &c, NULL), BPX_OK);
    CHECK(c.count == 4 && c.user_data_ok);

    meddler m = {w, BPX_OK, BPX_OK, BPX_OK, 0};
    CHECK_STATUS(bpx_world_query_each(w, &region, meddle, &m, NULL), BPX_OK);
    CHECK(m.calls == 4 && m.set == BPX_ERR_BAD_STATE && m.query == BPX_ERR_BAD_STATE &&
          m.collide == BPX_ERR_BAD_STATE);
    CHECK(bpx_world_box_count(w) == 4); // unchanged
    CHECK_STATUS(bpx_world_query_shared(w, &region, hits, 4, &count, NULL), BPX_OK);
    CHECK(count == 4);

    // A change makes the tree stale until the next prepare (or bpx_world_query).
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, 3), BPX_OK);
    CHECK_STATUS(bpx_world_query_shared(w, &region, hits, 4, &count, NULL), BPX_ERR_BAD_STATE);
    CHECK_STATUS(bpx_world_query_each(w, &region, collect, &c, NULL), BPX_ERR_BAD_STATE);
    CHECK_STATUS(bpx_world_prepare_queries(w), BPX_OK);
    CHECK_STATUS(bpx_world_query_shared(w, &region, hits, 4, &count, NULL), BPX_OK);
    CHECK(count == 3);
    bpx_world_destroy(w);
}

// Oriented boxes: with the identity and a quarter turn they are box queries of known bounds
// (the same hits); with random rotations, against a separating-axis test written from the
// boxes' corners (another formulation: projections of 8 corners on each of the 15 axes), which
// must agree except within a hair of touching; the any, shared and callback forms follow; and
// bad ones are refused. Points are box queries of a point.
static void random_rotation(scene_rng *r, float m[9])
{
    // A unit quaternion from four normal-ish draws, then its matrix (row-major).
    double q[4], len = 0.0;
    for (int k = 0; k < 4; k++) {
        q[k] = scene_rng_range(r, -1.0f, 1.0f);
        len += q[k] * q[k];
    }
    len = sqrt(len);
    double w = q[0] / len, x = q[1] / len, y = q[2] / len, z = q[3] / len;
    double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
                   2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                   2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
    for (int k = 0; k < 9; k++)
        m[k] = (float)R[k];
}

// The corners' separating-axis test; *slack receives how near the decision was (the least
// |gap| over the axes, relative to the boxes' size), so that a disagreement can be judged.
static bool corners_meet(const bpx_query *q, const bpx_box *b, double *slack)
{
    double qc[8][3], bc[8][3], axes[15][3];
    for (int k = 0; k < 8; k++)
        for (int a = 0; a < 3; a++) {
            double v = q->centre[a];
            for (int j = 0; j < 3; j++)
                v += q->rotation[3 * a + j] * ((k >> j) & 1 ? 1.0 : -1.0) * q->half_extents[j];
            qc[k][a] = v;
            bc[k][a] = (k >> a) & 1 ? b->max[a] : b->min[a];
        }
    for (int i = 0; i < 3; i++)
        for (int a = 0; a < 3; a++) {
            axes[i][a] = i == a;
            axes[3 + i][a] = q->rotation[3 * a + i];
        }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            const double *u = axes[i], *v = axes[3 + j];
            double *c = axes[6 + 3 * i + j];
            c[0] = u[1] * v[2] - u[2] * v[1];
            c[1] = u[2] * v[0] - u[0] * v[2];
            c[2] = u[0] * v[1] - u[1] * v[0];
        }
    bool meet = true;
    *slack = INFINITY;
    for (int l = 0; l < 15; l++) {
        double n = sqrt(axes[l][0] * axes[l][0] + axes[l][1] * axes[l][1] + axes[l][2] * axes[l][2]);
        if (n < 1e-9)
            continue;
        double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
        for (int k = 0; k < 8; k++) {
            double pq = (qc[k][0] * axes[l][0] + qc[k][1] * axes[l][1] + qc[k][2] * axes[l][2]) / n;
            double pb = (bc[k][0] * axes[l][0] + bc[k][1] * axes[l][1] + bc[k][2] * axes[l][2]) / n;
            lo[0] = fmin(lo[0], pq), hi[0] = fmax(hi[0], pq);
            lo[1] = fmin(lo[1], pb), hi[1] = fmax(hi[1], pb);
        }
        double gap = fmax(lo[1] - hi[0], lo[0] - hi[1]); // > 0: separated
        *slack = fmin(*slack, fabs(gap));
        if (gap > 0)
            meet = false;
    }
    return meet;
}

static void test_oriented(void)
{
    check_set_context("oriented boxes");
    enum { n = 3000 };
    bpx_box *boxes = malloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 2.0f, 17, boxes);
    bpx_world *w = make_world(1);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_prepare_queries(w), BPX_OK);
    scene_rng r;
    scene_rng_seed(&r, 23);
    static const float identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    static const float quarter[9] = {0, -1, 0, 1, 0, 0, 0, 0, 1}; // a quarter turn about z
    size_t got = 0, want = 0, near = 0, hits_total = 0;
    for (int k = 0; k < 400; k++) {
        const bpx_box *b = &boxes[scene_rng_below(&r, n)];
        // Centres and half extents in quarters, so that centre +- half is exact in float.
        float c[3], h[3];
        for (int a = 0; a < 3; a++) {
            c[a] = (float)(int)(b->min[a] * 4.0f) * 0.25f;
            h[a] = (float)(1 + scene_rng_below(&r, 12)) * 0.25f;
        }
        int form = k % 3;
        bpx_query q = bpx_query_oriented(c, h, form == 0 ? identity : form == 1 ? quarter : identity);
        if (form == 2)
            random_rotation(&r, q.rotation);
        CHECK_STATUS(bpx_world_query(w, &q, got_buf, buf_cap, &got), BPX_OK);
        hits_total += got;
        if (form < 2) { // the same as the box query of its bounds
            float reach[3] = {form ? h[1] : h[0], form ? h[0] : h[1], h[2]};
            bpx_box bounds;
            for (int a = 0; a < 3; a++)
                bounds.min[a] = c[a] - reach[a], bounds.max[a] = c[a] + reach[a];
            bpx_query box = bpx_query_box(bounds);
            CHECK_STATUS(bpx_world_query(w, &box, expect_buf, buf_cap, &want), BPX_OK);
            CHECK_MSG(got == want && memcmp(got_buf, expect_buf, sizeof(bpx_hit) * got) == 0,
                      "oriented %d (form %d): %zu hits, box query %zu", k, form, got, want);
        } else { // against the corners' test over every box
            size_t g = 0;
            for (uint32_t i = 0; i < n; i++) {
                double slack;
                bool meet = corners_meet(&q, &boxes[i], &slack);
                bool listed = g < got && got_buf[g].id == i;
                g += listed;
                if (meet != listed) {
                    near++;
                    CHECK_MSG(slack < 1e-4, "oriented %d: box %u %s, the corners' test says %s "
                              "(slack %g)", k, i, listed ? "hit" : "missed",
                              meet ? "meet" : "apart", slack);
                }
            }
            CHECK(g == got);
        }
        // The read-only forms give the same (and any gives one of them).
        size_t shared = 0;
        CHECK_STATUS(bpx_world_query_shared(w, &q, expect_buf, buf_cap, &shared, NULL), BPX_OK);
        CHECK(shared == got && memcmp(expect_buf, got_buf, sizeof(bpx_hit) * got) == 0);
        q.any = true;
        size_t one = 0;
        CHECK_STATUS(bpx_world_query(w, &q, expect_buf, buf_cap, &one), BPX_OK);
        CHECK(one == (got > 0));
    }
    CHECK(hits_total > 400); // the scene is dense enough to test something
    CHECK(near <= 2);        // disagreements only a hair from touching, and rare
    // Points: the boxes that contain the point.
    float point[3] = {boxes[0].min[0], boxes[0].min[1], boxes[0].max[2]};
    bpx_query pq = bpx_query_point(point);
    CHECK_STATUS(bpx_world_query(w, &pq, got_buf, buf_cap, &got), BPX_OK);
    bool has0 = false;
    for (size_t k = 0; k < got; k++)
        has0 |= got_buf[k].id == 0;
    CHECK(has0); // a corner of box 0 is in box 0 (closed)
    // Bad oriented boxes.
    float c[3] = {0, 0, 0}, h[3] = {1, 1, 1}, skew[9] = {1, 0.1f, 0, 0, 1, 0, 0, 0, 1};
    bpx_query bad = bpx_query_oriented(c, h, skew);
    CHECK_STATUS(bpx_world_query(w, &bad, got_buf, buf_cap, &got), BPX_ERR_INVALID_ARGUMENT);
    CHECK(strstr(bpx_world_error(w)->message, "orthonormal") != NULL);
    float negative[3] = {1, -1, 1};
    bad = bpx_query_oriented(c, negative, identity);
    CHECK_STATUS(bpx_world_query(w, &bad, got_buf, buf_cap, &got), BPX_ERR_INVALID_ARGUMENT);
    CHECK(bpx_world_error(w)->axis == 1);
    float nan_centre[3] = {0, NAN, 0};
    bad = bpx_query_oriented(nan_centre, h, identity);
    CHECK_STATUS(bpx_world_query(w, &bad, got_buf, buf_cap, &got), BPX_ERR_NOT_FINITE);
    bpx_world_destroy(w);
    free(boxes);
}

// Allocation failure: OUT_OF_MEMORY, nothing leaked, and the next query works.
static int64_t fail_after = -1;
static void *failing_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    if (fail_after == 0)
        return NULL;
    if (fail_after > 0)
        fail_after--;
    return aligned_alloc(alignment, size);
}
static void plain_free(void *memory, void *user)
{
    (void)user;
    free(memory);
}

static void test_out_of_memory(void)
{
    check_set_context("out of memory");
    bpx_set_allocator(failing_alloc, plain_free, NULL);
    enum { N = 3000 };
    bpx_box *boxes = malloc(sizeof(bpx_box) * N);
    scene_uniform_density(N, 1.0f, 3, boxes);
    world_copy copy = {boxes, N, NULL, NULL, NULL};
    bpx_query q = bpx_query_box((bpx_box){{-1e9f, -1e9f, -1e9f}, {1e9f, 1e9f, 1e9f}});
    int failures = 0;
    for (int64_t after = 0; after < 40; after++) {
        fail_after = -1;
        bpx_world *w = make_world(1);
        CHECK_STATUS(bpx_world_set_boxes(w, boxes, N), BPX_OK);
        int64_t before = bpx_allocated_bytes();
        fail_after = after;
        size_t count = 0;
        bpx_status s = bpx_world_query(w, &q, got_buf, buf_cap, &count);
        fail_after = -1;
        if (s != BPX_OK) {
            failures++;
            CHECK_STATUS(s, BPX_ERR_OUT_OF_MEMORY);
        }
        CHECK(bpx_allocated_bytes() >= before);
        compare_one(w, &copy, &q, (int)after);
        bpx_world_destroy(w);
    }
    CHECK(failures > 0);
    bpx_set_allocator(NULL, NULL, NULL);
    free(boxes);
}

int main(void)
{
    buf_cap = 1u << 20;
    expect_buf = malloc(sizeof(bpx_hit) * buf_cap);
    got_buf = malloc(sizeof(bpx_hit) * buf_cap);
    all_buf = malloc(sizeof(bpx_hit) * buf_cap);
    int64_t start = bpx_allocated_bytes();
    test_scenes(BPX_SIMD_AUTO);
    if (bpx_simd_best() == BPX_SIMD_AVX512 && bpx_simd_supported(BPX_SIMD_AVX2))
        test_scenes(BPX_SIMD_AVX2);
    test_scenes(BPX_SIMD_SCALAR);
    test_parallel_tree(false);
    test_parallel_tree(true);
    test_adversarial_rays();
    test_objects_and_moves();
    test_centres();
    test_batches();
    test_errors();
    test_read_only_rules();
    test_oriented();
    test_out_of_memory();
    CHECK_EQ_U64((uint64_t)bpx_allocated_bytes(), (uint64_t)start);
    free(expect_buf);
    free(got_buf);
    free(all_buf);
    return check_finish("test_query", 1);
}
