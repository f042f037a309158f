// The sap backend (src/cpu/sap/) over long incremental sequences, every cycle against the
// reference backend, byte for byte: coherent motion, sudden jumps, boxes passing through each
// other, many boxes sharing one x, everything overlapping, touching faces that part and meet
// again by one ulp (-0.0, subnormals, +-FLT_MAX included), n changing between cycles, objects
// added and removed. Checks bpx_cycle_stats.rebuilt against sap's documented rules: cold on the
// first cycle, when n shrank or grew by more than an eighth, and when the boxes moved too far to
// mend; warm otherwise. Tens of thousands of boxes and allocation failure: test_sap_large.c.
#include <float.h>
#include <math.h>

#include "sap_util.h"

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

int main(void)
{
    if (!bpx_backend_query(BPX_BACKEND_SAP).available) {
        return check_finish("test_sap", 0);
    }
    double t0 = now_s();
    printf("test_sap: seeds 11..101 (fixed); %s\n", bpx_backend_query(BPX_BACKEND_SAP).detail);
    struct {
        const char *name;
        void (*run)(void);
    } tests[] = {
        {"passing rows", test_passing_rows},   {"shared coordinates", test_shared_coordinates},
        {"all overlap", test_all_overlap},     {"ulp steps", test_ulp_steps},
        {"extreme touches", test_extreme_touches},
        {"changing n", test_changing_n},       {"objects", test_objects},
        {"resting with jumps", test_resting_with_jumps},
    };
    // Quick (BPX_TEST_QUICK, the tsan preset): the runs on more than one worker, and no scalar
    // sweep, which runs on one thread (allocation failure lives in test_sap_large).
    for (int workers = check_quick() ? 3 : 1; workers <= 3; workers += 2)
        for (int wide = 0; wide < 2; wide++) {
            double t = now_s();
            test_coherent_and_jumps(workers, wide);
            printf("  coherent and jumps, %d worker(s)%s: %.2f s\n", workers,
                   wide ? ", one wide box" : "", now_s() - t);
        }
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
        double t = now_s();
        tests[k].run();
        printf("  %-20s %.2f s\n", tests[k].name, now_s() - t);
        fflush(stdout);
    }
    printf("total %.2f s\n", now_s() - t0);
    return check_finish("test_sap", 1);
}
