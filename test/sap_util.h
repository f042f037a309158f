// bpx tests: the sap tests' harness, shared by test_sap and test_sap_large: a sap world and a
// checking world given the same boxes every cycle, their pairs compared byte for byte, and sap's
// cold cycles counted. SPDX-License-Identifier: MIT
#pragma once

#include <time.h>

#include "pairs_util.h"
#include "scenes.h"

typedef struct duo {
    bpx_world *sap;
    bpx_world *ref;
    pair_list want;
    int cycles;
    int cold;
} duo;

static inline double now_s(void)
{
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static bpx_simd forced_simd = BPX_SIMD_AUTO; // the rebuild's sweep kernel, for sap worlds

static bpx_world *make_world(bpx_backend backend, int workers, bool events)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.simd = backend == BPX_BACKEND_SAP ? forced_simd : BPX_SIMD_AUTO;
    def.worker_count = workers;
    def.track_events = events;
    bpx_world *w = NULL;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    return w;
}

static inline void duo_init(duo *d, int workers)
{
    *d = (duo){0};
    d->sap = make_world(BPX_BACKEND_SAP, workers, true);
    d->ref = make_world(BPX_BACKEND_REFERENCE, 1, false);
}

// The same for tens of thousands of boxes, where the reference's n^2 / 2 tests would take
// seconds a cycle: prune (itself checked against the reference by test_differential) checks.
static inline void duo_init_large(duo *d, int workers)
{
    *d = (duo){0};
    d->sap = make_world(BPX_BACKEND_SAP, workers, true);
    d->ref = make_world(BPX_BACKEND_PRUNE, 1, false);
}

static inline void duo_free(duo *d)
{
    bpx_world_destroy(d->sap);
    bpx_world_destroy(d->ref);
    pair_list_free(&d->want);
}

// Collides both worlds (boxes already given to both) and compares; returns sap's cold flag.
static inline bool duo_collide(duo *d)
{
    CHECK_STATUS(bpx_world_collide(d->ref), BPX_OK);
    CHECK_STATUS(bpx_world_collide(d->sap), BPX_OK);
    size_t want_count = 0, got_count = 0;
    const bpx_pair *want = bpx_world_pairs(d->ref, &want_count);
    const bpx_pair *got = bpx_world_pairs(d->sap, &got_count);
    CHECK_PAIRS_EQ(want, want_count, got, got_count);
    bpx_cycle_stats stats = bpx_world_stats(d->sap);
    CHECK_EQ_U64(stats.pair_count, want_count);
    CHECK(!bpx_world_stats(d->ref).rebuilt); // other backends never set it
    pair_list_set(&d->want, want, want_count);
    d->cycles++;
    d->cold += stats.rebuilt;
    return stats.rebuilt;
}

// One cycle of boxes through set_boxes.
static inline bool duo_step(duo *d, const bpx_box *boxes, uint32_t n)
{
    CHECK_STATUS(bpx_world_set_boxes(d->ref, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_set_boxes(d->sap, boxes, n), BPX_OK);
    return duo_collide(d);
}

// A cycle whose cold flag is known.
#define STEP_EXPECT(d, boxes, n, cold, what)                                                       \
    do {                                                                                           \
        bool got_cold_ = duo_step((d), (boxes), (n));                                              \
        CHECK_MSG(got_cold_ == (cold), "%s: rebuilt=%d, want %d", (what), (int)got_cold_,          \
                  (int)(cold));                                                                    \
    } while (0)

// Fisher-Yates: box slots change owners, so every box jumps somewhere else.
static inline void shuffle(bpx_box *boxes, uint32_t n, scene_rng *r)
{
    for (uint32_t i = n; i > 1; i--) {
        uint32_t j = scene_rng_below(r, i);
        bpx_box t = boxes[i - 1];
        boxes[i - 1] = boxes[j];
        boxes[j] = t;
    }
}

// Box 0 made 16 times as wide on every axis: its extents are then far from the mean, so sap
// mends its endpoint lists rather than the scan list (which wants even extents).
static inline void widen_one(bpx_box *boxes)
{
    for (int a = 0; a < 3; a++) {
        float centre = 0.5f * (boxes[0].min[a] + boxes[0].max[a]);
        float half = 8.0f * (boxes[0].max[a] - boxes[0].min[a]);
        boxes[0].min[a] = centre - half;
        boxes[0].max[a] = centre + half;
    }
}
