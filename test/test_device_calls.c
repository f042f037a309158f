// The device calls of include/bpx/opencl.h and include/bpx/cuda.h keep the world's books alike
// (src/core/device.c over each backend's bpx_device_ops). SPDX-License-Identifier: MIT
//
// For every device backend usable here (opencl on PoCL in CI; cuda on the fake device when built
// as test_device_calls_fake_cuda, or on a GPU): a device-resident cycle is no longer the host's
// result, a refused one leaves that result, a refused finish leaves the stats, calls on a world
// of another backend say so, NULL device memory for boxes is refused. Skipped (77) when no
// device backend is usable.
#include <bpx/cuda.h>
#include <bpx/opencl.h>

#include "check.h"
#include "scenes.h"

enum { N = 3000 };

typedef struct device_calls {
    bpx_backend backend;
    bpx_status (*set_boxes)(bpx_world *, const void *, uint32_t);
    bpx_status (*set_centres)(bpx_world *, const void *, uint32_t);
    bpx_status (*collide)(bpx_world *);
    bpx_status (*pairs)(bpx_world *, void **, void **, size_t *);
    bpx_status (*finish)(bpx_world *, size_t *);
} device_calls;

static bpx_status cuda_collide(bpx_world *w)
{
    return bpx_cuda_collide_device(w, NULL);
}

static const device_calls families[] = {
    {BPX_BACKEND_OPENCL, bpx_opencl_set_boxes_device, bpx_opencl_set_centres_device,
     bpx_opencl_collide_device, bpx_opencl_device_pairs, bpx_opencl_finish},
    {BPX_BACKEND_CUDA, bpx_cuda_set_boxes_device, bpx_cuda_set_centres_device, cuda_collide,
     bpx_cuda_device_pairs, bpx_cuda_finish},
};

static bpx_world *make_world(bpx_backend backend, const bpx_box *boxes)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    bpx_world *w = NULL;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    if (w)
        CHECK_STATUS(bpx_world_set_boxes(w, boxes, N), BPX_OK);
    return w;
}

static void check_family(const device_calls *f, const bpx_box *boxes)
{
    const char *name = bpx_backend_name(f->backend);
    check_set_context("%s", name);
    bpx_world *w = make_world(f->backend, boxes);
    bpx_world *other = make_world(BPX_BACKEND_PRUNE, boxes);
    if (!w || !other) {
        bpx_world_destroy(w);
        bpx_world_destroy(other);
        return;
    }

    // A world of another backend: BACKEND_UNAVAILABLE, naming both.
    CHECK_STATUS(f->set_boxes(other, boxes, N), BPX_ERR_BACKEND_UNAVAILABLE);
    CHECK(strstr(bpx_world_error(other)->message, name) != NULL);
    CHECK_STATUS(f->set_centres(other, boxes, N), BPX_ERR_BACKEND_UNAVAILABLE);
    CHECK_STATUS(f->collide(other), BPX_ERR_BACKEND_UNAVAILABLE);
    CHECK_STATUS(f->finish(other, NULL), BPX_ERR_BACKEND_UNAVAILABLE);
    CHECK_STATUS(f->collide(NULL), BPX_ERR_NULL_ARGUMENT);
    // No device memory for boxes that are there: NULL_ARGUMENT, the world as it was.
    CHECK_STATUS(f->set_boxes(w, NULL, N), BPX_ERR_NULL_ARGUMENT);
    CHECK(bpx_world_box_count(w) == N);

    // The host's cycle: its pairs and stats.
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    size_t host = 0;
    CHECK(bpx_world_pairs(w, &host) != NULL && host > 0);
    bpx_cycle_stats before = bpx_world_stats(w);
    CHECK(before.pair_count == host);

    // A refused finish (opencl: no device cycle yet) leaves the stats as they were.
    size_t count = 1;
    if (f->backend == BPX_BACKEND_OPENCL) {
        CHECK_STATUS(f->finish(w, &count), BPX_ERR_BAD_STATE);
        CHECK(count == 0);
        CHECK(bpx_world_stats(w).pair_count == before.pair_count);
        CHECK(bpx_world_stats(w).pair_tests == before.pair_tests);
    }

    // A refused device cycle (filters need the host's pairs) leaves the host's result.
    bpx_world *filtered = make_world(f->backend, boxes);
    uint32_t *ones = malloc(sizeof(uint32_t) * N);
    if (filtered && ones) {
        for (uint32_t i = 0; i < N; i++)
            ones[i] = 0xFFFFFFFFu;
        CHECK_STATUS(bpx_world_set_filters(filtered, NULL, ones, ones, N), BPX_OK);
        CHECK_STATUS(bpx_world_collide(filtered), BPX_OK);
        CHECK_STATUS(f->collide(filtered), BPX_ERR_BAD_STATE);
        size_t kept = 0;
        CHECK(bpx_world_pairs(filtered, &kept) != NULL && kept == host);
    }
    free(ones);
    bpx_world_destroy(filtered);

    // A device cycle: its count is the host's, and the host's pairs are no longer the last
    // cycle's on either backend.
    CHECK_STATUS(f->collide(w), BPX_OK);
    CHECK_STATUS(f->finish(w, &count), BPX_OK);
    CHECK(count == host);
    CHECK(bpx_world_stats(w).pair_count == host);
    void *pairs = NULL, *count_buffer = NULL;
    size_t capacity = 0;
    CHECK_STATUS(f->pairs(w, &pairs, &count_buffer, &capacity), BPX_OK);
    CHECK(pairs != NULL && count_buffer != NULL && capacity >= host);
    size_t left = 1;
    CHECK(bpx_world_pairs(w, &left) == NULL && left == 0);
    size_t copied = 1;
    CHECK_STATUS(bpx_world_copy_pairs(w, NULL, 0, &copied), BPX_OK);
    CHECK(copied == 0);
    // The host's cycle again.
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK(bpx_world_pairs(w, &left) != NULL && left == host);

    bpx_world_destroy(w);
    bpx_world_destroy(other);
}

int main(void)
{
    bpx_box *boxes = malloc(sizeof(bpx_box) * N);
    if (!boxes || scene_generate(SCENE_UNIFORM_DENSITY, N, 11, boxes) != 0) {
        fprintf(stderr, "test_device_calls: no scene\n");
        return 1;
    }
    int ran = 0;
    for (size_t k = 0; k < sizeof families / sizeof families[0]; k++) {
        bpx_backend_info info = bpx_backend_query(families[k].backend);
        if (!info.available) {
            printf("test_device_calls: %s skipped: %s\n", info.name, info.reason);
            continue;
        }
        check_family(&families[k], boxes);
        ran++;
    }
    free(boxes);
    return check_finish("test_device_calls", ran);
}
