// The cuda backend beyond what the suites that loop over every backend check (test_differential
// and test_determinism run it wherever it is available): both comparators (brute force up to 1024
// boxes, the tree beyond) on every scene kind over moving cycles, against prune (itself checked
// against the reference) and at small n against the reference; the same bytes on a second
// world; device-resident round trips (boxes in device memory, pairs left on the device, then
// read back and compared); a pair buffer too small (CAPACITY with the needed count, then room;
// on the host path, grown within the cycle); invalid device boxes; queries refused while the
// boxes are on the device; the paper's two-phase mode on the device's updater, with host centres
// and with device centres (errors named like the host's); and the calls refused where they do
// not apply.
//
// Without a CUDA device (or without CUDA in the build) the test reports itself skipped (77).
#include <float.h>
#include <math.h>

#include <bpx/cuda.h>

#include "pairs_util.h"
#include "scenes.h"

#if BPX_TEST_CUDA
#include <cuda_runtime_api.h>
#endif
#if BPX_TEST_FAKE_CUDA
#include "fake_cuda.h"
#endif

// A device failure names the CUDA call and error only through the logger (the world's error
// says DEVICE): printed, a failure on a lent GPU says which call failed and why.
static void print_log(int level, const char *message, void *user)
{
    (void)user;
    if (level <= 1)
        fprintf(stderr, "bpx log: %s\n", message);
}

static bpx_world *cuda_world(bool events)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_CUDA;
    def.track_events = events;
    bpx_world *w = NULL;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    return w;
}

static bpx_world *oracle_world_events(uint32_t n, bool events)
{
    bpx_world_def def = bpx_default_world_def();
    def.track_events = events;
    // prune beyond 3000 boxes: one sweep, the cheapest exact oracle for scenes that change
    // wholesale (sap, the oracle before, ran out of memory on the denormal scene at 120,000
    // boxes until its fat margins were capped).
    def.backend = n <= 3000 ? BPX_BACKEND_REFERENCE : BPX_BACKEND_PRUNE;
    def.worker_count = 2;
    bpx_world *w = NULL;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    return w;
}

static bpx_world *oracle_world(uint32_t n)
{
    return oracle_world_events(n, false);
}

static bool same_pairs(bpx_world *a, bpx_world *b, const char *what)
{
    size_t na = 0, nb = 0;
    const bpx_pair *pa = bpx_world_pairs(a, &na);
    const bpx_pair *pb = bpx_world_pairs(b, &nb);
    size_t diff = pairs_first_diff(pa, na, pb, nb);
    bool same = na == nb && diff == na;
    CHECK_MSG(same, "%s: %zu vs %zu pairs, first difference at %zu", what, na, nb, diff);
    return same;
}

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

#if BPX_TEST_CUDA
// A copy to the device that has landed before the world reads it: a cudaMemcpy from pageable
// memory may return before its DMA ends, and the world's non-blocking stream does not wait for
// the legacy stream the copy runs on.
static bool copy_to_device(void *d, const void *h, size_t bytes)
{
    return cudaMemcpy(d, h, bytes, cudaMemcpyHostToDevice) == cudaSuccess &&
           cudaDeviceSynchronize() == cudaSuccess;
}

static bpx_box *to_device(const bpx_box *boxes, uint32_t n)
{
    void *d = NULL;
    CHECK(cudaMalloc(&d, sizeof(bpx_box) * (n ? n : 1)) == cudaSuccess);
    CHECK(copy_to_device(d, boxes, sizeof(bpx_box) * n));
    return d;
}

// Device in, device out; then the pairs read back and compared with the oracle. A first cycle
// whose pairs pass the buffer reports CAPACITY with the count, and the next has room.
static void test_device_resident(void)
{
    static const uint32_t sizes[] = {500, 1024, 5000, 200000, 2500};
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        uint32_t n = sizes[s];
        if (quick && n > 5000)
            continue;
        bool crowded = n == 2500; // every box over one point: n(n-1)/2 pairs, past the buffer
        bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
        if (crowded)
            CHECK(scene_generate(SCENE_ALL_OVERLAP, n, 1, boxes) == 0);
        else
            scene_heavy_tailed_density(n, 11, boxes);
        bpx_box *d_boxes = to_device(boxes, n);
        bpx_world *cuda = cuda_world(false), *oracle = oracle_world(n);
        CHECK_STATUS(bpx_cuda_set_boxes_device(cuda, d_boxes, n), BPX_OK);
        CHECK(bpx_world_box_count(cuda) == n);
        CHECK_STATUS(bpx_world_set_boxes(oracle, boxes, n), BPX_OK);
        CHECK_STATUS(bpx_world_collide(oracle), BPX_OK);
        size_t want = 0;
        const bpx_pair *want_pairs = bpx_world_pairs(oracle, &want);
        for (int cycle = 0; cycle < 3; cycle++) {
            CHECK_STATUS(bpx_cuda_collide_device(cuda, NULL), BPX_OK);
            size_t count = 0;
            bpx_status st = bpx_cuda_finish(cuda, &count);
            CHECK_MSG(count == want, "n=%u cycle %d: %zu pairs, want %zu", n, cycle, count, want);
            if (crowded && cycle == 0) {
                CHECK_STATUS(st, BPX_ERR_CAPACITY);
                continue;
            }
            CHECK_STATUS(st, BPX_OK);
            void *d_pairs = NULL;
            void *d_count = NULL;
            size_t capacity = 0;
            CHECK_STATUS(bpx_cuda_device_pairs(cuda, &d_pairs, &d_count, &capacity), BPX_OK);
            CHECK(capacity >= count);
            unsigned long long on_device = 0;
            CHECK(cudaMemcpy(&on_device, d_count, sizeof on_device, cudaMemcpyDeviceToHost) ==
                  cudaSuccess);
            CHECK(on_device == want);
            bpx_pair *got = check_alloc(sizeof(bpx_pair) * (count ? count : 1));
            CHECK(cudaMemcpy(got, d_pairs, sizeof(bpx_pair) * count, cudaMemcpyDeviceToHost) ==
                  cudaSuccess);
            CHECK_MSG(count == want && pairs_first_diff(got, count, want_pairs, want) == want,
                      "device-resident n=%u cycle %d differs", n, cycle);
            free(got);
        }
        // Device in, host out: the ordinary collide reads the same device boxes.
        CHECK_STATUS(bpx_world_collide(cuda), BPX_OK);
        same_pairs(cuda, oracle, "device in, host out");
        bpx_world_destroy(cuda);
        bpx_world_destroy(oracle);
        cudaFree(d_boxes);
        free(boxes);
    }
}

// A device-resident cycle keeps room for the last count and half more, whatever slack the
// buffer has: a count past it (boxes grown between cycles, pairs 20 times as many, still within
// the buffer) is CAPACITY with the count and a capacity below it, and the next cycle has room.
static void test_device_room(void)
{
    enum { n = 3000 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 1.0f, 21, boxes);
    bpx_box *d_boxes = to_device(boxes, n);
    bpx_world *cuda = cuda_world(false), *oracle = oracle_world(n);
    CHECK_STATUS(bpx_cuda_set_boxes_device(cuda, d_boxes, n), BPX_OK);
    size_t count = 0, capacity = 0;
    CHECK_STATUS(bpx_cuda_collide_device(cuda, NULL), BPX_OK);
    CHECK_STATUS(bpx_cuda_finish(cuda, &count), BPX_OK);
    for (uint32_t i = 0; i < n; i++) // each box 3 times as wide: about 20 times the pairs
        for (int a = 0; a < 3; a++) {
            float c = 0.5f * boxes[i].min[a] + 0.5f * boxes[i].max[a];
            float h = 1.5f * (boxes[i].max[a] - boxes[i].min[a]);
            boxes[i].min[a] = c - h, boxes[i].max[a] = c + h;
        }
    CHECK(copy_to_device(d_boxes, boxes, sizeof(bpx_box) * n));
    CHECK_STATUS(bpx_world_set_boxes(oracle, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_collide(oracle), BPX_OK);
    size_t want = 0;
    const bpx_pair *want_pairs = bpx_world_pairs(oracle, &want);
    CHECK_MSG(want > 3 * count / 2 + 1024 && want < 65536, "%zu pairs, then %zu", count, want);
    CHECK_STATUS(bpx_cuda_collide_device(cuda, NULL), BPX_OK);
    CHECK_STATUS(bpx_cuda_finish(cuda, &count), BPX_ERR_CAPACITY);
    CHECK_STATUS(bpx_cuda_device_pairs(cuda, NULL, NULL, &capacity), BPX_OK);
    CHECK_MSG(count == want && capacity < count, "%zu pairs, want %zu, room %zu", count, want,
              capacity);
    CHECK_STATUS(bpx_cuda_collide_device(cuda, NULL), BPX_OK);
    CHECK_STATUS(bpx_cuda_finish(cuda, &count), BPX_OK);
    void *d_pairs = NULL;
    CHECK_STATUS(bpx_cuda_device_pairs(cuda, &d_pairs, NULL, &capacity), BPX_OK);
    bpx_pair *got = check_alloc(sizeof(bpx_pair) * (count ? count : 1));
    CHECK(cudaMemcpy(got, d_pairs, sizeof(bpx_pair) * count, cudaMemcpyDeviceToHost) ==
          cudaSuccess);
    CHECK_MSG(count == want && capacity >= count &&
                  pairs_first_diff(got, count, want_pairs, want) == want,
              "after CAPACITY: %zu pairs, want %zu", count, want);
    free(got);
    bpx_world_destroy(cuda);
    bpx_world_destroy(oracle);
    cudaFree(d_boxes);
    free(boxes);
}

// Device-resident cycles on the caller's stream, as an engine runs them: the caller's copy of
// the moved boxes, the cycle and the caller's read of the pairs all on one non-blocking stream of
// its own, every other cycle on the world's stream instead (after the caller's stream is
// synchronised, as include/bpx/cuda.h asks). On the fake device (test/fake_cuda/) any access the
// backend makes out of stream order aborts the test.
static void test_device_caller_stream(void)
{
    static const uint32_t sizes[] = {600, 3000};
    for (size_t z = 0; z < sizeof sizes / sizeof sizes[0]; z++) {
        const uint32_t n = sizes[z];
        bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
        scene_uniform_density(n, 1.0f, 31, boxes);
        bpx_box *d_boxes = to_device(boxes, n);
        cudaStream_t mine = NULL;
        CHECK(cudaStreamCreateWithFlags(&mine, cudaStreamNonBlocking) == cudaSuccess);
        bpx_world *cuda = cuda_world(false), *oracle = oracle_world(n);
        CHECK_STATUS(bpx_cuda_set_boxes_device(cuda, d_boxes, n), BPX_OK);
        scene_rng rng;
        scene_rng_seed(&rng, 5);
        for (int cycle = 0; cycle < 4; cycle++) {
            scene_move(boxes, n, 0.2f, &rng);
            CHECK(cudaMemcpyAsync(d_boxes, boxes, sizeof(bpx_box) * n, cudaMemcpyHostToDevice,
                                  mine) == cudaSuccess);
            bool own = cycle % 2 == 1; // the world's stream: the caller's copy must land first
            if (own)
                CHECK(cudaStreamSynchronize(mine) == cudaSuccess);
            CHECK_STATUS(bpx_cuda_collide_device(cuda, own ? NULL : mine), BPX_OK);
            size_t count = 0;
            CHECK_STATUS(bpx_cuda_finish(cuda, &count), BPX_OK);
            void *d_pairs = NULL;
            CHECK_STATUS(bpx_cuda_device_pairs(cuda, &d_pairs, NULL, NULL), BPX_OK);
            bpx_pair *got = check_alloc(sizeof(bpx_pair) * (count ? count : 1));
            CHECK(cudaMemcpyAsync(got, d_pairs, sizeof(bpx_pair) * count, cudaMemcpyDeviceToHost,
                                  mine) == cudaSuccess &&
                  cudaStreamSynchronize(mine) == cudaSuccess);
            CHECK_STATUS(bpx_world_set_boxes(oracle, boxes, n), BPX_OK);
            CHECK_STATUS(bpx_world_collide(oracle), BPX_OK);
            size_t want = 0;
            const bpx_pair *want_pairs = bpx_world_pairs(oracle, &want);
            CHECK_MSG(count == want && pairs_first_diff(got, count, want_pairs, want) == want,
                      "n=%u cycle %d (%s stream): %zu pairs, want %zu", n, cycle,
                      own ? "the world's" : "the caller's", count, want);
            free(got);
        }
        bpx_world_destroy(cuda);
        bpx_world_destroy(oracle);
        CHECK(cudaStreamDestroy(mine) == cudaSuccess);
        cudaFree(d_boxes);
        free(boxes);
    }
}

// A bad box in device memory is named like a bad host box, and the world keeps its boxes; one
// that turns bad after the check is reported by the cycle that reads it, on both comparators
// (the small one's kernel must leave the check alone).
static void test_device_errors(uint32_t n)
{
    const uint32_t nan_at = n * 2 / 5, flipped_at = n * 2 / 3;
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 1.0f, 2, boxes);
    bpx_box *good = to_device(boxes, n);
    boxes[nan_at].min[1] = NAN;
    boxes[flipped_at].min[0] = boxes[flipped_at].max[0] + 1.0f;
    bpx_box *bad = to_device(boxes, n);
    bpx_world *cuda = cuda_world(false);
    CHECK_STATUS(bpx_cuda_set_boxes_device(cuda, good, n), BPX_OK);
    CHECK_STATUS(bpx_cuda_set_boxes_device(cuda, bad, n), BPX_ERR_NOT_FINITE);
    const bpx_error *e = bpx_world_error(cuda);
    CHECK(e->index == nan_at && e->axis == 1);
    CHECK(bpx_world_box_count(cuda) == n);
    CHECK_STATUS(bpx_world_collide(cuda), BPX_OK); // still the good boxes
    size_t first = 0;
    bpx_world_pairs(cuda, &first);
    // The good buffer turns bad between cycles.
    CHECK(cudaMemcpy(good, bad, sizeof(bpx_box) * n, cudaMemcpyDeviceToDevice) == cudaSuccess &&
          cudaDeviceSynchronize() == cudaSuccess); // landed before the world's stream reads it
    CHECK_STATUS(bpx_world_collide(cuda), BPX_ERR_NOT_FINITE);
    CHECK_MSG(bpx_world_error(cuda)->index == nan_at, "n=%u: named box %u, want %u (%s)", n,
              bpx_world_error(cuda)->index, nan_at, bpx_world_error(cuda)->message);
    CHECK_STATUS(bpx_cuda_collide_device(cuda, NULL), BPX_OK);
    CHECK_STATUS(bpx_cuda_finish(cuda, NULL), BPX_ERR_NOT_FINITE);
    CHECK(bpx_world_error(cuda)->index == nan_at);
    bpx_world_destroy(cuda);
    cudaFree(good);
    cudaFree(bad);
    free(boxes);
}

// Device in, host out on a world's first cycle, when the pairs pass the first pair buffer: the
// walk runs again into a grown buffer, whose head must still carry the boxes' check. Then the
// device boxes turn infinite from box 100 on (n^2 / 2 candidate pairs): the cycle names box 100
// before it grows anything.
static void test_device_first_cycle_growth(void)
{
    enum { n = 2500 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    CHECK(scene_generate(SCENE_ALL_OVERLAP, n, 1, boxes) == 0); // n(n-1)/2 pairs
    bpx_box *d_boxes = to_device(boxes, n);
    bpx_world *cuda = cuda_world(false), *oracle = oracle_world(n);
    CHECK_STATUS(bpx_cuda_set_boxes_device(cuda, d_boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_set_boxes(oracle, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_collide(oracle), BPX_OK);
    CHECK_STATUS(bpx_world_collide(cuda), BPX_OK);
    same_pairs(cuda, oracle, "device in, host out, first cycle past the buffer");
    bpx_world_destroy(cuda);

    cuda = cuda_world(false);
    CHECK_STATUS(bpx_cuda_set_boxes_device(cuda, d_boxes, n), BPX_OK);
    for (uint32_t i = 100; i < n; i++)
        for (int a = 0; a < 3; a++)
            boxes[i].min[a] = -INFINITY, boxes[i].max[a] = INFINITY;
    CHECK(copy_to_device(d_boxes, boxes, sizeof(bpx_box) * n));
    CHECK_STATUS(bpx_world_collide(cuda), BPX_ERR_NOT_FINITE);
    CHECK_MSG(bpx_world_error(cuda)->index == 100, "named box %u, want 100",
              bpx_world_error(cuda)->index);
    bpx_world_destroy(cuda);
    bpx_world_destroy(oracle);
    cudaFree(d_boxes);
    free(boxes);
}

// A device-resident cycle over boxes that turned infinite counts about n^2 / 2 pairs; once the
// boxes are good again, the next cycle's buffer is sized by the good cycles, not by that count.
static void test_device_bad_count(void)
{
    enum { n = 2500 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 1.0f, 8, boxes);
    bpx_box *d_boxes = to_device(boxes, n), *d_bad = to_device(boxes, n);
    bpx_box *bad = check_alloc(sizeof(bpx_box) * n);
    memcpy(bad, boxes, sizeof(bpx_box) * n);
    for (uint32_t i = 100; i < n; i++)
        for (int a = 0; a < 3; a++)
            bad[i].min[a] = -INFINITY, bad[i].max[a] = INFINITY;
    CHECK(copy_to_device(d_bad, bad, sizeof(bpx_box) * n));
    bpx_world *cuda = cuda_world(false);
    CHECK_STATUS(bpx_cuda_set_boxes_device(cuda, d_boxes, n), BPX_OK);
    CHECK_STATUS(bpx_cuda_collide_device(cuda, NULL), BPX_OK);
    size_t good = 0, count = 0, capacity = 0;
    CHECK_STATUS(bpx_cuda_finish(cuda, &good), BPX_OK);
    CHECK(cudaMemcpy(d_boxes, d_bad, sizeof(bpx_box) * n, cudaMemcpyDeviceToDevice) ==
              cudaSuccess &&
          cudaDeviceSynchronize() == cudaSuccess); // landed before the world's stream reads it
    CHECK_STATUS(bpx_cuda_collide_device(cuda, NULL), BPX_OK);
    CHECK_STATUS(bpx_cuda_finish(cuda, &count), BPX_ERR_NOT_FINITE);
    CHECK(bpx_world_error(cuda)->index == 100);
    CHECK(copy_to_device(d_boxes, boxes, sizeof(bpx_box) * n));
    CHECK_STATUS(bpx_cuda_collide_device(cuda, NULL), BPX_OK);
    CHECK_STATUS(bpx_cuda_finish(cuda, &count), BPX_OK);
    CHECK(count == good);
    CHECK_STATUS(bpx_cuda_device_pairs(cuda, NULL, NULL, &capacity), BPX_OK);
    CHECK_MSG(capacity < (size_t)n * n / 4, "%zu pairs' room after a bad cycle (%zu found)",
              capacity, good);
    bpx_world_destroy(cuda);
    cudaFree(d_boxes);
    cudaFree(d_bad);
    free(bad);
    free(boxes);
}

// Queries while the boxes are in device memory: refused (BAD_STATE, nothing written), the
// cycles unaffected, until set_boxes brings host boxes back; then they see those.
static void test_device_queries(void)
{
    enum { n = 2000 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    bpx_hit *got = check_alloc(sizeof(bpx_hit) * n), *want = check_alloc(sizeof(bpx_hit) * n);
    scene_uniform_density(n, 1.0f, 4, boxes);
    bpx_box *d_boxes = to_device(boxes, n);
    bpx_world *cuda = cuda_world(false), *oracle = oracle_world(n);
    bpx_box region = boxes[n / 2]; // the boxes around one
    for (int a = 0; a < 3; a++)
        region.min[a] -= 2.0f, region.max[a] += 2.0f;
    const bpx_query q = bpx_query_box(region);
    CHECK_STATUS(bpx_world_set_boxes(oracle, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_collide(oracle), BPX_OK);
    CHECK_STATUS(bpx_cuda_set_boxes_device(cuda, d_boxes, n), BPX_OK);
    for (int cycle = 0; cycle < 2; cycle++) {
        bpx_hit hit = {7, 0.5f};
        size_t count = 99, offsets[2] = {5, 5}, total = 99;
        CHECK_STATUS(bpx_world_query(cuda, &q, &hit, 1, &count), BPX_ERR_BAD_STATE);
        CHECK_STATUS(bpx_world_query_batch(cuda, &q, 1, offsets, &hit, 1, &total),
                     BPX_ERR_BAD_STATE);
        CHECK(count == 99 && total == 99 && offsets[0] == 5 && offsets[1] == 5 && hit.id == 7);
        const bpx_error *e = bpx_world_error(cuda);
        CHECK_MSG(e->status == BPX_ERR_BAD_STATE && e->index == UINT32_MAX && e->axis == -1 &&
                      strstr(e->message, "device buffer"),
                  "error: %s", e->message);
        CHECK_STATUS(bpx_world_collide(cuda), BPX_OK); // the world runs on
        same_pairs(cuda, oracle, "collide after a refused query");
    }
    // Host boxes again: the queries see them.
    CHECK_STATUS(bpx_world_set_boxes(cuda, boxes, n), BPX_OK);
    size_t got_count = 0, want_count = 0;
    CHECK_STATUS(bpx_world_query(cuda, &q, got, n, &got_count), BPX_OK);
    CHECK_STATUS(bpx_world_query(oracle, &q, want, n, &want_count), BPX_OK);
    CHECK(want_count > 0 && got_count == want_count &&
          memcmp(got, want, sizeof(bpx_hit) * want_count) == 0);
    bpx_world_destroy(cuda);
    bpx_world_destroy(oracle);
    cudaFree(d_boxes);
    free(boxes);
    free(got);
    free(want);
}

static float *centres_to_device(const float *centres, uint32_t n)
{
    void *d = NULL;
    CHECK(cudaMalloc(&d, 12 * (size_t)(n ? n : 1)) == cudaSuccess);
    CHECK(copy_to_device(d, centres, 12 * (size_t)n));
    return d;
}

// The paper's two-phase mode: extents once, then centres. boxes -> centres and origin-centred
// minima (<= 0), as a simulation keeps them.
static void split_boxes(const bpx_box *boxes, uint32_t n, float *centres, float *minima)
{
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            float c = 0.5f * boxes[i].min[a] + 0.5f * boxes[i].max[a];
            float half = 0.5f * boxes[i].max[a] - 0.5f * boxes[i].min[a];
            centres[3 * (size_t)i + a] = c;
            minima[3 * (size_t)i + a] = -half;
        }
}

static void centres_move(float *centres, uint32_t n, uint32_t cycle)
{
    for (uint32_t i = 0; i < n; i++)
        centres[3 * (size_t)i + cycle % 3] += (i % 5 == 0) ? 0.3f : -0.05f;
}

// Host centres go to the device's updater (12 bytes an object); device centres are read in
// place. Both give the oracle's pairs, whose boxes the host's updater made from the same
// centres, on both paths (small, tree), through host-out and device-resident cycles;
// subnormal and signed-zero coordinates included (the device must round as the host does).
static void test_centres(void)
{
    static const uint32_t sizes[] = {1, 500, 1024, 1025, 20000};
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        for (int edge = 0; edge < 2; edge++) {
            uint32_t n = sizes[s];
            if ((edge || quick) && n > 3000)
                continue;
            bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
            if (edge)
                CHECK(scene_generate(n % 2 ? SCENE_DENORMAL : SCENE_SIGNED_ZERO, n, 5, boxes) == 0);
            else
                scene_uniform_density(n, 1.0f, 8, boxes);
            float *centres = check_alloc(12 * (size_t)n), *minima = check_alloc(12 * (size_t)n);
            split_boxes(boxes, n, centres, minima);
            bpx_world *cuda = cuda_world(false), *oracle = oracle_world(n);
            CHECK_STATUS(bpx_world_load_extents(cuda, minima, n), BPX_OK);
            CHECK_STATUS(bpx_world_load_extents(oracle, minima, n), BPX_OK);
            float *d_centres = centres_to_device(centres, n);
            for (uint32_t cycle = 0; cycle < 6; cycle++) {
                char what[96];
                snprintf(what, sizeof what, "centres n=%u%s cycle %u", n, edge ? " (edge)" : "",
                         cycle);
                CHECK_STATUS(bpx_world_update_centres(oracle, centres), BPX_OK);
                CHECK_STATUS(bpx_world_collide(oracle), BPX_OK);
                if (cycle % 2 == 0) { // host centres over the link
                    CHECK_STATUS(bpx_world_update_centres(cuda, centres), BPX_OK);
                    CHECK_STATUS(bpx_world_collide(cuda), BPX_OK);
                    CHECK_MSG(bpx_world_stats(cuda).bytes_in == 12ull * n, "%s: %llu bytes in",
                              what, (unsigned long long)bpx_world_stats(cuda).bytes_in);
                    same_pairs(cuda, oracle, what);
                } else { // device centres, read in place; then device-resident
                    CHECK(copy_to_device(d_centres, centres, 12 * (size_t)n));
                    CHECK_STATUS(bpx_cuda_set_centres_device(cuda, d_centres, n), BPX_OK);
                    CHECK_STATUS(bpx_world_collide(cuda), BPX_OK);
                    CHECK(bpx_world_stats(cuda).bytes_in == 0);
                    same_pairs(cuda, oracle, what);
                    size_t want = 0, count = 0;
                    const bpx_pair *want_pairs = bpx_world_pairs(oracle, &want);
                    CHECK_STATUS(bpx_cuda_collide_device(cuda, NULL), BPX_OK);
                    bpx_status st = bpx_cuda_finish(cuda, &count);
                    CHECK(st == BPX_OK || st == BPX_ERR_CAPACITY);
                    if (st == BPX_ERR_CAPACITY) { // the first resident cycle may be short
                        CHECK_STATUS(bpx_cuda_collide_device(cuda, NULL), BPX_OK);
                        CHECK_STATUS(bpx_cuda_finish(cuda, &count), BPX_OK);
                    }
                    void *d_pairs = NULL;
                    CHECK_STATUS(bpx_cuda_device_pairs(cuda, &d_pairs, NULL, NULL), BPX_OK);
                    bpx_pair *got = check_alloc(sizeof(bpx_pair) * (count ? count : 1));
                    CHECK(cudaMemcpy(got, d_pairs, sizeof(bpx_pair) * count,
                                     cudaMemcpyDeviceToHost) == cudaSuccess);
                    CHECK_MSG(count == want &&
                                  pairs_first_diff(got, count, want_pairs, want) == want,
                              "%s: device-resident pairs differ", what);
                    free(got);
                }
                if (!edge)
                    centres_move(centres, n, cycle);
            }
            bpx_world_destroy(cuda);
            bpx_world_destroy(oracle);
            cudaFree(d_centres);
            free(centres);
            free(minima);
            free(boxes);
        }
    }
}

// Device centres refused or named like host centres; a centre that turns bad later is named by
// the cycle that reads it; queries wait for host data.
static void test_centres_errors(uint32_t n)
{
    const uint32_t nan_at = n / 40 + 2, big = n - n / 6; // 77 and 2500 of 3000
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 1.0f, 6, boxes);
    float *centres = check_alloc(12 * (size_t)n), *minima = check_alloc(12 * (size_t)n);
    split_boxes(boxes, n, centres, minima);
    centres[3 * big] = 0.0f; // object `big` spans the whole x axis: a big centre overflows it
    minima[3 * big] = -FLT_MAX;
    float *d_good = centres_to_device(centres, n);
    bpx_world *cuda = cuda_world(false);
    CHECK_STATUS(bpx_cuda_set_centres_device(cuda, d_good, n), BPX_ERR_BAD_STATE); // no extents
    CHECK_STATUS(bpx_world_load_extents(cuda, minima, n), BPX_OK);
    CHECK_STATUS(bpx_cuda_set_centres_device(cuda, NULL, n), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_cuda_set_centres_device(cuda, d_good, n - 1), BPX_ERR_INVALID_ARGUMENT);
    CHECK_STATUS(bpx_world_update_centres(cuda, centres), BPX_OK);
    CHECK_STATUS(bpx_world_collide(cuda), BPX_OK);
    size_t first = 0;
    bpx_world_pairs(cuda, &first);
    // A NaN centre at object nan_at (axis 2), and an overflow at object big (axis 0).
    centres[3 * nan_at + 2] = NAN;
    centres[3 * big] = 1e38f;
    float *d_bad = centres_to_device(centres, n);
    CHECK_STATUS(bpx_cuda_set_centres_device(cuda, d_bad, n), BPX_ERR_NOT_FINITE);
    const bpx_error *e = bpx_world_error(cuda);
    CHECK_MSG(e->index == nan_at && e->axis == 2, "n=%u: named object %u axis %d", n, e->index,
              e->axis);
    CHECK_STATUS(bpx_world_collide(cuda), BPX_OK); // still the host centres
    size_t again = 0;
    bpx_world_pairs(cuda, &again);
    CHECK(again == first);
    // Good device centres, queries refused meanwhile; then they turn bad (nan_at mended: big's
    // overflow is the first).
    CHECK_STATUS(bpx_cuda_set_centres_device(cuda, d_good, n), BPX_OK);
    bpx_hit hit;
    size_t hits = 0;
    const bpx_query q = bpx_query_box(boxes[0]);
    CHECK_STATUS(bpx_world_query(cuda, &q, &hit, 1, &hits), BPX_ERR_BAD_STATE);
    CHECK_STATUS(bpx_world_collide(cuda), BPX_OK);
    bpx_world_pairs(cuda, &again);
    CHECK(again == first);
    centres[3 * nan_at + 2] = 0.0f;
    CHECK(copy_to_device(d_good, centres, 12 * (size_t)n));
    CHECK_STATUS(bpx_world_collide(cuda), BPX_ERR_NOT_FINITE);
    CHECK_MSG(bpx_world_error(cuda)->index == big && bpx_world_error(cuda)->axis == 0,
              "n=%u: named object %u", n, bpx_world_error(cuda)->index);
    CHECK_STATUS(bpx_cuda_collide_device(cuda, NULL), BPX_OK);
    CHECK_STATUS(bpx_cuda_finish(cuda, NULL), BPX_ERR_NOT_FINITE);
    CHECK(bpx_world_error(cuda)->index == big);
    bpx_world_destroy(cuda);
    cudaFree(d_good);
    cudaFree(d_bad);
    free(centres);
    free(minima);
    free(boxes);
}

// Ids removed or moved by id after the centres or the device data were given change the host's
// boxes alone: host centres give way to them at the next cycle (the removed object pairs with
// nothing, the moved one where it went); device boxes and centres are refused (BAD_STATE), but
// not for filters, which change no box.
static void test_removed_after_centres(uint32_t n)
{
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    scene_uniform_density(n, 2.0f, 4, boxes);
    float *centres = check_alloc(12 * (size_t)n), *minima = check_alloc(12 * (size_t)n);
    split_boxes(boxes, n, centres, minima);
    bpx_world *cuda = cuda_world(false), *oracle = oracle_world(n);
    bpx_world *worlds[2] = {cuda, oracle};
    const uint32_t gone[3] = {0, n / 2, n - 1}, moved = n / 3;
    const bpx_box there = boxes[n / 4];
    for (int k = 0; k < 2; k++) {
        CHECK_STATUS(bpx_world_load_extents(worlds[k], minima, n), BPX_OK);
        CHECK_STATUS(bpx_world_update_centres(worlds[k], centres), BPX_OK);
        CHECK_STATUS(bpx_world_collide(worlds[k]), BPX_OK);
    }
    same_pairs(cuda, oracle, "centres before removal");
    for (int k = 0; k < 2; k++) {
        CHECK_STATUS(bpx_world_remove_boxes(worlds[k], gone, 3), BPX_OK);
        CHECK_STATUS(bpx_world_move_boxes(worlds[k], &moved, &there, 1), BPX_OK);
        CHECK_STATUS(bpx_world_collide(worlds[k]), BPX_OK);
    }
    char what[64];
    snprintf(what, sizeof what, "n=%u: centres, then removed and moved ids", n);
    same_pairs(cuda, oracle, what);
    bpx_world_destroy(cuda);
    // Device boxes, then an id removed: the device's boxes cannot follow.
    cuda = cuda_world(false);
    bpx_box *d_boxes = to_device(boxes, n);
    CHECK_STATUS(bpx_cuda_set_boxes_device(cuda, d_boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_collide(cuda), BPX_OK);
    const uint32_t category = 1, mask = UINT32_MAX; // filters change no box: still read
    CHECK_STATUS(bpx_world_set_filters(cuda, gone, &category, &mask, 1), BPX_OK);
    CHECK_STATUS(bpx_world_collide(cuda), BPX_OK);
    CHECK_STATUS(bpx_world_remove_boxes(cuda, gone, 1), BPX_OK);
    CHECK_STATUS(bpx_world_collide(cuda), BPX_ERR_BAD_STATE);
    CHECK_STATUS(bpx_cuda_collide_device(cuda, NULL), BPX_ERR_BAD_STATE);
    bpx_world_destroy(cuda);
    // Device centres, then an id moved: the same.
    cuda = cuda_world(false);
    float *d_centres = centres_to_device(centres, n);
    CHECK_STATUS(bpx_world_load_extents(cuda, minima, n), BPX_OK);
    CHECK_STATUS(bpx_cuda_set_centres_device(cuda, d_centres, n), BPX_OK);
    CHECK_STATUS(bpx_world_collide(cuda), BPX_OK);
    CHECK_STATUS(bpx_world_move_boxes(cuda, &moved, &there, 1), BPX_OK);
    CHECK_STATUS(bpx_world_collide(cuda), BPX_ERR_BAD_STATE);
    CHECK_STATUS(bpx_cuda_collide_device(cuda, NULL), BPX_ERR_BAD_STATE);
    bpx_world_destroy(cuda);
    bpx_world_destroy(oracle);
    cudaFree(d_boxes);
    cudaFree(d_centres);
    free(centres);
    free(minima);
    free(boxes);
}
#endif

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
#if BPX_TEST_CUDA
    test_device_resident();
    test_device_errors(600);  // one block
    test_device_errors(3000); // the tree
    test_device_first_cycle_growth();
    test_device_room();
    test_device_caller_stream();
    test_device_bad_count();
    test_device_queries();
    test_centres();
    test_centres_errors(3000);
    test_centres_errors(500);
    test_removed_after_centres(500);  // the small comparator
    test_removed_after_centres(3000); // the tree
#endif
#if BPX_TEST_FAKE_CUDA
    test_allocation_failures();
    CHECK_MSG(bpx_fake_cuda_live_blocks() == 0, "%ld device or pinned allocations never freed",
              bpx_fake_cuda_live_blocks());
#endif
    return check_finish("test_cuda", 1);
}
