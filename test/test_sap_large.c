// The sap backend (src/cpu/sap/) at tens of thousands of boxes, every cycle against prune (itself
// checked against the reference by test_differential): warm cycles on the workers, rebuilds by
// the grid and by a sweep, the endpoint lists made on demand (sap's counters, src/cpu/backends.h)
// and the one-pass mend after a rebuild; and allocation failure at every allocation of a sequence
// of cold and warm cycles. The incremental sequences at small n: test_sap.c.
#include <float.h>
#include <math.h>
#include <stdatomic.h>

#include "cpu/backends.h"
#include "sap_util.h"

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
    // More than a handful, so that failures in several places were met (400 boxes: 4, since
    // a box set is one allocation, not six: e9734b8).
    CHECK(budget > 3 && budget < 10000);
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

// A few boxes far larger than the rest (the denormal scene: 3% span the whole subnormal lattice
// on one axis; huge_tiny: boxes 2^40 apart in size) must not make every pair of fat boxes
// overlap: sap and auto (sap from its second resting cycle) on 20,000 boxes, every block under
// 256 MiB (the fat pairs of margins from the mean extent took 6 GB there), against prune.
static _Atomic size_t big_blocks;

// The span of the boxes' coordinates on `axis`.
static float want_span(const bpx_box *boxes, uint32_t n, int axis)
{
    float lo = INFINITY, hi = -INFINITY;
    for (uint32_t i = 0; i < n; i++) {
        lo = boxes[i].min[axis] < lo ? boxes[i].min[axis] : lo;
        hi = boxes[i].max[axis] > hi ? boxes[i].max[axis] : hi;
    }
    return hi - lo;
}

static void *small_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    if (size >= (size_t)256 << 20) {
        big_blocks++;
        return NULL;
    }
    return aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
}

static void small_free(void *memory, void *user)
{
    (void)user;
    free(memory);
}

static void test_extreme_size_mix(void)
{
    enum { n = 20000 };
    const scene_kind kinds[] = {SCENE_DENORMAL, SCENE_HUGE_TINY};
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    pair_list want = {0};
    for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++) {
        CHECK(scene_generate(kinds[k], n, 5, boxes) == 0);
        pairs_by_prune(&want, boxes, n);
        bpx_set_allocator(small_alloc, small_free, NULL);
        const bpx_backend backends[] = {BPX_BACKEND_SAP, BPX_BACKEND_AUTO};
        for (size_t b = 0; b < 2; b++) {
            check_set_context("%s, %s", scene_kind_name(kinds[k]), bpx_backend_name(backends[b]));
            bpx_world *w = make_world(backends[b], 2, false);
            for (int cycle = 0; cycle < 3; cycle++) {
                CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
                CHECK_STATUS(bpx_world_collide(w), BPX_OK);
                size_t count = 0;
                const bpx_pair *pairs = bpx_world_pairs(w, &count);
                CHECK_MSG(count == want.count &&
                              pairs_first_diff(pairs, count, want.pairs, want.count) == count,
                          "cycle %d: %zu pairs, want %zu", cycle, count, want.count);
            }
            if (backends[b] == BPX_BACKEND_AUTO)
                CHECK(bpx_world_backend(w) == BPX_BACKEND_SAP); // resting: sap's scene
            else
                for (int a = 0; a < 3; a++) // the typical box's scale, not the huge ones'
                    CHECK_MSG(bpx__sap_counters(w).margin[a] <= 1e-3f * want_span(boxes, n, a),
                              "axis %d: margin %g", a, (double)bpx__sap_counters(w).margin[a]);
            bpx_world_destroy(w);
        }
        bpx_set_allocator(NULL, NULL, NULL);
        CHECK_MSG(big_blocks == 0, "%zu blocks of 256 MiB or more asked for", (size_t)big_blocks);
    }
    pair_list_free(&want);
    free(boxes);
}

// Mostly points (particles): four in five boxes, then points and unit boxes taking turns by
// index (a layout a strided sample would see only one kind of). The margins' bound samples only
// boxes with an extent, so the margins stay the mean extent / 16 (a bound from the points' zero
// extents would make them 0, and every moving box would leave its fat box every cycle).
static void test_points_keep_their_margin(void)
{
    enum { n = 20000, cycles = 10 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    pair_list want = {0};
    for (int layout = 0; layout < 2; layout++) {
        check_set_context("points, layout %d", layout);
        scene_rng r;
        scene_rng_seed(&r, 17);
        for (uint32_t i = 0; i < n; i++) {
            bool point = layout ? i % 2 == 0 : scene_rng_below(&r, 5) != 0;
            for (int a = 0; a < 3; a++) {
                float c = (float)scene_rng_below(&r, 50000) / 1000.0f; // a 50-wide cube
                boxes[i].min[a] = point ? c : c - 0.5f;
                boxes[i].max[a] = point ? c : c + 0.5f;
            }
        }
        bpx_world *w = make_world(BPX_BACKEND_SAP, 1, false);
        int rebuilt = 0;
        for (int cycle = 0; cycle < cycles; cycle++) {
            for (uint32_t i = 0; i < n; i++) { // a fraction of the margin per cycle
                boxes[i].min[0] += 0.0005f;
                boxes[i].max[0] += 0.0005f;
            }
            pairs_by_prune(&want, boxes, n);
            CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
            CHECK_STATUS(bpx_world_collide(w), BPX_OK);
            size_t count = 0;
            const bpx_pair *pairs = bpx_world_pairs(w, &count);
            CHECK(count == want.count &&
                  pairs_first_diff(pairs, count, want.pairs, want.count) == count);
            rebuilt += bpx_world_stats(w).rebuilt;
        }
        CHECK_MSG(rebuilt == 1, "%d of %d cycles rebuilt", rebuilt, cycles);
        double sum[3] = {0, 0, 0};
        for (uint32_t i = 0; i < n; i++)
            for (int a = 0; a < 3; a++)
                sum[a] += (double)boxes[i].max[a] - (double)boxes[i].min[a];
        bpx_sap_counters c = bpx__sap_counters(w);
        for (int a = 0; a < 3; a++) // moved since the rebuild, the boxes kept their sizes
            CHECK_MSG(fabs(c.margin[a] - sum[a] / n / 16) < 1e-3 * sum[a] / n,
                      "axis %d: margin %g, mean extent / 16 %g", a, (double)c.margin[a],
                      sum[a] / n / 16);
        bpx_world_destroy(w);
    }
    pair_list_free(&want);
    free(boxes);
}

int main(void)
{
    if (!bpx_backend_query(BPX_BACKEND_SAP).available) {
        return check_finish("test_sap_large", 0);
    }
    double t0 = now_s();
    printf("test_sap_large: seeds 81..151 (fixed); %s\n",
           bpx_backend_query(BPX_BACKEND_SAP).detail);
    // Quick (BPX_TEST_QUICK, the tsan preset): the runs on more than one worker only.
    for (int workers = check_quick() ? 2 : 1; workers <= 2; workers++) {
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
    double t_mix = now_s();
    test_extreme_size_mix();
    test_points_keep_their_margin();
    printf("  extreme size mix:   %.2f s\n", now_s() - t_mix);
    double t = now_s();
    if (!check_quick())
        test_allocation_failure();
    printf("  %-20s %.2f s\n", "allocation failure", now_s() - t);
    printf("total %.2f s\n", now_s() - t0);
    return check_finish("test_sap_large", 1);
}
