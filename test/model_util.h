// bpx tests: helpers shared by test_model and test_model_errors. SPDX-License-Identifier: MIT
#pragma once

#include <time.h>

#include <bpx/model.h>

#include "pairs_util.h"

static inline double now_s(void)
{
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static inline bpx_model *new_model(const bpx_model_config *config)
{
    bpx_model *model = NULL;
    CHECK_STATUS(bpx_model_create(config, &model), BPX_OK);
    return model;
}

// The reference backend's pairs, through a world kept by the caller.
static inline void reference_pairs(bpx_world *reference, const bpx_box *boxes, uint32_t n,
                                   pair_list *out)
{
    out->count = 0;
    CHECK_STATUS(bpx_world_set_boxes(reference, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_collide(reference), BPX_OK);
    size_t count = 0;
    const bpx_pair *pairs = bpx_world_pairs(reference, &count);
    pair_list_set(out, pairs, count);
}

static inline bpx_world *reference_world(void)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_REFERENCE;
    bpx_world *world = NULL;
    CHECK_STATUS(bpx_world_create(&def, &world), BPX_OK);
    return world;
}
