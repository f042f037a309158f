// bpx tests: checks of the error a call reports, shared by test_errors and test_out_of_memory.
// SPDX-License-Identifier: MIT
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
