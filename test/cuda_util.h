// bpx tests: what test_cuda.c (the host-out cycles) and test_cuda_device.c (the device-resident
// ones) share: the worlds they compare, their comparison, the two-phase mode's split of boxes
// into centres and minima, and (with the CUDA runtime, real or fake) device buffers that have
// landed before a world reads them. Header only, like the other helpers, so that its CHECKs
// count in the including test's harness (check.h). SPDX-License-Identifier: MIT
#pragma once

#include <bpx/cuda.h>

#include "pairs_util.h"

#if BPX_TEST_CUDA
#include <cuda_runtime_api.h>
#endif

// A device failure names the CUDA call and error only through the logger (the world's error
// says DEVICE): printed, a failure on a lent GPU says which call failed and why.
static inline void print_log(int level, const char *message, void *user)
{
    (void)user;
    if (level <= 1)
        fprintf(stderr, "bpx log: %s\n", message);
}

static inline bpx_world *cuda_world(bool events)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_CUDA;
    def.track_events = events;
    bpx_world *w = NULL;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    return w;
}

static inline bpx_world *oracle_world_events(uint32_t n, bool events)
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

static inline bpx_world *oracle_world(uint32_t n)
{
    return oracle_world_events(n, false);
}

static inline bool same_pairs(bpx_world *a, bpx_world *b, const char *what)
{
    size_t na = 0, nb = 0;
    const bpx_pair *pa = bpx_world_pairs(a, &na);
    const bpx_pair *pb = bpx_world_pairs(b, &nb);
    size_t diff = pairs_first_diff(pa, na, pb, nb);
    bool same = na == nb && diff == na;
    CHECK_MSG(same, "%s: %zu vs %zu pairs, first difference at %zu", what, na, nb, diff);
    return same;
}

// The paper's two-phase mode: extents once, then centres. boxes -> centres and origin-centred
// minima (<= 0), as a simulation keeps them.
static inline void split_boxes(const bpx_box *boxes, uint32_t n, float *centres, float *minima)
{
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            float c = 0.5f * boxes[i].min[a] + 0.5f * boxes[i].max[a];
            float half = 0.5f * boxes[i].max[a] - 0.5f * boxes[i].min[a];
            centres[3 * (size_t)i + a] = c;
            minima[3 * (size_t)i + a] = -half;
        }
}

#if BPX_TEST_CUDA
// A copy to the device that has landed before the world reads it: a cudaMemcpy from pageable
// memory may return before its DMA ends, and the world's non-blocking stream does not wait for
// the legacy stream the copy runs on.
static inline bool copy_to_device(void *d, const void *h, size_t bytes)
{
    return cudaMemcpy(d, h, bytes, cudaMemcpyHostToDevice) == cudaSuccess &&
           cudaDeviceSynchronize() == cudaSuccess;
}

static inline bpx_box *to_device(const bpx_box *boxes, uint32_t n)
{
    void *d = NULL;
    CHECK(cudaMalloc(&d, sizeof(bpx_box) * (n ? n : 1)) == cudaSuccess);
    CHECK(copy_to_device(d, boxes, sizeof(bpx_box) * n));
    return d;
}

static inline float *centres_to_device(const float *centres, uint32_t n)
{
    void *d = NULL;
    CHECK(cudaMalloc(&d, 12 * (size_t)(n ? n : 1)) == cudaSuccess);
    CHECK(copy_to_device(d, centres, 12 * (size_t)n));
    return d;
}
#endif
