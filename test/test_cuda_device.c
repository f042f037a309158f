// The cuda backend's device-resident cycles (include/bpx/cuda.h): boxes in device memory, pairs
// left on the device, then read back and compared with an oracle world's; a pair buffer too
// small (CAPACITY with the needed count, then room; on the host path, grown within the cycle);
// cycles on the caller's stream, and the caller's reads there followed by a next cycle on
// another stream or a host cycle; invalid device boxes, named like host ones; queries refused
// while the boxes are on the device; the paper's two-phase mode on the device's updater, with
// host centres and with device centres (errors named like the host's); ids removed or moved
// under device data. The host-out cycles are test_cuda.c's.
//
// Without a CUDA device (or without CUDA in the build) the test reports itself skipped (77).
#include <float.h>
#include <math.h>

#include "cuda_util.h"
#include "scenes.h"

#if BPX_TEST_FAKE_CUDA
#include "fake_cuda.h"
#endif

// --quick (for compute-sanitizer, which runs kernels tens of times slower): no set past 5000
// boxes, so every path still runs (both comparators, growth, errors) on small sets.
static bool quick;

#if BPX_TEST_CUDA
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

// The caller's work that reads a device-resident cycle's pairs on its stream A (here a copy of
// the count and the whole room into pinned memory, enqueued behind the cycle and not waited for)
// keeps them until it is done, whatever the world's next call (include/bpx/cuda.h): a cycle on
// another stream B, one on the world's stream, or a host cycle, each on boxes that moved (other
// pairs into the same buffers), waits for it on the device. On the fake device (test/fake_cuda/)
// a next cycle that writes the count, the pairs or the keys before the caller's copy has ended
// aborts the test; on a GPU such a race shows as a copy that is not the first cycle's pairs.
static void test_device_stream_handoff(void)
{
    static const uint32_t sizes[] = {600, 3000}; // the small comparator, the tree
    static const char *const next_names[] = {
        "a device cycle on another stream", "a device cycle on the world's stream", "a host cycle"};
    for (size_t z = 0; z < sizeof sizes / sizeof sizes[0]; z++) {
        const uint32_t n = sizes[z];
        bpx_box *boxes = check_alloc(sizeof(bpx_box) * n),
                *moved = check_alloc(sizeof(bpx_box) * n);
        scene_uniform_density(n, 1.0f, 41, boxes);
        memcpy(moved, boxes, sizeof(bpx_box) * n);
        scene_rng rng;
        scene_rng_seed(&rng, 9);
        scene_move(moved, n, 0.5f, &rng);
        bpx_box *d_boxes = to_device(boxes, n);
        bpx_world *first = oracle_world(n), *second = oracle_world(n);
        CHECK_STATUS(bpx_world_set_boxes(first, boxes, n), BPX_OK);
        CHECK_STATUS(bpx_world_collide(first), BPX_OK);
        CHECK_STATUS(bpx_world_set_boxes(second, moved, n), BPX_OK);
        CHECK_STATUS(bpx_world_collide(second), BPX_OK);
        size_t want = 0, want_moved = 0;
        const bpx_pair *want_pairs = bpx_world_pairs(first, &want);
        const bpx_pair *moved_pairs = bpx_world_pairs(second, &want_moved);
        CHECK_MSG(want != want_moved ||
                      pairs_first_diff(want_pairs, want, moved_pairs, want_moved) < want,
                  "n=%u: the moved boxes have the same pairs", n);
        cudaStream_t a = NULL, b = NULL;
        CHECK(cudaStreamCreateWithFlags(&a, cudaStreamNonBlocking) == cudaSuccess &&
              cudaStreamCreateWithFlags(&b, cudaStreamNonBlocking) == cudaSuccess);
        for (int next = 0; next < 3; next++) {
            bpx_world *cuda = cuda_world(false);
            CHECK_STATUS(bpx_cuda_set_boxes_device(cuda, d_boxes, n), BPX_OK);
            CHECK_STATUS(bpx_cuda_collide_device(cuda, a), BPX_OK);
            void *d_pairs = NULL, *d_count = NULL;
            size_t room = 0;
            CHECK_STATUS(bpx_cuda_device_pairs(cuda, &d_pairs, &d_count, &room), BPX_OK);
            CHECK(room >= want);
            unsigned long long *seen = NULL; // the count, then the room's pairs
            CHECK(cudaMallocHost((void **)&seen, 8 + sizeof(bpx_pair) * room) == cudaSuccess);
            CHECK(cudaMemcpyAsync(seen, d_count, 8, cudaMemcpyDeviceToHost, a) == cudaSuccess &&
                  cudaMemcpyAsync(seen + 1, d_pairs, sizeof(bpx_pair) * room,
                                  cudaMemcpyDeviceToHost, a) == cudaSuccess);
            // The next call, on other boxes, while the copy on `a` may still be reading.
            CHECK_STATUS(bpx_world_set_boxes(cuda, moved, n), BPX_OK);
            if (next < 2) {
                CHECK_STATUS(bpx_cuda_collide_device(cuda, next == 0 ? b : NULL), BPX_OK);
                size_t count = 0;
                CHECK_STATUS(bpx_cuda_finish(cuda, &count), BPX_OK);
                CHECK_STATUS(bpx_cuda_device_pairs(cuda, &d_pairs, NULL, NULL), BPX_OK);
                bpx_pair *got = check_alloc(sizeof(bpx_pair) * (count ? count : 1));
                CHECK(cudaMemcpy(got, d_pairs, sizeof(bpx_pair) * count, cudaMemcpyDeviceToHost) ==
                      cudaSuccess);
                CHECK_MSG(count == want_moved &&
                              pairs_first_diff(got, count, moved_pairs, want_moved) == want_moved,
                          "n=%u, %s: %zu pairs, want %zu", n, next_names[next], count, want_moved);
                free(got);
            } else {
                CHECK_STATUS(bpx_world_collide(cuda), BPX_OK);
                same_pairs(cuda, second,
                           "a host cycle after a device cycle on the caller's stream");
            }
            CHECK(cudaStreamSynchronize(a) == cudaSuccess);
            const bpx_pair *copied = (const bpx_pair *)(seen + 1);
            CHECK_MSG(seen[0] == want && pairs_first_diff(copied, want, want_pairs, want) == want,
                      "n=%u, then %s: the caller's copy on its stream holds %llu pairs, want the "
                      "first cycle's %zu",
                      n, next_names[next], seen[0], want);
            bpx_world_destroy(cuda);
            CHECK(cudaFreeHost(seen) == cudaSuccess);
        }
        CHECK(cudaStreamDestroy(a) == cudaSuccess && cudaStreamDestroy(b) == cudaSuccess);
        bpx_world_destroy(first);
        bpx_world_destroy(second);
        cudaFree(d_boxes);
        free(moved);
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

int main(int argc, char **argv)
{
    quick = argc > 1 && strcmp(argv[1], "--quick") == 0;
    bpx_set_logger(print_log, NULL);
    bpx_backend_info info = bpx_backend_query(BPX_BACKEND_CUDA);
    printf("cuda: %s%s\n",
           info.available ? info.detail : "unavailable: ", info.available ? "" : info.reason);
    if (!info.available)
        return check_finish("test_cuda_device", 0); // test_cuda checks the refusals
#if BPX_TEST_CUDA
    test_device_resident();
    test_device_errors(600);  // one block
    test_device_errors(3000); // the tree
    test_device_first_cycle_growth();
    test_device_room();
    test_device_caller_stream();
    test_device_stream_handoff();
    test_device_bad_count();
    test_device_queries();
    test_centres();
    test_centres_errors(3000);
    test_centres_errors(500);
    test_removed_after_centres(500);  // the small comparator
    test_removed_after_centres(3000); // the tree
#endif
#if BPX_TEST_FAKE_CUDA
    CHECK_MSG(bpx_fake_cuda_live_blocks() == 0, "%ld device or pinned allocations never freed",
              bpx_fake_cuda_live_blocks());
#endif
    return check_finish("test_cuda_device", 1);
}
