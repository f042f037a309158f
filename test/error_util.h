// bpx tests: checks of the error a call reports, and what the allocation-failure tests share
// (test_errors, test_out_of_memory, test_model_errors, test_opencl*). SPDX-License-Identifier: MIT
#pragma once

#include "check.h"

static inline bpx_world *new_world(int workers)
{
    bpx_world_def def = bpx_default_world_def();
    def.worker_count = workers;
    bpx_world *world = NULL;
    CHECK_STATUS(bpx_world_create(&def, &world), BPX_OK);
    return world;
}

static inline void check_error(const bpx_error *e, bpx_status status, uint32_t index, int axis)
{
    CHECK(e != NULL);
    if (!e) {
        return;
    }
    CHECK_MSG(e->status == status, "error status %s, want %s", check_status_name(e->status),
              check_status_name(status));
    CHECK_MSG(e->index == index, "error index %u, want %u", e->index, index);
    CHECK_MSG(e->axis == axis, "error axis %d, want %d", e->axis, axis);
    if (status != BPX_OK) {
        CHECK(e->message[0] != '\0');
        CHECK(memchr(e->message, '\0', sizeof e->message) != NULL);
    }
}

static inline void check_world_error(const bpx_world *w, bpx_status status, uint32_t index,
                                     int axis)
{
    check_error(bpx_world_error(w), status, index, axis);
}

/// What a call may return when an allocation fails under it.
static inline bool ok_or_oom(bpx_status s)
{
    return s == BPX_OK || s == BPX_ERR_OUT_OF_MEMORY;
}

// An allocator that fails on demand, for one thread: install it with
// bpx_set_allocator(budget_alloc, budget_free, &budget_tag) and set budget_left to the number of
// allocations that may succeed before every later one fails (negative: no limit). budget_live
// counts the blocks not yet freed. (test_out_of_memory keeps its own, atomic and checked.)
static long long budget_left = -1;
static long long budget_live;
static int budget_tag; // the user pointer bpx must hand back

static inline void *budget_alloc(size_t size, size_t alignment, void *user)
{
    if (user != &budget_tag || (budget_left >= 0 && budget_left-- == 0))
        return NULL;
    size_t rounded = (size + alignment - 1) / alignment * alignment;
    void *p = aligned_alloc(alignment, rounded ? rounded : alignment);
    budget_live += p != NULL;
    return p;
}

static inline void budget_free(void *memory, void *user)
{
    (void)user;
    budget_live -= memory != NULL;
    free(memory);
}

/// The two-phase form of boxes (load_extents, update_centres): per object and axis the minimum
/// (minus half the size) and the centre, 3 floats per object each.
static inline void extents_of(const bpx_box *boxes, uint32_t n, float *minima, float *centres)
{
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            float half = (boxes[i].max[a] - boxes[i].min[a]) * 0.5f;
            minima[3 * i + a] = -half;
            centres[3 * i + a] = boxes[i].min[a] + half;
        }
}
