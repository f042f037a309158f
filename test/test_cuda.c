// The cuda backend's host-out cycles beyond what the suites that loop over every backend check
// (test_differential and test_determinism run it wherever it is available): both comparators
// (brute force up to 1024 boxes, the tree beyond) on every scene kind over moving cycles, against
// prune (itself checked against the reference) and at small n against the reference; the same
// bytes on a second world; removed ids; the calls refused where they do not apply; on the fake
// device, every allocation failing in turn. The device-resident cycles (boxes, centres and pairs
// in device memory) are test_cuda_device.c's.
//
// Without a CUDA device (or without CUDA in the build) the test reports itself skipped (77).
#include <float.h>
#include <math.h>

#include "cuda_util.h"
#include "scenes.h"

#if BPX_TEST_FAKE_CUDA
#include "fake_cuda.h"
#endif

// Every scene kind at sizes around the two paths' border, moving for a few cycles.
// --quick (for compute-sanitizer, which runs kernels tens of times slower): no set past 5000
// boxes, so every path still runs (both comparators, growth, errors) on small sets.
static bool quick;

static void test_scenes(void)
{
    static const uint32_t sizes[] = {0, 1, 2, 3, 31, 500, 1024, 1025, 3000, 20000, 120000};
    bpx_world *cuda = cuda_world(false);
    for (int kind = 0; kind < SCENE_KIND_COUNT; kind++) {
        for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
            uint32_t n = sizes[s];
            if ((kind == SCENE_ALL_OVERLAP || quick) && n > 3000)
                continue;
            // Quadratic scenes stop at 20000 (13M and 7M pairs): at 120000 dense has 481M
            // and huge_tiny 231M, minutes of the oracle's time and ~50 GB of host memory out of
            // a lent GPU's few minutes, for no path that 20000 does not take.
            if ((kind == SCENE_DENSE || kind == SCENE_HUGE_TINY) && n > 20000)
                continue;
            bpx_box *boxes = check_alloc(sizeof(bpx_box) * (n ? n : 1));
            CHECK(scene_generate((scene_kind)kind, n, 7 + n, boxes) == 0);
            bpx_world *oracle = oracle_world(n);
            scene_rng rng;
            scene_rng_seed(&rng, 99);
            for (int cycle = 0; cycle < 3; cycle++) {
                char what[96];
                snprintf(what, sizeof what, "%s n=%u cycle %d", scene_kind_name((scene_kind)kind),
                         n, cycle);
                CHECK_STATUS(bpx_world_set_boxes(cuda, boxes, n), BPX_OK);
                CHECK_STATUS(bpx_world_set_boxes(oracle, boxes, n), BPX_OK);
                CHECK_STATUS(bpx_world_collide(cuda), BPX_OK);
                CHECK_STATUS(bpx_world_collide(oracle), BPX_OK);
                if (!same_pairs(cuda, oracle, what))
                    break;
                // Motion would push the extreme scenes' coordinates out of range.
                if (kind == SCENE_HUGE_TINY || kind == SCENE_DENORMAL ||
                    kind == SCENE_SIGNED_ZERO || kind == SCENE_TOUCHING)
                    break;
                scene_move(boxes, n, 0.2f, &rng);
            }
            bpx_world_destroy(oracle);
            free(boxes);
        }
    }
    bpx_world_destroy(cuda);
}

// Heavy-tailed and uniform scenes at the benchmark's density, against prune; a second cuda world
// gives the same bytes.
static void test_large(void)
{
    static const uint32_t sizes[] = {65536, 300000};
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        uint32_t n = sizes[s];
        bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
        for (int heavy = 0; heavy < 2; heavy++) {
            if (heavy)
                scene_heavy_tailed_density(n, 5, boxes);
            else
                scene_uniform_density(n, 1.0f, 5, boxes);
            bpx_world *a = cuda_world(false), *b = cuda_world(false), *oracle = oracle_world(n);
            CHECK_STATUS(bpx_world_set_boxes(a, boxes, n), BPX_OK);
            CHECK_STATUS(bpx_world_set_boxes(b, boxes, n), BPX_OK);
            CHECK_STATUS(bpx_world_set_boxes(oracle, boxes, n), BPX_OK);
            CHECK_STATUS(bpx_world_collide(a), BPX_OK);
            CHECK_STATUS(bpx_world_collide(b), BPX_OK);
            CHECK_STATUS(bpx_world_collide(oracle), BPX_OK);
            char what[64];
            snprintf(what, sizeof what, "%s n=%u", heavy ? "heavy" : "uniform", n);
            same_pairs(a, oracle, what);
            same_pairs(a, b, what);
            bpx_cycle_stats st = bpx_world_stats(a);
            CHECK(st.bytes_in == 24ull * n);
            CHECK(st.device_ns > 0);
            bpx_world_destroy(a);
            bpx_world_destroy(b);
            bpx_world_destroy(oracle);
        }
        free(boxes);
    }
}

// Removed ids are inert boxes in the middle of the array: they sort last and pair with nothing.
static void test_objects_and_events(void)
{
    enum { n = 5000 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 2.0f, 3, boxes);
    bpx_world *cuda = cuda_world(true), *oracle = oracle_world_events(n, true);
    uint32_t ids[n];
    CHECK_STATUS(bpx_world_add_boxes(cuda, boxes, n, ids), BPX_OK);
    CHECK_STATUS(bpx_world_add_boxes(oracle, boxes, n, ids), BPX_OK);
    uint32_t gone[100];
    for (int k = 0; k < 100; k++)
        gone[k] = (uint32_t)(k * 37 % n);
    for (int cycle = 0; cycle < 3; cycle++) {
        if (cycle == 1) {
            CHECK_STATUS(bpx_world_remove_boxes(cuda, gone, 100), BPX_OK);
            CHECK_STATUS(bpx_world_remove_boxes(oracle, gone, 100), BPX_OK);
        }
        CHECK_STATUS(bpx_world_collide(cuda), BPX_OK);
        CHECK_STATUS(bpx_world_collide(oracle), BPX_OK);
        same_pairs(cuda, oracle, "objects");
        bpx_pair_events ec, eo;
        CHECK_STATUS(bpx_world_pair_events(cuda, &ec), BPX_OK);
        CHECK_STATUS(bpx_world_pair_events(oracle, &eo), BPX_OK);
        CHECK(ec.began_count == eo.began_count && ec.ended_count == eo.ended_count);
    }
    bpx_world_destroy(cuda);
    bpx_world_destroy(oracle);
    free(boxes);
}

// A live box alone in the Morton order's top cell (code 0x3FFFFFFF) after removed ids: their
// code (~0u) must sort after it, else the codes are out of order and the tree is no tree.
static void test_inert_before_top_cell(void)
{
    enum { n = 3000 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 1.0f, 6, boxes);
    for (int a = 0; a < 3; a++) { // a pair of boxes beyond every other on every axis
        boxes[n - 2].min[a] = 1e6f, boxes[n - 2].max[a] = 1e6f + 2.0f;
        boxes[n - 1].min[a] = 1e6f + 1.0f, boxes[n - 1].max[a] = 1e6f + 3.0f;
    }
    bpx_world *cuda = cuda_world(false), *oracle = oracle_world(n);
    uint32_t *ids = check_alloc(sizeof(uint32_t) * n);
    CHECK_STATUS(bpx_world_add_boxes(cuda, boxes, n, ids), BPX_OK);
    CHECK_STATUS(bpx_world_add_boxes(oracle, boxes, n, ids), BPX_OK);
    uint32_t gone[10] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
    CHECK_STATUS(bpx_world_remove_boxes(cuda, gone, 10), BPX_OK);
    CHECK_STATUS(bpx_world_remove_boxes(oracle, gone, 10), BPX_OK);
    CHECK_STATUS(bpx_world_collide(cuda), BPX_OK);
    CHECK_STATUS(bpx_world_collide(oracle), BPX_OK);
    same_pairs(cuda, oracle, "top cell after removed ids");
    bpx_world_destroy(cuda);
    bpx_world_destroy(oracle);
    free(ids);
    free(boxes);
}

// Calls that do not apply are refused, with the world unchanged.
static void test_refusals(void)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_SAP;
    bpx_world *sap = NULL;
    CHECK_STATUS(bpx_world_create(&def, &sap), BPX_OK);
    CHECK_STATUS(bpx_cuda_collide_device(sap, NULL), BPX_ERR_BACKEND_UNAVAILABLE);
    CHECK_STATUS(bpx_cuda_set_boxes_device(sap, NULL, 0), BPX_ERR_BACKEND_UNAVAILABLE);
    CHECK_STATUS(bpx_cuda_set_centres_device(sap, NULL, 0), BPX_ERR_BACKEND_UNAVAILABLE);
    CHECK_STATUS(bpx_cuda_finish(NULL, NULL), BPX_ERR_NULL_ARGUMENT);
    bpx_world_destroy(sap);

    bpx_world *w = cuda_world(true);
    CHECK_STATUS(bpx_cuda_collide_device(w, NULL), BPX_ERR_BAD_STATE); // events need the host
    CHECK_STATUS(bpx_cuda_set_boxes_device(w, NULL, 5), BPX_ERR_NULL_ARGUMENT);
    bpx_world_destroy(w);
}

#if BPX_TEST_FAKE_CUDA
// The fake device (test/fake_cuda/) fails its k-th allocation from here on, for every k a few
// cycles make, on the host path (both comparators, host boxes and host centres) and the
// device-resident one: each failure is a status (DEVICE_MEMORY, or OUT_OF_MEMORY for pinned
// host memory), nothing is lost (with allocations back, the same world gives the oracle's pairs),
// and destroying the world frees every allocation.
static void run_cycles(bpx_world *w, const bpx_box *boxes, uint32_t n, const float *centres,
                       const float *minima, bool resident, bpx_status *first)
{
    bpx_status s =
        centres ? bpx_world_load_extents(w, minima, n) : bpx_world_set_boxes(w, boxes, n);
    if (s == BPX_OK && centres)
        s = bpx_world_update_centres(w, centres);
    for (int cycle = 0; cycle < 2 && s == BPX_OK; cycle++) {
        s = resident ? bpx_cuda_collide_device(w, NULL) : bpx_world_collide(w);
        if (s == BPX_OK && resident)
            s = bpx_cuda_finish(w, NULL);
        if (s == BPX_ERR_CAPACITY)
            s = BPX_OK; // the next cycle has room
    }
    *first = s;
}

static void test_allocation_failures(void)
{
    const uint32_t sizes[] = {700, 3000};
    for (size_t z = 0; z < sizeof sizes / sizeof sizes[0]; z++) {
        const uint32_t n = sizes[z];
        bpx_box *boxes = malloc(sizeof(bpx_box) * n);
        float *centres = malloc(sizeof(float) * 3 * n), *minima = malloc(sizeof(float) * 3 * n);
        CHECK(boxes && centres && minima);
        scene_uniform_density(n, 1.0f, 11 + n, boxes);
        split_boxes(boxes, n, centres, minima);
        for (int mode = 0; mode < 3; mode++) { // host boxes, host centres, device-resident
            const float *c = mode == 1 ? centres : NULL;
            bpx_world *oracle = oracle_world(n);
            bpx_status o;
            run_cycles(oracle, boxes, n, c, minima, false, &o); // the same input, on the host
            CHECK_STATUS(o, BPX_OK);
            int failures = 0;
            for (long k = 0;; k++) {
                long before = bpx_fake_cuda_live_blocks();
                bpx_world *w = cuda_world(false);
                bpx_fake_cuda_fail_allocations_after(k);
                bpx_status s;
                run_cycles(w, boxes, n, c, minima, mode == 2, &s);
                bpx_fake_cuda_fail_allocations_after(-1);
                if (s == BPX_OK) { // k passed every allocation the cycles make
                    bpx_world_destroy(w);
                    break;
                }
                failures++;
                CHECK_MSG(s == BPX_ERR_DEVICE_MEMORY || s == BPX_ERR_OUT_OF_MEMORY,
                          "n = %u, mode %d, allocation %ld failed: %s", n, mode, k,
                          bpx_status_name(s));
                run_cycles(w, boxes, n, c, minima, mode == 2, &s);
                CHECK_MSG(s == BPX_OK, "n = %u, mode %d, after allocation %ld failed: %s", n, mode,
                          k, bpx_status_name(s));
                if (mode == 2) { // the device's pairs, read back
                    size_t count = 0;
                    CHECK_STATUS(bpx_cuda_collide_device(w, NULL), BPX_OK);
                    CHECK_STATUS(bpx_cuda_finish(w, &count), BPX_OK);
                    void *dp = NULL;
                    CHECK_STATUS(bpx_cuda_device_pairs(w, &dp, NULL, NULL), BPX_OK);
                    size_t want = 0;
                    const bpx_pair *wp = bpx_world_pairs(oracle, &want);
                    bpx_pair *back = malloc(sizeof(bpx_pair) * (count ? count : 1));
                    CHECK(back && cudaMemcpy(back, dp, sizeof(bpx_pair) * count,
                                             cudaMemcpyDeviceToHost) == cudaSuccess);
                    CHECK_MSG(count == want && pairs_first_diff(back, count, wp, want) == want,
                              "n = %u, resident, after allocation %ld failed: pairs differ", n, k);
                    free(back);
                } else {
                    CHECK(same_pairs(w, oracle, "after a failed allocation"));
                }
                bpx_world_destroy(w);
                CHECK_MSG(bpx_fake_cuda_live_blocks() == before,
                          "n = %u, mode %d, allocation %ld: %ld allocations left", n, mode, k,
                          bpx_fake_cuda_live_blocks() - before);
                CHECK_MSG(k < 200, "n = %u, mode %d: no end to the allocations", n, mode);
                if (k >= 200)
                    break;
            }
            CHECK_MSG(failures > 0, "n = %u, mode %d: no allocation to fail", n, mode);
            printf("allocation failures (n = %u, %s): %d, each a status, nothing lost\n", n,
                   mode == 0   ? "host boxes"
                   : mode == 1 ? "host centres"
                               : "device-resident",
                   failures);
            bpx_world_destroy(oracle);
        }
        free(boxes);
        free(centres);
        free(minima);
    }
}
#endif

int main(int argc, char **argv)
{
    quick = argc > 1 && strcmp(argv[1], "--quick") == 0;
    bpx_set_logger(print_log, NULL);
    bpx_backend_info info = bpx_backend_query(BPX_BACKEND_CUDA);
    printf("cuda: %s%s\n",
           info.available ? info.detail : "unavailable: ", info.available ? "" : info.reason);
    if (!info.available) {
        // The calls exist in every build and refuse politely.
        bpx_world_def def = bpx_default_world_def();
        def.backend = BPX_BACKEND_CUDA;
        bpx_world *w = NULL;
        CHECK_STATUS(bpx_world_create(&def, &w), BPX_ERR_BACKEND_UNAVAILABLE);
        CHECK(w == NULL);
        CHECK_STATUS(bpx_cuda_set_centres_device(NULL, NULL, 0), BPX_ERR_NULL_ARGUMENT);
        CHECK_STATUS(bpx_cuda_set_boxes_device(NULL, NULL, 0), BPX_ERR_NULL_ARGUMENT);
        return check_finish("test_cuda", 0);
    }
    test_refusals();
    test_scenes();
    if (!quick)
        test_large();
    test_objects_and_events();
    test_inert_before_top_cell();
#if BPX_TEST_FAKE_CUDA
    test_allocation_failures();
    CHECK_MSG(bpx_fake_cuda_live_blocks() == 0, "%ld device or pinned allocations never freed",
              bpx_fake_cuda_live_blocks());
#endif
    return check_finish("test_cuda", 1);
}
