// The hybrid backend (src/hybrid/): the CPU and a device (opencl on PoCL in CI) share each cycle.
// Every scene kind with the device's share forced from a sliver to everything, over moving
// cycles, in both updater modes, with removed objects, filters and events, against Algorithm 1;
// the measured split at a size where it splits; bad shares; allocation failure. Skips (77) where
// no device backend is usable.
#include <math.h>
#include <stdatomic.h>

#include <limits.h>

#include "check.h"
#include "error_util.h"
#include "pairs_util.h"
#include "scenes.h"

// A failing allocator safe across threads: the device side allocates on hybrid's own thread.
static atomic_llong left = -1, live;
static int tag;
static void *counted_alloc(size_t size, size_t alignment, void *user)
{
    if (user != &tag || atomic_fetch_sub(&left, 1) == 0)
        return NULL;
    void *p = aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
    atomic_fetch_add(&live, p != NULL);
    return p;
}
static void counted_free(void *memory, void *user)
{
    (void)user;
    atomic_fetch_sub(&live, memory != NULL);
    free(memory);
}

static bpx_world *hybrid_world(float share, int workers, bool events)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_HYBRID;
    def.hybrid_device_share = share;
    def.worker_count = workers;
    def.track_events = events;
    bpx_world *w = NULL;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    return w;
}

static void check_cycle(bpx_world *w, const bpx_box *boxes, uint32_t n)
{
    size_t want_count = 0;
    bpx_pair *want = check_alloc(sizeof(bpx_pair) * ((size_t)n * n / 2 + 1));
    CHECK_STATUS(bpx_find_pairs(boxes, n, BPX_BACKEND_REFERENCE, want, (size_t)n * n / 2 + 1,
                                &want_count, NULL),
                 BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    size_t count;
    const bpx_pair *got = bpx_world_pairs(w, &count);
    CHECK_MSG(count == want_count && (count == 0 || memcmp(got, want, count * 8) == 0),
              "%zu pairs, want %zu", count, want_count);
    free(want);
}

// Every scene kind, each share, three moving cycles, general and two-phase mode.
static void test_scenes_and_shares(void)
{
    static const float shares[] = {0.01f, 0.3f, 0.7f, 1.0f};
    static const uint32_t sizes[] = {0, 1, 300, 1500};
    // Quick (ThreadSanitizer): the threads meet the same way at any size; one size will do.
    size_t first_size = check_quick() ? 2 : 0, last_size = check_quick() ? 3 : 4;
    for (int kind = 0; kind < SCENE_KIND_COUNT; kind++) {
        for (size_t z = first_size; z < last_size; z++) {
            uint32_t n = sizes[z];
            if (kind == SCENE_ALL_OVERLAP && n > 300)
                continue;
            bpx_box *boxes = check_alloc(sizeof(bpx_box) * (n + 1));
            CHECK(scene_generate((scene_kind)kind, n, 40 + (uint64_t)kind, boxes) == 0);
            for (size_t s = 0; s < sizeof shares / sizeof shares[0]; s++) {
                check_set_context("kind=%s n=%u share=%.2f", scene_kind_name((scene_kind)kind), n,
                                  (double)shares[s]);
                bpx_world *w = hybrid_world(shares[s], (int)(s % 2) + 1, false);
                scene_rng motion;
                scene_rng_seed(&motion, 7);
                for (int c = 0; c < 3 && w; c++) {
                    CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
                    check_cycle(w, boxes, n);
                    if (kind == SCENE_UNIFORM_DENSITY || kind == SCENE_SPARSE ||
                        kind == SCENE_MIXED_SIZES)
                        scene_move(boxes, n, 0.3f, &motion);
                }
                bpx_world_destroy(w);
            }
            free(boxes);
        }
    }
}

// The paper's two-phase updater, removed objects, filters and events through hybrid.
static void test_world_features(void)
{
    uint32_t n = 1200;
    check_set_context("features n=%u", n);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 2.0f, 3, boxes);
    float *minima = check_alloc(sizeof(float) * 3 * n), *centres = check_alloc(sizeof(float) * 3 * n);
    extents_of(boxes, n, minima, centres);
    bpx_world *w = hybrid_world(0.5f, 2, true);
    bpx_world *ref = NULL;
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_REFERENCE;
    def.track_events = true;
    CHECK_STATUS(bpx_world_create(&def, &ref), BPX_OK);
    bpx_world *both[2] = {w, ref};
    for (int k = 0; k < 2 && w; k++) {
        CHECK_STATUS(bpx_world_load_extents(both[k], minima, n), BPX_OK);
        CHECK_STATUS(bpx_world_update_centres(both[k], centres), BPX_OK);
    }
    for (int c = 0; c < 4 && w; c++) {
        for (uint32_t i = 0; i < n; i++)
            centres[3 * i] += 0.05f * (float)((i + (uint32_t)c) % 7) - 0.15f;
        for (int k = 0; k < 2; k++) {
            CHECK_STATUS(bpx_world_update_centres(both[k], centres), BPX_OK);
            CHECK_STATUS(bpx_world_collide(both[k]), BPX_OK);
        }
        size_t a, b;
        const bpx_pair *pa = bpx_world_pairs(w, &a), *pb = bpx_world_pairs(ref, &b);
        CHECK(a == b && (a == 0 || memcmp(pa, pb, a * 8) == 0));
        bpx_pair_events ea, eb;
        CHECK_STATUS(bpx_world_pair_events(w, &ea), BPX_OK);
        CHECK_STATUS(bpx_world_pair_events(ref, &eb), BPX_OK);
        CHECK(ea.began_count == eb.began_count && ea.ended_count == eb.ended_count);
        CHECK(ea.began_count == 0 || memcmp(ea.began, eb.began, ea.began_count * 8) == 0);
        CHECK(ea.ended_count == 0 || memcmp(ea.ended, eb.ended, ea.ended_count * 8) == 0);
        bpx_cycle_stats st = bpx_world_stats(w);
        CHECK(st.device_share > 0.2f && st.device_share < 0.8f);
    }
    // General mode: remove some ids (inert boxes) and filter others.
    for (int k = 0; k < 2 && w; k++) {
        CHECK_STATUS(bpx_world_set_boxes(both[k], boxes, n), BPX_OK);
        uint32_t gone[3] = {5, 77, 600};
        CHECK_STATUS(bpx_world_remove_boxes(both[k], gone, 3), BPX_OK);
        uint32_t ids[4] = {1, 2, 3, 900}, cats[4] = {2, 2, 4, 2}, masks[4] = {4, 4, 2, 0};
        CHECK_STATUS(bpx_world_set_filters(both[k], ids, cats, masks, 4), BPX_OK);
        CHECK_STATUS(bpx_world_collide(both[k]), BPX_OK);
    }
    size_t a, b;
    const bpx_pair *pa = bpx_world_pairs(w, &a), *pb = bpx_world_pairs(ref, &b);
    CHECK(w && a == b && (a == 0 || memcmp(pa, pb, a * 8) == 0));
    bpx_world_destroy(w);
    bpx_world_destroy(ref);
    free(boxes), free(minima), free(centres);
}

// The measured split: above 20,000 boxes both sides work, and the share moves with their speed.
static void test_balanced(void)
{
    uint32_t n = 30000;
    check_set_context("balanced n=%u", n);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 1.0f, 9, boxes);
    bpx_world *w = hybrid_world(0.0f, 2, false);
    scene_rng motion;
    scene_rng_seed(&motion, 9);
    float first = -1.0f;
    for (int c = 0; c < 4 && w; c++) {
        CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
        check_cycle(w, boxes, n);
        float share = bpx_world_stats(w).device_share;
        CHECK_MSG(share > 0.0f && share < 1.0f, "device share %.3f", (double)share);
        if (c == 0)
            first = share;
        scene_move(boxes, n, 0.2f, &motion);
    }
    printf("balanced: device share %.3f in the first cycle, %.3f in the fourth\n", (double)first,
           (double)bpx_world_stats(w).device_share);
    bpx_world_destroy(w);
    free(boxes);
}

// Past 32,768 boxes and pairs per side the split, the corner rule and the merge run in chunks
// on the world's workers: every worker count, shares that leave each side more or less, moving
// boxes and removed ids, against sap (itself checked against the reference elsewhere).
static void test_chunked(void)
{
    uint32_t n = check_quick() ? 70000 : 150000;
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 3.0f, 21, boxes);
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_SAP;
    bpx_world *oracle = NULL;
    CHECK_STATUS(bpx_world_create(&def, &oracle), BPX_OK);
    static const float shares[] = {0.1f, 0.5f, 0.9f};
    static const int workers[] = {1, 2, 3};
    uint32_t gone[4] = {0, 7, n / 2, n - 1};
    for (size_t s = 0; s < sizeof shares / sizeof shares[0] && oracle; s++) {
        int worker_count = workers[s];
        check_set_context("chunked n=%u share=%.1f workers=%d", n, (double)shares[s], worker_count);
        bpx_world *w = hybrid_world(shares[s], worker_count, false);
        scene_rng motion;
        scene_rng_seed(&motion, 5 + s);
        for (int c = 0; c < 3 && w; c++) {
            bpx_world *both[2] = {w, oracle};
            for (int k = 0; k < 2; k++) {
                CHECK_STATUS(bpx_world_set_boxes(both[k], boxes, n), BPX_OK);
                if (c == 2)
                    CHECK_STATUS(bpx_world_remove_boxes(both[k], gone, 4), BPX_OK);
                CHECK_STATUS(bpx_world_collide(both[k]), BPX_OK);
            }
            size_t a, b;
            const bpx_pair *pa = bpx_world_pairs(w, &a), *pb = bpx_world_pairs(oracle, &b);
            CHECK_MSG(a == b && (a == 0 || memcmp(pa, pb, a * 8) == 0), "%zu pairs, want %zu", a,
                      b);
            CHECK_MSG(b > 100000, "%zu pairs: too few for chunks on each side", b);
            scene_move(boxes, n, 0.2f, &motion);
        }
        bpx_world_destroy(w);
    }
    bpx_world_destroy(oracle);
    free(boxes);
}

static void test_errors(void)
{
    check_set_context("errors");
    static const float bad[] = {-0.1f, 1.5f, NAN};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        bpx_world_def def = bpx_default_world_def();
        def.backend = BPX_BACKEND_HYBRID;
        def.hybrid_device_share = bad[k];
        bpx_world *w = (bpx_world *)1;
        CHECK_STATUS(bpx_world_create(&def, &w), BPX_ERR_INVALID_ARGUMENT);
        CHECK(w == NULL);
    }
    // Allocation failing at every point of the first cycle: a status, then a clean recovery.
    uint32_t n = 400;
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 1.0f, 11, boxes);
    int failures = 0;
    // Every failure point of the cycle (a few dozen allocations), until one runs with memory
    // to spare; quick runs (ThreadSanitizer) take every third.
    for (long long budget = 0; budget < 4000; budget += check_quick() ? 3 : 1) {
        bpx_set_allocator(counted_alloc, counted_free, &tag);
        atomic_store(&left, LLONG_MAX);
        bpx_world *w = hybrid_world(0.5f, 1, false);
        if (!w) {
            bpx_set_allocator(NULL, NULL, NULL);
            break;
        }
        CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
        atomic_store(&left, budget);
        bpx_status s = bpx_world_collide(w);
        bool whole = atomic_exchange(&left, LLONG_MAX) >= 0; // no allocation was refused
        CHECK_MSG(ok_or_oom(s) || s == BPX_ERR_DEVICE || s == BPX_ERR_DEVICE_MEMORY, "%s",
                  check_status_name(s));
        failures += s != BPX_OK;
        check_cycle(w, boxes, n); // with memory back, the next cycle is whole
        bpx_world_destroy(w);
        bpx_set_allocator(NULL, NULL, NULL);
        CHECK_EQ_U64(atomic_load(&live), 0);
        if (whole)
            break;
    }
    CHECK(failures > 0);
    free(boxes);
}

int main(void)
{
    bpx_backend_info info = bpx_backend_query(BPX_BACKEND_HYBRID);
    if (!info.available) {
        printf("test_hybrid: SKIPPED (%s)\n", info.reason);
        return CHECK_SKIP;
    }
    printf("hybrid: %s\n", info.detail);
    test_errors();
    test_scenes_and_shares();
    test_world_features();
    test_balanced();
    test_chunked();
    return check_finish("test_hybrid", 1);
}
