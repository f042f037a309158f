// The sap backend (src/cpu/sap/) over long incremental sequences, every cycle against the
// reference backend, byte for byte: coherent motion, sudden jumps, boxes passing through each
// other, many boxes sharing one x, everything overlapping, touching faces that part and meet
// again by one ulp (-0.0, subnormals, +-FLT_MAX included), n changing between cycles, objects
// added and removed, and allocation failure at every allocation of such a sequence. Checks
// bpx_cycle_stats.rebuilt against sap's documented rules: cold on the first cycle, when n
// shrank or grew by more than an eighth, and when the boxes moved too far to mend; warm
// otherwise.
#include <float.h>
#include <math.h>
#include <stdatomic.h>
#include <time.h>

#include "cpu/kernels.h"
#include "pairs_util.h"
#include "scenes.h"

typedef struct duo {
    bpx_world *sap;
    bpx_world *ref;
    pair_list want;
    int cycles;
    int cold;
} duo;

static double now_s(void)
{
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static bpx_simd forced_simd = BPX_SIMD_AUTO; // the rebuild's sweep kernel, for sap worlds

static bpx_world *make_world(bpx_backend backend, int workers, bool events)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.simd = backend == BPX_BACKEND_SAP ? forced_simd : BPX_SIMD_AUTO;
    def.worker_count = workers;
    def.track_events = events;
    bpx_world *w = NULL;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    return w;
}

static void duo_init(duo *d, int workers)
{
    *d = (duo){0};
    d->sap = make_world(BPX_BACKEND_SAP, workers, true);
    d->ref = make_world(BPX_BACKEND_REFERENCE, 1, false);
}

// The same for tens of thousands of boxes, where the reference's n^2 / 2 tests would take
// seconds a cycle: prune (itself checked against the reference by test_differential) checks.
static void duo_init_large(duo *d, int workers)
{
    *d = (duo){0};
    d->sap = make_world(BPX_BACKEND_SAP, workers, true);
    d->ref = make_world(BPX_BACKEND_PRUNE, 1, false);
}

static void duo_free(duo *d)
{
    bpx_world_destroy(d->sap);
    bpx_world_destroy(d->ref);
    pair_list_free(&d->want);
}

// Collides both worlds (boxes already given to both) and compares; returns sap's cold flag.
static bool duo_collide(duo *d)
{
    CHECK_STATUS(bpx_world_collide(d->ref), BPX_OK);
    CHECK_STATUS(bpx_world_collide(d->sap), BPX_OK);
    size_t want_count = 0, got_count = 0;
    const bpx_pair *want = bpx_world_pairs(d->ref, &want_count);
    const bpx_pair *got = bpx_world_pairs(d->sap, &got_count);
    CHECK_PAIRS_EQ(want, want_count, got, got_count);
    bpx_cycle_stats stats = bpx_world_stats(d->sap);
    CHECK_EQ_U64(stats.pair_count, want_count);
    CHECK(!bpx_world_stats(d->ref).rebuilt); // other backends never set it
    pair_list_set(&d->want, want, want_count);
    d->cycles++;
    d->cold += stats.rebuilt;
    return stats.rebuilt;
}

// One cycle of boxes through set_boxes.
static bool duo_step(duo *d, const bpx_box *boxes, uint32_t n)
{
    CHECK_STATUS(bpx_world_set_boxes(d->ref, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_set_boxes(d->sap, boxes, n), BPX_OK);
    return duo_collide(d);
}

// A cycle whose cold flag is known.
#define STEP_EXPECT(d, boxes, n, cold, what)                                                      \
    do {                                                                                           \
        bool got_cold_ = duo_step((d), (boxes), (n));                                              \
        CHECK_MSG(got_cold_ == (cold), "%s: rebuilt=%d, want %d", (what), (int)got_cold_,         \
                  (int)(cold));                                                                    \
    } while (0)

// Fisher-Yates: box slots change owners, so every box jumps somewhere else.
static void shuffle(bpx_box *boxes, uint32_t n, scene_rng *r)
{
    for (uint32_t i = n; i > 1; i--) {
        uint32_t j = scene_rng_below(r, i);
        bpx_box t = boxes[i - 1];
        boxes[i - 1] = boxes[j];
        boxes[j] = t;
    }
}

// Box 0 made 16 times as wide on every axis: its extents are then far from the mean, so sap
// mends its endpoint lists rather than the scan list (which wants even extents).
static void widen_one(bpx_box *boxes)
{
    for (int a = 0; a < 3; a++) {
        float centre = 0.5f * (boxes[0].min[a] + boxes[0].max[a]);
        float half = 8.0f * (boxes[0].max[a] - boxes[0].min[a]);
        boxes[0].min[a] = centre - half;
        boxes[0].max[a] = centre + half;
    }
}

// ---------------------------------------------------------------------------------------------

// Coherent motion for long stretches, with a sudden jump (a shuffle) now and then: cold on the
// first cycle and on each jump, warm on every other.
static void test_coherent_and_jumps(int workers, bool wide)
{
    enum { n = 1500, cycles = 60, jump_every = 20 };
    const uint64_t seed = 11;
    check_set_seed(seed);
    duo d;
    duo_init(&d, workers);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 1.0f, seed, boxes);
    if (wide)
        widen_one(boxes);
    scene_rng r;
    scene_rng_seed(&r, seed);
    for (int cycle = 0; cycle < cycles; cycle++) {
        check_set_context("coherent n=%d workers=%d wide=%d cycle=%d", n, workers, wide, cycle);
        bool jump = cycle > 0 && cycle % jump_every == 0;
        if (jump)
            shuffle(boxes, n, &r);
        else if (cycle > 0)
            scene_move(boxes, n, 0.02f, &r);
        STEP_EXPECT(&d, boxes, n, cycle == 0 || jump, jump ? "jump" : "coherent");
    }
    // Incoherent motion (every box jumps each cycle): after two give-ups in a row, sap tries
    // mending once in 8 cycles only (so cycles 2..8 rebuild and 9 tries, and gives up).
    for (int cycle = 0; cycle < 20; cycle++) {
        check_set_context("jumps n=%d workers=%d cycle=%d", n, workers, cycle);
        shuffle(boxes, n, &r);
        duo_step(&d, boxes, n);
    }
    // Larger steps: correct whatever the mending budget decides.
    for (int cycle = 0; cycle < 20; cycle++) {
        check_set_context("step 0.5 n=%d workers=%d cycle=%d", n, workers, cycle);
        scene_move(boxes, n, 0.5f, &r);
        duo_step(&d, boxes, n);
    }
    // The same boxes again: nothing moves, nothing to mend. After a run of give-ups sap
    // rebuilds without trying for up to 7 cycles, then mends again.
    int cold = 0;
    for (int cycle = 0; cycle < 10; cycle++) {
        check_set_context("unchanged n=%d workers=%d cycle=%d", n, workers, cycle);
        bool rebuilt = duo_step(&d, boxes, n);
        cold += rebuilt;
        CHECK_MSG(!rebuilt || cold == cycle + 1, "a rebuild after mending resumed");
    }
    CHECK_MSG(cold <= 7, "%d of 10 unchanged cycles rebuilt", cold);
    free(boxes);
    duo_free(&d);
}

// Two rows of boxes passing through each other along x, in a band that y and z partly share:
// pairs begin and end every cycle, all by mending.
static void test_passing_rows(void)
{
    enum { n = 400, cycles = 120 };
    duo d;
    duo_init(&d, 1);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_rng r;
    scene_rng_seed(&r, 21);
    check_set_seed(21);
    for (uint32_t i = 0; i < n; i++) {
        float x = (float)(i / 2) * 1.3f + (i % 2 ? 40.0f : 0.0f);
        float y = scene_rng_range(&r, 0.0f, 3.0f), z = scene_rng_range(&r, 0.0f, 3.0f);
        boxes[i] = (bpx_box){{x, y, z}, {x + 1.0f, y + 1.0f, z + 1.0f}};
    }
    for (int cycle = 0; cycle < cycles; cycle++) {
        check_set_context("passing rows cycle=%d", cycle);
        for (uint32_t i = 0; i < n && cycle > 0; i++) {
            float dx = i % 2 ? -0.25f : 0.25f;
            boxes[i].min[0] += dx;
            boxes[i].max[0] += dx;
        }
        STEP_EXPECT(&d, boxes, n, cycle == 0, "passing rows");
    }
    CHECK(d.want.count > 0);
    free(boxes);
    duo_free(&d);
}

// Many boxes share one x interval (and some share y too): the sweep's worst case on x. The
// rebuild sweeps the axis whose intervals overlap least; moving in y and z only, the x list
// needs no mending at all.
static void test_shared_coordinates(void)
{
    enum { n = 1500, cycles = 40 };
    duo d;
    duo_init(&d, 2);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_rng r;
    scene_rng_seed(&r, 31);
    check_set_seed(31);
    for (uint32_t i = 0; i < n; i++) {
        float y = scene_rng_range(&r, 0.0f, 40.0f), z = scene_rng_range(&r, 0.0f, 40.0f);
        float x0 = 0.0f, x1 = 1.0f;
        if (i % 10 == 1)
            x1 = 0.0f; // a plane at x = 0
        else if (i % 10 == 2)
            x0 = 1.0f; // a plane at x = 1: touches every other box there
        if (i % 3 == 0)
            y = 5.0f; // a third also share one y interval
        boxes[i] = (bpx_box){{x0, y, z}, {x1, y + 1.0f, z + 1.0f}};
    }
    for (int cycle = 0; cycle < cycles; cycle++) {
        check_set_context("shared x cycle=%d", cycle);
        for (uint32_t i = 0; i < n && cycle > 0; i++) {
            for (int a = 1; a < 3; a++) {
                float step = scene_rng_range(&r, -0.05f, 0.05f);
                if (a == 1 && i % 3 == 0)
                    continue; // the shared y stays shared
                boxes[i].min[a] += step;
                boxes[i].max[a] += step;
            }
        }
        STEP_EXPECT(&d, boxes, n, cycle == 0, "shared x");
    }
    // Everyone on one x and one y interval: only z tells boxes apart.
    for (uint32_t i = 0; i < n; i++) {
        boxes[i].min[0] = boxes[i].min[1] = 0.0f;
        boxes[i].max[0] = boxes[i].max[1] = 1.0f;
    }
    check_set_context("shared x and y");
    duo_step(&d, boxes, n);
    CHECK(d.want.count > 0);
    free(boxes);
    duo_free(&d);
}

// Every box overlaps every other (n(n-1)/2 pairs), and keeps doing so while it moves.
static void test_all_overlap(void)
{
    enum { n = 300, cycles = 30 };
    duo d;
    duo_init(&d, 1);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    CHECK(scene_generate(SCENE_ALL_OVERLAP, n, 41, boxes) == 0);
    float common[3]; // a point every box contains: the largest minimum
    for (int a = 0; a < 3; a++) {
        common[a] = boxes[0].min[a];
        for (uint32_t i = 1; i < n; i++)
            common[a] = boxes[i].min[a] > common[a] ? boxes[i].min[a] : common[a];
    }
    scene_rng r;
    scene_rng_seed(&r, 41);
    check_set_seed(41);
    for (int cycle = 0; cycle < cycles; cycle++) {
        check_set_context("all overlap cycle=%d", cycle);
        for (uint32_t i = 0; i < n && cycle > 0; i++)
            for (int a = 0; a < 3; a++) { // grow or shrink a little, never past the common point
                float lo = boxes[i].min[a] - scene_rng_range(&r, -0.01f, 0.01f);
                float hi = boxes[i].max[a] + scene_rng_range(&r, -0.01f, 0.01f);
                boxes[i].min[a] = lo < common[a] ? lo : common[a];
                boxes[i].max[a] = hi > common[a] ? hi : common[a];
            }
        STEP_EXPECT(&d, boxes, n, cycle == 0, "all overlap");
        CHECK_EQ_U64(d.want.count, (uint64_t)n * (n - 1) / 2);
    }
    free(boxes);
    duo_free(&d);
}

// Moves a box one ulp up or down on one axis (min and max together, so it stays valid; never
// past +-FLT_MAX), and sometimes flips the sign of a zero bound.
static void ulp_nudge(bpx_box *b, scene_rng *r)
{
    int a = (int)scene_rng_below(r, 3);
    float toward = scene_rng_below(r, 2) ? FLT_MAX : -FLT_MAX;
    b->min[a] = nextafterf(b->min[a], toward);
    b->max[a] = nextafterf(b->max[a], toward);
    for (int k = 0; k < 3; k++) {
        if (b->min[k] == 0.0f && scene_rng_below(r, 2))
            b->min[k] = -b->min[k];
        if (b->max[k] == 0.0f && scene_rng_below(r, 2))
            b->max[k] = -b->max[k];
    }
}

// Touching faces part by one ulp and meet again, on the scenes made of exact touches and
// edge-case floats; all by mending.
static void test_ulp_steps(void)
{
    static const scene_kind kinds[] = {SCENE_TOUCHING,  SCENE_SIGNED_ZERO, SCENE_DENORMAL,
                                       SCENE_HUGE_TINY, SCENE_ZERO_EXTENT, SCENE_IDENTICAL,
                                       SCENE_SHARED_COORD};
    enum { n = 1000, cycles = 30 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    bpx_box *start = check_alloc(sizeof(bpx_box) * n);
    for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++) {
        duo d;
        duo_init(&d, 1);
        uint64_t seed = 50 + k;
        check_set_seed(seed);
        CHECK(scene_generate(kinds[k], n, seed, boxes) == 0);
        memcpy(start, boxes, sizeof(bpx_box) * n);
        scene_rng r;
        scene_rng_seed(&r, seed);
        pair_list before = {0};
        int changed = 0;
        for (int cycle = 0; cycle < cycles; cycle++) {
            check_set_context("ulp steps scene=%s cycle=%d", scene_kind_name(kinds[k]), cycle);
            bool restore = cycle > 0 && cycle % 10 == 0;
            if (restore) {
                // Every nudged box back at once: mended or rebuilt, as the budget decides
                // (on the lattice, a box one ulp off passes every endpoint sharing its key).
                memcpy(boxes, start, sizeof(bpx_box) * n);
                duo_step(&d, boxes, n);
            } else {
                for (uint32_t i = 0; i < n && cycle > 0; i++)
                    if (scene_rng_below(&r, 32) == 0)
                        ulp_nudge(&boxes[i], &r);
                duo_step(&d, boxes, n);
            }
            changed += cycle > 0 && (d.want.count != before.count ||
                                     memcmp(d.want.pairs, before.pairs,
                                            sizeof(bpx_pair) * before.count) != 0);
            pair_list_set(&before, d.want.pairs, d.want.count);
        }
        printf("    %-14s %3zu pairs, set changed in %d of %d cycles, %d rebuilt\n",
               scene_kind_name(kinds[k]), d.want.count, changed, cycles - 1, d.cold);
        // Mending must be what runs here (a rebuild would prove little about it), though
        // where many endpoints share one key a one-ulp step passes them all and may cost a
        // rebuild; and where boxes touch exactly, one ulp makes and breaks pairs.
        CHECK_MSG(d.cold <= cycles / 4, "%d of %d cycles rebuilt", d.cold, cycles);
        if (kinds[k] == SCENE_TOUCHING || kinds[k] == SCENE_DENORMAL ||
            kinds[k] == SCENE_ZERO_EXTENT)
            CHECK_MSG(changed > cycles / 2, "pair set changed in %d cycles", changed);
        pair_list_free(&before);
        duo_free(&d);
    }
    free(boxes);
    free(start);
}

// Faces that touch exactly at the floats' edges — +-FLT_MAX, -0.0 against +0.0, a subnormal —
// and part by one ulp, box by box, every cycle. Groups of six boxes share a cell in y and z
// (cells apart): three end at the group's site on x, three start there. Left boxes always
// pair with each other, right ones too, and a left with a right exactly when both touch.
// Each cycle an eighth of the boxes switch between touching and one ulp apart.
static void test_extreme_touches(void)
{
    enum { groups = 100, n = 6 * groups, cycles = 40 };
    const float sites[4] = {-FLT_MAX, 0.0f, 3 * FLT_TRUE_MIN, FLT_MAX};
    bool touching[n];
    duo d;
    duo_init(&d, 1);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_rng r;
    scene_rng_seed(&r, 91);
    check_set_seed(91);
    for (int cycle = 0; cycle < cycles; cycle++) {
        check_set_context("extreme touches cycle=%d", cycle);
        for (uint32_t i = 0; i < n; i++) {
            uint32_t g = i / 6;
            float site = sites[g % 4];
            bool left = i % 6 < 3;
            if (cycle == 0 || scene_rng_below(&r, 8) == 0)
                touching[i] = cycle == 0 || !touching[i];
            bool touch = touching[i];
            float y = (float)(g % 10) * 3.0f, z = (float)(g / 10) * 3.0f;
            bpx_box b = {{0, y, z}, {0, y + 1.0f, z + 1.0f}};
            if (site == FLT_MAX) { // only the left side can step back
                b.min[0] = left ? 1e38f : FLT_MAX;
                b.max[0] = left && !touch ? nextafterf(FLT_MAX, 0.0f) : FLT_MAX;
            } else if (site == -FLT_MAX) { // only the right side can step forward
                b.min[0] = !left && !touch ? nextafterf(-FLT_MAX, 0.0f) : -FLT_MAX;
                b.max[0] = left ? -FLT_MAX : -1e38f;
            } else {
                float edge = touch ? site : nextafterf(site, left ? -FLT_MAX : FLT_MAX);
                if (edge == 0.0f && scene_rng_below(&r, 2))
                    edge = -edge; // -0.0 touches +0.0
                b.min[0] = left ? site - 1.0f : edge;
                b.max[0] = left ? edge : site + 1.0f;
            }
            boxes[i] = b;
        }
        duo_step(&d, boxes, n);
    }
    printf("    %d cycles, %d rebuilt, %zu pairs in the last\n", cycles, d.cold, d.want.count);
    CHECK_MSG(d.cold <= cycles / 4, "%d of %d cycles rebuilt", d.cold, cycles);
    free(boxes);
    duo_free(&d);
}

// n grows and shrinks between cycles: a few new boxes mend in; many (more than an eighth) or
// any shrink rebuild; so does growth that needs too many moves.
static void test_changing_n(void)
{
    enum { max_n = 2700 };
    duo d;
    duo_init(&d, 3);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * max_n);
    scene_uniform_density(max_n, 1.0f, 61, boxes);
    scene_rng r;
    scene_rng_seed(&r, 61);
    check_set_seed(61);
    static const struct {
        uint32_t n;
        bool cold;
        const char *what;
    } plan[] = {
        {2000, true, "first"},           {2000, false, "same n"},
        {2002, false, "2 more"},         {2003, false, "1 more"},
        {2004, false, "1 more"},         {2003, true, "1 fewer"},
        {2003, false, "same n"},         {2400, true, "+397 > n/8"},
        {2400, false, "same n"},         {2700, true, "+300: too many moves"},
        {2700, false, "same n"},         {1, true, "1 box"},
        {1, false, "same n"},            {0, true, "no boxes"},
        {0, false, "still none"},        {1, true, "0 -> 1"},
        {2, true, "1 -> 2: more than an eighth"},
    };
    for (size_t k = 0; k < sizeof plan / sizeof plan[0]; k++) {
        check_set_context("changing n: step %zu, n=%u (%s)", k, plan[k].n, plan[k].what);
        scene_move(boxes, max_n, 0.01f, &r);
        STEP_EXPECT(&d, boxes, plan[k].n, plan[k].cold, plan[k].what);
    }
    // And a long run of small growth with motion, all mended.
    uint32_t n = 2000;
    duo_step(&d, boxes, n);
    for (int cycle = 0; cycle < 40; cycle++) {
        check_set_context("slow growth cycle=%d n=%u", cycle, n);
        n += cycle % 3 == 0;
        scene_move(boxes, max_n, 0.01f, &r);
        STEP_EXPECT(&d, boxes, n, false, "slow growth");
    }
    free(boxes);
    duo_free(&d);
}

// A scene at rest (every box shifts by at most 0.001, inside its fat box) where a few boxes jump
// a box width each cycle, then an eighth of them a fifth of that, then all of them a box width:
// the lists mend box by box, then all at once, then (within budget or not); every cycle exact.
static void test_resting_with_jumps_of(bool wide)
{
    enum { n = 3000, cycles = 36 };
    duo d;
    duo_init(&d, 1);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 1.0f, 101, boxes);
    if (wide)
        widen_one(boxes);
    scene_rng r;
    scene_rng_seed(&r, 101);
    check_set_seed(101);
    for (int cycle = 0; cycle < cycles; cycle++) {
        check_set_context("resting with jumps wide=%d cycle=%d", wide, cycle);
        uint32_t jumping = cycle < 12 ? 5 : cycle < 24 ? n / 8 : n;
        scene_move(boxes, n, 0.001f, &r);
        for (uint32_t k = 0; k < jumping && cycle > 0; k++) {
            uint32_t i = jumping == n ? k : scene_rng_below(&r, n);
            for (int a = 0; a < 3; a++) {
                float reach = jumping == 5 ? 1.0f : 0.2f; // within the move budget
                float step = scene_rng_range(&r, -reach, reach);
                boxes[i].min[a] += step;
                boxes[i].max[a] += step;
            }
        }
        bool cold = duo_step(&d, boxes, n);
        if (cycle > 0 && cycle < 24)
            CHECK_MSG(!cold, "%u boxes jumping: rebuilt", jumping);
    }
    CHECK(d.want.count > 0);
    free(boxes);
    duo_free(&d);
}

// Both mends: the scan list (even extents), the endpoint lists (one box 16 times as wide).
static void test_resting_with_jumps(void)
{
    test_resting_with_jumps_of(false);
    test_resting_with_jumps_of(true);
}

// Many boxes, dense: the rebuild finds its fat pairs with the grid (a sweep on the best axis
// would meet more than BPX_SWEEP_MAX_CANDIDATES boxes per box), and from 16384 boxes the warm
// cycle's check, filter and one-pass mend run on the workers. Checked against prune (itself
// checked against the reference by test_differential; the reference would take seconds here).
static void test_many_boxes(int workers)
{
    enum { n = 20000, cycles = 40 };
    const uint64_t seed = 121;
    check_set_seed(seed);
    duo d = {0};
    d.sap = make_world(BPX_BACKEND_SAP, workers, true);
    d.ref = make_world(BPX_BACKEND_PRUNE, 1, false);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 4.0f, seed, boxes);
    scene_rng r;
    scene_rng_seed(&r, seed);
    for (int cycle = 0; cycle < cycles; cycle++) {
        check_set_context("many boxes workers=%d cycle=%d", workers, cycle);
        // Slow drift (boxes leave their fat boxes a few, then many, at a time), a jump (cold:
        // the grid), faster drift (the one-pass mend, or give-ups).
        if (cycle == 25)
            shuffle(boxes, n, &r);
        else if (cycle > 0)
            scene_move(boxes, n, cycle < 25 ? 0.01f : 0.05f, &r);
        bool cold = duo_step(&d, boxes, n);
        if (cycle == 0 || cycle == 25)
            CHECK_MSG(cold, "cycle %d: not rebuilt", cycle);
        else if (cycle < 25)
            CHECK_MSG(!cold, "coherent cycle %d: rebuilt", cycle);
    }
    // Boxes at the ends of the float range among the many (the mean extent is then ~1e34, so
    // the fat margins fall back to 0): rebuilt, then drifting.
    const float big = FLT_MAX;
    boxes[0] = (bpx_box){{-big, -big, -big}, {-big / 2, -big / 2, -big / 2}};
    boxes[1] = (bpx_box){{big / 2, big / 2, big / 2}, {big, big, big}};
    boxes[2] = (bpx_box){{-big, -big, -big}, {big, big, big}};
    boxes[3] = (bpx_box){{big, big, big}, {big, big, big}};
    shuffle(boxes, n, &r);
    for (int cycle = 0; cycle < 6; cycle++) {
        check_set_context("many boxes, float range's ends, workers=%d cycle=%d", workers, cycle);
        if (cycle > 0)
            scene_move(boxes, n, 0.01f, &r);
        duo_step(&d, boxes, n);
    }
    CHECK(d.want.count > (uint64_t)n);
    free(boxes);
    duo_free(&d);
}

// Past 65536 boxes a rebuild's endpoint lists (2n words each, over 1 MiB) take the streamed
// radix sort, the three at once on two workers, and the fat pairs come from the grid (dense:
// its input copied on the workers) or from a sweep (sparse); the lists' index waits for the
// first mend. A few boxes moving past their fat boxes (the few-boxes mend, through that index),
// a jump (a rebuild), then a few again.
static void test_large_rebuilds(float overlaps_per_box)
{
    enum { n = 70000, cycles = 9, jump = 5 };
    const uint64_t seed = 131;
    check_set_seed(seed);
    duo d;
    duo_init_large(&d, 2);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, overlaps_per_box, seed, boxes);
    scene_rng r;
    scene_rng_seed(&r, seed);
    for (int cycle = 0; cycle < cycles; cycle++) {
        check_set_context("large rebuilds, %g overlaps per box, cycle=%d", (double)overlaps_per_box,
                          cycle);
        if (cycle == jump) {
            shuffle(boxes, n, &r);
        } else if (cycle > 0) {
            for (uint32_t k = 0; k < 40; k++) { // 40 boxes, each a third of its size along x
                bpx_box *b = &boxes[scene_rng_below(&r, n)];
                b->min[0] += 0.3f;
                b->max[0] += 0.3f;
            }
        }
        STEP_EXPECT(&d, boxes, n, cycle == 0 || cycle == jump, "large rebuilds");
    }
    free(boxes);
    duo_free(&d);
}

// Moves `count` boxes (from `first` on, every third) along x by `dx`.
static void nudge(bpx_box *boxes, uint32_t first, uint32_t count, float dx)
{
    for (uint32_t k = 0; k < count; k++) {
        boxes[first + 3 * k].min[0] += dx;
        boxes[first + 3 * k].max[0] += dx;
    }
}

// Dense boxes, past 65536: the grid finds the fat pairs, and a rebuild after the first keeps
// that choice and leaves the endpoint lists unmade until a warm cycle must mend or grow. Cycles
// with nothing to mend stay warm without them; a few boxes leaving their fat boxes (or one box
// added) make them first; more than the fewest moves expected allow, or many boxes added,
// rebuild untried. sap's counters tell the lists made and the untried give-ups apart from the
// rest. Quiet cycles between give-ups, so that none counts as incoherent motion.
static void test_lists_on_demand(void)
{
    enum { n = 70000, grow = 11 };
    const uint64_t seed = 151;
    check_set_seed(seed);
    duo d;
    duo_init_large(&d, 2);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * (n + grow));
    scene_uniform_density(n + grow, 1.0f, seed, boxes);
    scene_rng r;
    scene_rng_seed(&r, seed);
    // FEW: 40 boxes leave (the few-boxes mend); PAST_FEW: 1200, just more than n / 64 + 16 (the
    // one-pass mend, whose list for x runs out of moves); MANY: 5000 (past even the fewest moves
    // expected). Each a third of a box along x, past the fat margin (a sixteenth).
    enum { STILL, SHUFFLE, FEW, PAST_FEW, MANY, GROW_10, GROW_1 };
    const struct {
        int what;
        bool cold;
        uint32_t lists, untried; // made, and given up untried, this cycle
        const char *name;
    } steps[] = {
        {STILL, true, 1, 0, "first"},
        {SHUFFLE, true, 0, 0, "jump: the grid kept, no lists"},
        {STILL, false, 0, 0, "still, no lists"},
        {FEW, false, 1, 0, "few leave: lists made"},
        {SHUFFLE, true, 0, 0, "jump again"},
        {STILL, false, 0, 0, "still"},
        {MANY, true, 0, 1, "many leave: rebuilt untried"},
        {STILL, false, 0, 0, "still"},
        {PAST_FEW, true, 1, 0, "more than few leave: lists made, the mend gives up"},
        {STILL, false, 0, 0, "still"},
        {GROW_10, true, 0, 1, "ten added: rebuilt untried"},
        {FEW, false, 1, 0, "few leave after growth"},
        {SHUFFLE, true, 0, 0, "jump"},
        {STILL, false, 0, 0, "still"},
        {GROW_1, false, 1, 0, "one added: lists made, mended"},
        {STILL, false, 0, 0, "still, lists made"},
    };
    uint32_t count = n;
    bpx_sap_counters before = bpx__sap_counters(d.sap);
    for (size_t k = 0; k < sizeof steps / sizeof steps[0]; k++) {
        check_set_context("lists on demand, step %zu: %s", k, steps[k].name);
        int what = steps[k].what;
        if (what == SHUFFLE)
            shuffle(boxes, count, &r);
        else if (what == FEW || what == PAST_FEW || what == MANY)
            nudge(boxes, (uint32_t)k, what == FEW ? 40 : what == PAST_FEW ? 1200 : 5000, 0.3f);
        else if (what == GROW_10 || what == GROW_1)
            count += what == GROW_10 ? 10 : 1;
        STEP_EXPECT(&d, boxes, count, steps[k].cold, steps[k].name);
        bpx_sap_counters now = bpx__sap_counters(d.sap);
        CHECK_MSG(now.lists_made - before.lists_made == steps[k].lists, "lists made: %u, want %u",
                  now.lists_made - before.lists_made, steps[k].lists);
        CHECK_MSG(now.untried - before.untried == steps[k].untried, "untried: %u, want %u",
                  now.untried - before.untried, steps[k].untried);
        before = now;
    }
    free(boxes);
    duo_free(&d);
}

// The one-pass mend right after a rebuild, before any mend has made where (the changed boxes'
// words found by a pass over each list), then the few-boxes mend (which makes where), then the
// one-pass mend again (through where). Endpoint lists (one wide box), two workers.
static void test_one_pass_after_rebuild(void)
{
    enum { n = 20000 };
    const uint64_t seed = 141;
    check_set_seed(seed);
    duo d;
    duo_init_large(&d, 2);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 1.0f, seed, boxes);
    widen_one(boxes);
    // A box leaves its fat box past a margin of 1/16 of the mean extent (about 1 here); 0.3 is
    // past what the fat boxes' margins cover, so pairs begin and end.
    const struct {
        uint32_t first, count;
        float dx;
        const char *what;
    } steps[] = {{0, 0, 0.0f, "rebuild"},
                 {1, 400, 0.3f, "one pass, before where"},
                 {2, 10, 0.3f, "few boxes, making where"},
                 {1, 400, -0.3f, "one pass, through where"},
                 {2, 10, -0.3f, "few boxes again"}};
    // With the first one-pass mend, the lowest changed box (1) also jumps onto a box near it on
    // x that it did not overlap, and back with the second: pairs that only its words can show.
    uint32_t near = 2;
    while (near < n && (fabsf(boxes[near].min[0] - boxes[1].min[0]) > 2.0f ||
                        bpx_overlap(&boxes[near], &boxes[1])))
        near++;
    CHECK(near < n);
    const bpx_box home = boxes[1];
    for (size_t k = 0; k < sizeof steps / sizeof steps[0] && near < n; k++) {
        check_set_context("one pass after rebuild: %s", steps[k].what);
        nudge(boxes, steps[k].first, steps[k].count, steps[k].dx);
        if (k == 1 || k == 3) // after nudge: the jump is the box's whole move this cycle
            boxes[1] = k == 1 ? boxes[near] : home;
        STEP_EXPECT(&d, boxes, n, k == 0, steps[k].what);
    }
    free(boxes);
    duo_free(&d);
}

static bool pair_less(bpx_pair a, bpx_pair b)
{
    return a.i < b.i || (a.i == b.i && a.j < b.j);
}

// a - b for sorted lists.
static void difference(const pair_list *a, const pair_list *b, pair_list *out)
{
    pair_list_reserve(out, a->count);
    out->count = 0;
    size_t j = 0;
    for (size_t k = 0; k < a->count; k++) {
        while (j < b->count && pair_less(b->pairs[j], a->pairs[k]))
            j++;
        if (!(j < b->count && !pair_less(a->pairs[k], b->pairs[j])))
            out->pairs[out->count++] = a->pairs[k];
    }
}

// Objects added, removed and moved through the object API, in the same order on both worlds,
// with events on sap; one removal and one addition a cycle stay within the mending budget.
static void test_objects(void)
{
    // Ids: n at first; a freed id comes back only after the collide that reports its pairs
    // ended, so the first addition takes a new id, and later ones the id freed a cycle before.
    enum { n = 1500, max_ids = n + 2, cycles = 60 };
    duo d;
    duo_init(&d, 1);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * max_ids);
    scene_uniform_density(max_ids, 1.0f, 71, boxes);
    scene_rng r;
    scene_rng_seed(&r, 71);
    check_set_seed(71);
    uint32_t *ids = check_alloc(sizeof(uint32_t) * max_ids);
    uint32_t *ref_ids = check_alloc(sizeof(uint32_t) * max_ids);
    bool live[max_ids] = {false};
    uint32_t used = n; // ids handed out so far
    CHECK_STATUS(bpx_world_add_boxes(d.sap, boxes, n, ids), BPX_OK);
    CHECK_STATUS(bpx_world_add_boxes(d.ref, boxes, n, ref_ids), BPX_OK);
    for (uint32_t i = 0; i < n; i++)
        live[i] = true;
    pair_list previous = {0}, began = {0}, ended = {0};
    for (int cycle = 0; cycle < cycles; cycle++) {
        check_set_context("objects cycle=%d", cycle);
        if (cycle > 0) {
            // Remove one live box, add one.
            uint32_t gone = scene_rng_below(&r, used);
            while (!live[gone])
                gone = (gone + 1) % used;
            CHECK_STATUS(bpx_world_remove_boxes(d.sap, &gone, 1), BPX_OK);
            CHECK_STATUS(bpx_world_remove_boxes(d.ref, &gone, 1), BPX_OK);
            live[gone] = false;
            bpx_box fresh = boxes[scene_rng_below(&r, used)];
            uint32_t id = 0, ref_id = 0;
            CHECK_STATUS(bpx_world_add_boxes(d.sap, &fresh, 1, &id), BPX_OK);
            CHECK_STATUS(bpx_world_add_boxes(d.ref, &fresh, 1, &ref_id), BPX_OK);
            CHECK(id == ref_id && id < max_ids && !live[id]);
            if (id >= max_ids)
                break;
            live[id] = true;
            boxes[id] = fresh;
            used = id + 1 > used ? id + 1 : used;
            // Move every live box a little.
            uint32_t count = 0;
            for (uint32_t i = 0; i < used; i++)
                if (live[i]) {
                    for (int a = 0; a < 3; a++) {
                        float step = scene_rng_range(&r, -0.02f, 0.02f);
                        boxes[i].min[a] += step;
                        boxes[i].max[a] += step;
                    }
                    ids[count] = ref_ids[count] = i;
                    count++;
                }
            bpx_box *moved = check_alloc(sizeof(bpx_box) * (count ? count : 1));
            for (uint32_t k = 0; k < count; k++)
                moved[k] = boxes[ids[k]];
            CHECK_STATUS(bpx_world_move_boxes(d.sap, ids, moved, count), BPX_OK);
            CHECK_STATUS(bpx_world_move_boxes(d.ref, ref_ids, moved, count), BPX_OK);
            free(moved);
        }
        bool cold = duo_collide(&d);
        CHECK_MSG(cold == (cycle == 0), "rebuilt=%d", (int)cold);
        // Events: the difference of consecutive pair sets.
        bpx_pair_events ev;
        CHECK_STATUS(bpx_world_pair_events(d.sap, &ev), BPX_OK);
        difference(&d.want, &previous, &began);
        difference(&previous, &d.want, &ended);
        CHECK_PAIRS_EQ(began.pairs, began.count, ev.began, ev.began_count);
        CHECK_PAIRS_EQ(ended.pairs, ended.count, ev.ended, ev.ended_count);
        pair_list_set(&previous, d.want.pairs, d.want.count);
    }
    pair_list_free(&previous);
    pair_list_free(&began);
    pair_list_free(&ended);
    free(ids);
    free(ref_ids);
    free(boxes);
    duo_free(&d);
}

// ---------------------------------------------------------------------------------------------
// Allocation failure: the k-th allocation fails, for every k a sequence makes (cold cycles, warm
// cycles, growth, shrinking). Each call returns OK or OUT_OF_MEMORY, a failed collide is followed
// by correct ones once memory is back, and nothing leaks.

static atomic_llong fail_budget; // allocations left before failing; negative: unlimited
static int fail_tag;

static void *fail_alloc(size_t size, size_t alignment, void *user)
{
    if (user != &fail_tag)
        return NULL;
    if (atomic_load(&fail_budget) >= 0 && atomic_fetch_sub(&fail_budget, 1) <= 0)
        return NULL;
    return aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
}

static void fail_free(void *memory, void *user)
{
    (void)user;
    free(memory);
}

// A sequence of cycles: cycle k's boxes (`stride` apart) are a coherent move of cycle k-1's
// (warm), n changes at steps 2 (growth, still warm) and 4 (shrinking: a rebuild).
enum { ALLOC_STEPS = 6 };
typedef struct alloc_case {
    const char *name;
    uint32_t sizes[ALLOC_STEPS];
    uint32_t stride;
    float density; // overlaps per box
    int workers;
} alloc_case;

// One sequence with the first `budget` allocations succeeding; true when nothing failed.
static bool failing_run(long long budget, const alloc_case *c, const bpx_box *boxes,
                        const pair_list *wants)
{
    const uint32_t *sizes = c->sizes;
    enum { steps = ALLOC_STEPS };
    atomic_store(&fail_budget, budget);
    bool all_ok = true;
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_SAP;
    def.track_events = true;
    def.worker_count = c->workers;
    bpx_world *w = NULL;
    bpx_status s = bpx_world_create(&def, &w);
    CHECK(s == BPX_OK || s == BPX_ERR_OUT_OF_MEMORY);
    if (s != BPX_OK)
        return false;
    for (int k = 0; k < steps; k++) {
        const bpx_box *cycle_boxes = boxes + (size_t)k * c->stride;
        s = bpx_world_set_boxes(w, cycle_boxes, sizes[k]);
        CHECK_MSG(s == BPX_OK || s == BPX_ERR_OUT_OF_MEMORY, "step %d set_boxes: %s", k,
                  check_status_name(s));
        all_ok &= s == BPX_OK;
        if (s != BPX_OK)
            continue;
        s = bpx_world_collide(w);
        CHECK_MSG(s == BPX_OK || s == BPX_ERR_OUT_OF_MEMORY, "step %d collide: %s", k,
                  check_status_name(s));
        all_ok &= s == BPX_OK;
        if (s == BPX_OK) {
            size_t count = 0;
            const bpx_pair *pairs = bpx_world_pairs(w, &count);
            CHECK_PAIRS_EQ(wants[k].pairs, wants[k].count, pairs, count);
        }
    }
    // Memory back: the world recovers on the next cycles.
    atomic_store(&fail_budget, -1);
    for (int k = steps - 2; k < steps; k++) {
        CHECK_STATUS(bpx_world_set_boxes(w, boxes + (size_t)k * c->stride, sizes[k]), BPX_OK);
        CHECK_STATUS(bpx_world_collide(w), BPX_OK);
        size_t count = 0;
        const bpx_pair *pairs = bpx_world_pairs(w, &count);
        CHECK_PAIRS_EQ(wants[k].pairs, wants[k].count, pairs, count);
    }
    bpx_world_destroy(w);
    return all_ok;
}

// The expected pairs by prune (checked against the reference by test_differential).
static void pairs_by_prune(pair_list *out, const bpx_box *boxes, uint32_t n)
{
    bpx_world *w = make_world(BPX_BACKEND_PRUNE, 1, false);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    size_t count = 0;
    const bpx_pair *pairs = bpx_world_pairs(w, &count);
    pair_list_set(out, pairs, count);
    bpx_world_destroy(w);
}

static void allocation_failure(const alloc_case *c)
{
    enum { steps = ALLOC_STEPS };
    const uint32_t stride = c->stride;
    const uint32_t *sizes = c->sizes;
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * stride * steps);
    scene_uniform_density(stride, c->density, 81, boxes);
    scene_rng r;
    scene_rng_seed(&r, 81);
    check_set_seed(81);
    pair_list wants[steps] = {{0}};
    for (int k = 0; k < steps; k++) {
        if (k > 0) {
            memcpy(boxes + (size_t)k * stride, boxes + (size_t)(k - 1) * stride,
                   sizeof(bpx_box) * stride);
            scene_move(boxes + (size_t)k * stride, stride, 0.02f, &r);
        }
        pairs_by_prune(&wants[k], boxes + (size_t)k * stride, sizes[k]);
    }
    int64_t start = bpx_allocated_bytes();
    bpx_set_allocator(fail_alloc, fail_free, &fail_tag);
    long long budget = 0;
    for (; budget < 10000; budget++) {
        check_set_context("allocation failure (%s) after %lld allocations", c->name, budget);
        bool done = failing_run(budget, c, boxes, wants);
        CHECK_MSG(bpx_allocated_bytes() == start, "allocated %lld bytes, started at %lld",
                  (long long)bpx_allocated_bytes(), (long long)start);
        if (done)
            break;
    }
    bpx_set_allocator(NULL, NULL, NULL);
    printf("  allocation failure, %s: a full run needs %lld allocations; every shorter budget "
           "failed cleanly\n",
           c->name, budget);
    CHECK(budget > 5 && budget < 10000);
    for (int k = 0; k < steps; k++)
        pair_list_free(&wants[k]);
    free(boxes);
}

static void test_allocation_failure(void)
{
    static const alloc_case cases[] = {
        {"400 boxes", {400, 400, 402, 402, 300, 300}, 410, 1.0f, 1},
        // Dense and many: rebuilds by the grid, warm passes on 2 workers (and their threads).
        {"17000 boxes, 2 workers",
         {17000, 17000, 17002, 17002, 16500, 16500},
         17010,
         4.0f,
         2},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++)
        allocation_failure(&cases[k]);
}

int main(void)
{
    if (!bpx_backend_query(BPX_BACKEND_SAP).available) {
        return check_finish("test_sap", 0);
    }
    double t0 = now_s();
    printf("test_sap: seeds 11..81 (fixed); %s\n", bpx_backend_query(BPX_BACKEND_SAP).detail);
    struct {
        const char *name;
        void (*run)(void);
    } tests[] = {
        {"passing rows", test_passing_rows},   {"shared coordinates", test_shared_coordinates},
        {"all overlap", test_all_overlap},     {"ulp steps", test_ulp_steps},
        {"extreme touches", test_extreme_touches},
        {"changing n", test_changing_n},       {"objects", test_objects},
        {"resting with jumps", test_resting_with_jumps},
        {"allocation failure", test_allocation_failure},
    };
    // Quick (BPX_TEST_QUICK, the tsan preset): the runs on more than one worker, and no
    // allocation failure or scalar sweep, which run on one thread.
    int first_workers = check_quick() ? 2 : 1;
    for (int workers = first_workers == 2 ? 3 : 1; workers <= 3; workers += 2)
        for (int wide = 0; wide < 2; wide++) {
            double t = now_s();
            test_coherent_and_jumps(workers, wide);
            printf("  coherent and jumps, %d worker(s)%s: %.2f s\n", workers,
                   wide ? ", one wide box" : "", now_s() - t);
        }
    for (int workers = first_workers; workers <= 2; workers++) {
        double t = now_s();
        test_many_boxes(workers);
        printf("  many boxes, %d worker(s): %.2f s\n", workers, now_s() - t);
    }
    test_one_pass_after_rebuild();
    double t_large = now_s();
    test_large_rebuilds(1.0f);  // dense: the grid finds the fat pairs
    test_large_rebuilds(0.02f); // sparse: one sweep does
    test_lists_on_demand();
    printf("  large rebuilds, 2 workers: %.2f s\n", now_s() - t_large);
    // The rebuild sweeps with the prune kernel of the world's SIMD width: the narrowest too.
    if (!check_quick()) {
        forced_simd = BPX_SIMD_SCALAR;
        double t_scalar = now_s();
        test_changing_n();
        test_shared_coordinates();
        printf("  changing n + shared coordinates, scalar sweep: %.2f s\n",
               now_s() - t_scalar);
        forced_simd = BPX_SIMD_AUTO;
    }
    for (size_t k = 0; k < sizeof tests / sizeof tests[0]; k++) {
        if (check_quick() && tests[k].run == test_allocation_failure) {
            continue;
        }
        double t = now_s();
        tests[k].run();
        printf("  %-20s %.2f s\n", tests[k].name, now_s() - t);
        fflush(stdout);
    }
    printf("total %.2f s\n", now_s() - t0);
    return check_finish("test_sap", 1);
}
