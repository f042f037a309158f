// bpx tests: what the opencl backend's tests share (test_opencl, test_opencl_tree): the logger
// that keeps the backend's messages, worlds on the backend, their counters, and the pairs they
// must find. They see src/ and link OpenCL; without OpenCL in the build only main is compiled.
// SPDX-License-Identifier: MIT
#pragma once

#include <bpx/opencl.h>

#include "pairs_util.h"
#include "scenes.h"

#if BPX_TEST_OPENCL
#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>

#include "opencl/opencl_internal.h"

static inline const char *name_or(const char *s)
{
    return s ? s : "?";
}

// ---------------------------------------------------------------------------------------------
// Logger

static char log_text[1 << 16];
static int log_errors;

static inline void capture_log(int level, const char *message, void *user)
{
    (void)user;
    if (level == 0)
        log_errors++;
    size_t used = strlen(log_text);
    snprintf(log_text + used, sizeof log_text - used, "%s\n", message);
}

static inline void log_reset(void)
{
    log_text[0] = '\0';
    log_errors = 0;
}

// ---------------------------------------------------------------------------------------------
// Starting

/// Prints whether the backend is available here, as `name: opencl available: <device>`.
static inline bpx_backend_info opencl_info(const char *name)
{
    bpx_backend_info info = bpx_backend_query(BPX_BACKEND_OPENCL);
    printf("%s: opencl %s: %s\n", name, info.available ? "available" : "unavailable",
           info.available ? info.detail : name_or(info.reason));
    return info;
}

/// What main returns when the backend is unavailable: skipped (77) only when there is no
/// OpenCL at all (not in this build, no platform); any other reason is a failure.
static inline int opencl_unavailable(const char *name, bpx_backend_info info)
{
    const char *reason = name_or(info.reason);
    if (strcmp(reason, "not in this build") == 0 || strcmp(reason, "no OpenCL platform") == 0)
        return check_finish(name, 0);
    CHECK_MSG(info.available, "opencl unavailable: %s", reason);
    return check_finish(name, 1);
}

// ---------------------------------------------------------------------------------------------
// Worlds and their pairs

/// A comparator path: the method, forced block size and first pair buffer (0: the defaults).
typedef struct path {
    const char *name;
    int method;
    uint32_t block_boxes;
    uint32_t pair_capacity;
} path;

static inline bpx_world_def opencl_def(void)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_OPENCL;
    return def;
}

static inline bpx_world *make(const bpx_world_def *def)
{
    bpx_world *world = NULL;
    bpx_status s = bpx_world_create(def, &world);
    CHECK_MSG(s == BPX_OK, "create: %s", check_status_name(s));
    return s == BPX_OK ? world : NULL;
}

static inline bpx__opencl_counters counters(const bpx_world *world)
{
    bpx__opencl_counters c;
    memset(&c, 0, sizeof c);
    CHECK(bpx__opencl_get_counters(world, &c));
    return c;
}

/// set_boxes + collide on world, byte for byte against want.
static inline void check_world(bpx_world *world, const bpx_box *boxes, uint32_t n,
                               const pair_list *want)
{
    CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
    bpx_status s = bpx_world_collide(world);
    CHECK_MSG(s == BPX_OK, "collide: %s (%s)", check_status_name(s),
              bpx_world_error(world)->message);
    size_t count = 0;
    const bpx_pair *pairs = bpx_world_pairs(world, &count);
    CHECK_PAIRS_EQ(want->pairs, want->count, pairs, count);
    CHECK_EQ_U64(bpx_world_stats(world).pair_count, want->count);
}

/// The pairs of boxes[0 .. n) by one backend's bpx_find_pairs.
static inline void pairs_of(const bpx_box *boxes, uint32_t n, bpx_backend backend, pair_list *out)
{
    size_t count = 0;
    bpx_pair probe;
    bpx_status s = bpx_find_pairs(boxes, n, backend, &probe, 0, &count, NULL);
    CHECK(s == BPX_OK || s == BPX_ERR_CAPACITY);
    pair_list_reserve(out, count ? count : 1);
    CHECK_STATUS(bpx_find_pairs(boxes, n, backend, out->pairs, count, &out->count, NULL), BPX_OK);
}

static inline void reference_pairs(const bpx_box *boxes, uint32_t n, pair_list *out)
{
    pairs_of(boxes, n, BPX_BACKEND_REFERENCE, out);
}

// ---------------------------------------------------------------------------------------------
// Queries while the boxes or centres are in a device buffer

/// A query and a batch of one are refused with BAD_STATE, naming the reason, writing nothing.
static inline void check_query_refused(bpx_world *world, const bpx_query *q)
{
    bpx_hit hit = {7, 0.5f};
    size_t count = 99, offsets[2] = {5, 5}, total = 99;
    CHECK_STATUS(bpx_world_query(world, q, &hit, 1, &count), BPX_ERR_BAD_STATE);
    CHECK(count == 99 && hit.id == 7);
    const bpx_error *e = bpx_world_error(world);
    CHECK(e->status == BPX_ERR_BAD_STATE && e->index == UINT32_MAX && e->axis == -1);
    CHECK_MSG(strstr(e->message, "device buffer") && strstr(e->message, "set host boxes"),
              "message: %s", e->message);
    CHECK_STATUS(bpx_world_query_batch(world, q, 1, offsets, &hit, 1, &total), BPX_ERR_BAD_STATE);
    CHECK(offsets[0] == 5 && offsets[1] == 5 && total == 99 && hit.id == 7);
    CHECK_MSG(strstr(bpx_world_error(world)->message, "device buffer"), "message: %s",
              bpx_world_error(world)->message);
}

/// The query answers with the ids of boxes[0 .. n) that overlap its region, in id order.
static inline void check_query_sees(bpx_world *world, const bpx_query *q, const bpx_box *boxes,
                                    uint32_t n)
{
    size_t count = 0, total = 0, want = 0;
    bpx_status s = bpx_world_query(world, q, NULL, 0, &count);
    CHECK_MSG(s == BPX_OK || s == BPX_ERR_CAPACITY, "query: %s (%s)", check_status_name(s),
              bpx_world_error(world)->message);
    const bpx_hit *hits = bpx_world_query_hits(world, NULL, NULL, &total);
    bool same = total == count;
    for (uint32_t i = 0; i < n; i++)
        if (bpx_overlap(&boxes[i], &q->box)) {
            same &= want < total && hits[want].id == i;
            want++;
        }
    CHECK_MSG(same && want == total && want > 0, "%zu hits, want %zu", total, want);
}

#endif
