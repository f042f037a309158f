// Every error through the public API: exact status, reported index/axis, world state unchanged
// after the error, status strings, and allocation failure at every allocation (no crash, no
// leak).
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdalign.h>
#include <stdatomic.h>

#include "pairs_util.h"
#include "scenes.h"

enum { base_n = 64, bad_index = 37 };

static const char *name_or(const char *s)
{
    return s ? s : "?";
}

static bpx_world *new_world(int workers)
{
    bpx_world_def def = bpx_default_world_def();
    def.worker_count = workers;
    bpx_world *world = NULL;
    CHECK_STATUS(bpx_world_create(&def, &world), BPX_OK);
    return world;
}

static void check_error(const bpx_error *e, bpx_status status, uint32_t index, int axis)
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

static void check_world_error(const bpx_world *w, bpx_status status, uint32_t index, int axis)
{
    check_error(bpx_world_error(w), status, index, axis);
}

// The world still holds n boxes and the pairs `want`, before and after another cycle.
static void check_unchanged(bpx_world *w, uint32_t n, const pair_list *want)
{
    CHECK_EQ_U64(bpx_world_box_count(w), n);
    size_t count = 0;
    const bpx_pair *pairs = bpx_world_pairs(w, &count);
    CHECK_PAIRS_EQ(want->pairs, want->count, pairs, count);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    pairs = bpx_world_pairs(w, &count);
    CHECK_PAIRS_EQ(want->pairs, want->count, pairs, count);
}

static void collide_and_keep(bpx_world *w, pair_list *out)
{
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    size_t count = 0;
    const bpx_pair *pairs = bpx_world_pairs(w, &count);
    pair_list_set(out, pairs, count);
}

// ---------------------------------------------------------------------------------------------

static void test_status_strings(void)
{
    check_set_context("status strings");
    for (int s = 0; s < BPX_STATUS_COUNT; s++) {
        const char *text = bpx_status_string((bpx_status)s);
        const char *name = bpx_status_name((bpx_status)s);
        CHECK(text && text[0]);
        CHECK(name && strncmp(name, "BPX_", 4) == 0);
        if (!text || !name) {
            continue;
        }
        for (int t = 0; t < s; t++) {
            CHECK_MSG(strcmp(text, name_or(bpx_status_string((bpx_status)t))) != 0, "%d vs %d", s,
                      t);
            CHECK_MSG(strcmp(name, name_or(bpx_status_name((bpx_status)t))) != 0, "%d vs %d", s,
                      t);
        }
    }
    CHECK(strcmp(name_or(bpx_status_string(BPX_OK)), "ok") == 0);
    CHECK(strcmp(name_or(bpx_status_name(BPX_OK)), "BPX_OK") == 0);
    CHECK(strcmp(name_or(bpx_status_name(BPX_ERR_NOT_FINITE)), "BPX_ERR_NOT_FINITE") == 0);
    const int out_of_range[] = {BPX_STATUS_COUNT, BPX_STATUS_COUNT + 1, -1, 1000, INT_MAX, INT_MIN};
    for (size_t k = 0; k < sizeof out_of_range / sizeof out_of_range[0]; k++) {
        bpx_status s = (bpx_status)out_of_range[k];
        const char *text = bpx_status_string(s);
        const char *name = bpx_status_name(s);
        CHECK_MSG(text && strcmp(text, "unknown status") == 0, "value %d", out_of_range[k]);
        CHECK_MSG(name && name[0], "value %d", out_of_range[k]);
    }
    const char *version = bpx_version();
    CHECK(version && strcmp(version, "0.1.0") == 0);
}

static void test_names(void)
{
    check_set_context("backend and simd names");
    static const char *const backends[] = {"auto", "reference", "brute"};
    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        const char *name = bpx_backend_name((bpx_backend)b);
        CHECK(name && name[0]);
        if (b < 3) {
            CHECK(name && strcmp(name, backends[b]) == 0);
        }
        bpx_backend back = BPX_BACKEND_COUNT;
        CHECK_STATUS(bpx_backend_from_name(name_or(name), &back), BPX_OK);
        CHECK(back == (bpx_backend)b);
        bpx_backend_info info = bpx_backend_query((bpx_backend)b);
        CHECK(info.backend == (bpx_backend)b);
        CHECK(info.name && name && strcmp(info.name, name) == 0);
        CHECK(info.reason != NULL);
        CHECK(memchr(info.detail, '\0', sizeof info.detail) != NULL);
    }
    CHECK(bpx_backend_query(BPX_BACKEND_REFERENCE).available);
    CHECK(!bpx_backend_query(BPX_BACKEND_COUNT).available);
    CHECK(bpx_backend_name(BPX_BACKEND_COUNT) == NULL);
    CHECK(bpx_backend_name((bpx_backend)-1) == NULL);
    bpx_backend backend = BPX_BACKEND_BRUTE;
    CHECK_STATUS(bpx_backend_from_name("nope", &backend), BPX_ERR_UNKNOWN_BACKEND);
    CHECK_STATUS(bpx_backend_from_name("", &backend), BPX_ERR_UNKNOWN_BACKEND);
    CHECK_STATUS(bpx_backend_from_name("brute ", &backend), BPX_ERR_UNKNOWN_BACKEND);
    CHECK(backend == BPX_BACKEND_BRUTE); // untouched on error
    CHECK_STATUS(bpx_backend_from_name(NULL, &backend), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_backend_from_name("brute", NULL), BPX_ERR_NULL_ARGUMENT);

    static const char *const simds[] = {"auto", "scalar", "sse2", "avx2", "avx512", "neon"};
    static const int lanes[] = {0, 1, 4, 8, 16, 4};
    for (int s = 0; s < BPX_SIMD_COUNT; s++) {
        const char *name = bpx_simd_name((bpx_simd)s);
        CHECK(name && strcmp(name, simds[s]) == 0);
        bpx_simd back = BPX_SIMD_COUNT;
        CHECK_STATUS(bpx_simd_from_name(simds[s], &back), BPX_OK);
        CHECK(back == (bpx_simd)s);
        if (s != BPX_SIMD_AUTO) {
            CHECK_MSG(bpx_simd_lanes((bpx_simd)s) == lanes[s], "%s lanes %d", simds[s],
                      bpx_simd_lanes((bpx_simd)s));
        }
    }
    CHECK(bpx_simd_name(BPX_SIMD_COUNT) == NULL);
    bpx_simd simd = BPX_SIMD_SCALAR;
    CHECK(bpx_simd_from_name("avx1024", &simd) != BPX_OK);
    CHECK(simd == BPX_SIMD_SCALAR);
    CHECK_STATUS(bpx_simd_from_name(NULL, &simd), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_simd_from_name("avx2", NULL), BPX_ERR_NULL_ARGUMENT);
    CHECK(bpx_simd_supported(BPX_SIMD_SCALAR));
    CHECK(bpx_simd_best() != BPX_SIMD_AUTO && bpx_simd_supported(bpx_simd_best()));
    CHECK(bpx_simd_lanes(bpx_simd_best()) >= 1);
#if defined(__x86_64__) || defined(_M_X64) || defined(__i386__)
    CHECK(!bpx_simd_supported(BPX_SIMD_NEON));
    CHECK(bpx_simd_supported(BPX_SIMD_SSE2));
#endif
}

// ---------------------------------------------------------------------------------------------

static void expect_create_fails(const bpx_world_def *def, bpx_status want, const char *what)
{
    check_set_context("create: %s", what);
    bpx_world *world = (bpx_world *)&world; // any non-NULL value: must be reset to NULL
    CHECK_STATUS(bpx_world_create(def, &world), want);
    CHECK(world == NULL);
    bpx_world_destroy(world == (bpx_world *)&world ? NULL : world);
}

static void *inline_enqueue(bpx_task_fn *task, int item_count, int min_range, void *task_context,
                            void *user_context)
{
    (void)min_range;
    (void)user_context;
    task(0, item_count, 0, task_context);
    return NULL;
}

static void inline_finish(void *user_task, void *user_context)
{
    (void)user_task;
    (void)user_context;
}

static void test_create_errors(void)
{
    bpx_world_def def = bpx_default_world_def();
    CHECK(def.backend == BPX_BACKEND_AUTO && def.simd == BPX_SIMD_AUTO);
    CHECK(def.enqueue_task == NULL && def.finish_task == NULL);
    expect_create_fails(NULL, BPX_ERR_NULL_ARGUMENT, "NULL def");
    check_set_context("create: NULL out");
    CHECK_STATUS(bpx_world_create(&def, NULL), BPX_ERR_NULL_ARGUMENT);

    const int bad_workers[] = {-1, 257, 100000, INT_MIN, INT_MAX};
    for (size_t k = 0; k < sizeof bad_workers / sizeof bad_workers[0]; k++) {
        def = bpx_default_world_def();
        def.worker_count = bad_workers[k];
        char what[64];
        snprintf(what, sizeof what, "worker_count %d", bad_workers[k]);
        expect_create_fails(&def, BPX_ERR_INVALID_ARGUMENT, what);
    }

    def = bpx_default_world_def();
    def.enqueue_task = inline_enqueue;
    expect_create_fails(&def, BPX_ERR_INVALID_ARGUMENT, "enqueue hook alone");
    def = bpx_default_world_def();
    def.finish_task = inline_finish;
    expect_create_fails(&def, BPX_ERR_INVALID_ARGUMENT, "finish hook alone");

    // Edge values that are valid; 256 workers with hooks starts no thread.
    check_set_context("create: valid edge values");
    const int good_workers[] = {0, 1, 256};
    for (size_t k = 0; k < sizeof good_workers / sizeof good_workers[0]; k++) {
        def = bpx_default_world_def();
        def.worker_count = good_workers[k];
        def.enqueue_task = inline_enqueue;
        def.finish_task = inline_finish;
        def.spin_us = -1;
        def.capacity_hint = 100;
        bpx_world *world = NULL;
        CHECK_STATUS(bpx_world_create(&def, &world), BPX_OK);
        bpx_box boxes[2] = {{{0, 0, 0}, {1, 1, 1}}, {{1, 1, 1}, {2, 2, 2}}};
        CHECK_STATUS(bpx_world_set_boxes(world, boxes, 2), BPX_OK);
        CHECK_STATUS(bpx_world_collide(world), BPX_OK);
        CHECK_EQ_U64(bpx_world_stats(world).pair_count, 1);
        bpx_world_destroy(world);
    }

    // Unsupported SIMD widths (NEON on x86, AVX-512 on older CPUs) and out-of-range enums.
    int unsupported = 0;
    for (int s = BPX_SIMD_SCALAR; s < BPX_SIMD_COUNT; s++) {
        if (bpx_simd_supported((bpx_simd)s)) {
            continue;
        }
        unsupported++;
        const bpx_backend users[] = {BPX_BACKEND_BRUTE, BPX_BACKEND_AUTO};
        for (int u = 0; u < 2; u++) {
            def = bpx_default_world_def();
            def.backend = users[u];
            def.simd = (bpx_simd)s;
            char what[64];
            snprintf(what, sizeof what, "backend %s, unsupported simd %s",
                     name_or(bpx_backend_name(users[u])), name_or(bpx_simd_name((bpx_simd)s)));
            expect_create_fails(&def, BPX_ERR_BACKEND_UNAVAILABLE, what);
        }
    }
    printf("  %d SIMD widths unsupported here, each refused\n", unsupported);
    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        if (!bpx_backend_query((bpx_backend)b).available) {
            def = bpx_default_world_def();
            def.backend = (bpx_backend)b;
            expect_create_fails(&def, BPX_ERR_BACKEND_UNAVAILABLE, "unavailable backend");
        }
    }
    const int bad_backends[] = {BPX_BACKEND_COUNT, -1, 1000};
    for (size_t k = 0; k < sizeof bad_backends / sizeof bad_backends[0]; k++) {
        def = bpx_default_world_def();
        def.backend = (bpx_backend)bad_backends[k];
        check_set_context("create: backend value %d", bad_backends[k]);
        bpx_world *world = NULL;
        bpx_status s = bpx_world_create(&def, &world);
        CHECK_MSG(s == BPX_ERR_INVALID_ARGUMENT || s == BPX_ERR_UNKNOWN_BACKEND ||
                      s == BPX_ERR_BACKEND_UNAVAILABLE,
                  "got %s", check_status_name(s));
        CHECK(world == NULL);
        bpx_world_destroy(world);
    }
    const int bad_simds[] = {BPX_SIMD_COUNT, -1};
    for (size_t k = 0; k < sizeof bad_simds / sizeof bad_simds[0]; k++) {
        def = bpx_default_world_def();
        def.backend = BPX_BACKEND_BRUTE;
        def.simd = (bpx_simd)bad_simds[k];
        check_set_context("create: simd value %d", bad_simds[k]);
        bpx_world *world = NULL;
        bpx_status s = bpx_world_create(&def, &world);
        CHECK_MSG(s == BPX_ERR_INVALID_ARGUMENT || s == BPX_ERR_BACKEND_UNAVAILABLE, "got %s",
                  check_status_name(s));
        CHECK(world == NULL);
        bpx_world_destroy(world);
    }
    bpx_world_destroy(NULL);
}

// ---------------------------------------------------------------------------------------------

static void test_null_arguments(const bpx_box *boxes)
{
    check_set_context("NULL arguments");
    bpx_pair out[8];
    size_t count = 0;
    CHECK_STATUS(bpx_world_set_boxes(NULL, boxes, base_n), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_world_collide(NULL), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_world_collide_into(NULL, out, 8, &count), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_world_copy_pairs(NULL, out, 8, &count), BPX_ERR_NULL_ARGUMENT);
    float minima[3] = {-1, -1, -1};
    CHECK_STATUS(bpx_world_load_extents(NULL, minima, 1), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_world_update_centres(NULL, minima), BPX_ERR_NULL_ARGUMENT);

    bpx_world *w = new_world(1);
    if (!w) {
        return;
    }
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, base_n), BPX_OK);
    check_world_error(w, BPX_OK, UINT32_MAX, -1);
    pair_list want = {0};
    collide_and_keep(w, &want);
    CHECK(want.count > 0);

    CHECK_STATUS(bpx_world_set_boxes(w, NULL, 5), BPX_ERR_NULL_ARGUMENT);
    check_world_error(w, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1);
    check_unchanged(w, base_n, &want);
    check_world_error(w, BPX_OK, UINT32_MAX, -1);

    CHECK_STATUS(bpx_world_collide_into(w, out, 8, NULL), BPX_ERR_NULL_ARGUMENT);
    check_unchanged(w, base_n, &want);
    CHECK_STATUS(bpx_world_collide_into(w, NULL, 8, &count), BPX_ERR_NULL_ARGUMENT);
    check_unchanged(w, base_n, &want);
    CHECK_STATUS(bpx_world_copy_pairs(w, out, 8, NULL), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_world_copy_pairs(w, NULL, 8, &count), BPX_ERR_NULL_ARGUMENT);
    check_unchanged(w, base_n, &want);

    CHECK_STATUS(bpx_world_load_extents(w, NULL, 5), BPX_ERR_NULL_ARGUMENT);
    check_world_error(w, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1);
    check_unchanged(w, base_n, &want);

    // Empty input needs no pointer.
    CHECK_STATUS(bpx_world_set_boxes(w, NULL, 0), BPX_OK);
    CHECK_EQ_U64(bpx_world_box_count(w), 0);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK_EQ_U64(bpx_world_stats(w).pair_count, 0);
    count = 99;
    CHECK(bpx_world_pairs(w, &count) != NULL || count == 0);
    CHECK_EQ_U64(count, 0);
    CHECK_STATUS(bpx_world_load_extents(w, NULL, 0), BPX_OK);
    CHECK_EQ_U64(bpx_world_box_count(w), 0);
    bpx_world_destroy(w);
    pair_list_free(&want);

    bpx_error err;
    count = 99;
    CHECK_STATUS(bpx_find_pairs(NULL, 5, BPX_BACKEND_REFERENCE, out, 8, &count, &err),
                 BPX_ERR_NULL_ARGUMENT);
    check_error(&err, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1);
    CHECK_STATUS(bpx_find_pairs(boxes, base_n, BPX_BACKEND_REFERENCE, out, 8, NULL, &err),
                 BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_find_pairs(boxes, base_n, BPX_BACKEND_REFERENCE, NULL, 8, &count, NULL),
                 BPX_ERR_NULL_ARGUMENT);
    count = 99;
    CHECK_STATUS(bpx_find_pairs(NULL, 0, BPX_BACKEND_REFERENCE, out, 8, &count, &err), BPX_OK);
    CHECK_EQ_U64(count, 0);
    CHECK_STATUS(bpx_validate_boxes(NULL, 5, &err), BPX_ERR_NULL_ARGUMENT);
    check_error(&err, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1);
    CHECK_STATUS(bpx_validate_boxes(NULL, 0, &err), BPX_OK);
    CHECK_STATUS(bpx_validate_boxes(boxes, base_n, NULL), BPX_OK);
}

// ---------------------------------------------------------------------------------------------

// One bad box at `index` through every entry point that takes boxes.
static void expect_bad_boxes(bpx_world *w, const pair_list *want, const bpx_box *bad, uint32_t n,
                             bpx_status status, uint32_t index, int axis)
{
    CHECK_STATUS(bpx_world_set_boxes(w, bad, n), status);
    check_world_error(w, status, index, axis);
    check_unchanged(w, base_n, want);

    bpx_error err;
    memset(&err, 0, sizeof err);
    CHECK_STATUS(bpx_validate_boxes(bad, n, &err), status);
    check_error(&err, status, index, axis);
    CHECK_STATUS(bpx_validate_boxes(bad, n, NULL), status);

    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        if (!bpx_backend_query((bpx_backend)b).available) {
            continue;
        }
        bpx_pair out[4];
        size_t count = 0;
        memset(&err, 0, sizeof err);
        CHECK_STATUS(bpx_find_pairs(bad, n, (bpx_backend)b, out, 4, &count, &err), status);
        check_error(&err, status, index, axis);
        CHECK_STATUS(bpx_find_pairs(bad, n, (bpx_backend)b, out, 4, &count, NULL), status);
    }
}

static void test_bad_boxes(const bpx_box *boxes)
{
    bpx_world *w = new_world(2);
    if (!w) {
        return;
    }
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, base_n), BPX_OK);
    pair_list want = {0};
    collide_and_keep(w, &want);
    bpx_box bad[base_n];

    const float non_finite[] = {NAN, -NAN, INFINITY, -INFINITY};
    const char *const non_finite_names[] = {"nan", "-nan", "inf", "-inf"};
    for (int c = 0; c < 6; c++) {
        for (int v = 0; v < 4; v++) {
            // Each value at one index; NaN also at the first and last box.
            const uint32_t at[] = {bad_index, 0, base_n - 1};
            for (int k = 0; k < (v == 0 ? 3 : 1); k++) {
                check_set_context("%s in %s[%d] of box %u", non_finite_names[v],
                                  c < 3 ? "min" : "max", c % 3, at[k]);
                memcpy(bad, boxes, sizeof bad);
                float *coords = (float *)&bad[at[k]];
                coords[c] = non_finite[v];
                expect_bad_boxes(w, &want, bad, base_n, BPX_ERR_NOT_FINITE, at[k], c % 3);
            }
        }
    }

    for (int a = 0; a < 3; a++) {
        check_set_context("min > max on axis %d", a);
        memcpy(bad, boxes, sizeof bad);
        bad[bad_index].min[a] = bad[bad_index].max[a] + 1.0f;
        expect_bad_boxes(w, &want, bad, base_n, BPX_ERR_MIN_GREATER_THAN_MAX, bad_index, a);
        // One ulp is enough.
        memcpy(bad, boxes, sizeof bad);
        bad[bad_index].min[a] = nextafterf(bad[bad_index].max[a], INFINITY);
        expect_bad_boxes(w, &want, bad, base_n, BPX_ERR_MIN_GREATER_THAN_MAX, bad_index, a);
        // Swapped bounds on the last box of an otherwise valid array.
        memcpy(bad, boxes, sizeof bad);
        float t = bad[base_n - 1].min[a];
        bad[base_n - 1].min[a] = bad[base_n - 1].max[a];
        bad[base_n - 1].max[a] = t;
        expect_bad_boxes(w, &want, bad, base_n, BPX_ERR_MIN_GREATER_THAN_MAX, base_n - 1, a);
    }

    // Precedence: the first offending box is named; within a box a non-finite coordinate wins
    // over min > max.
    check_set_context("precedence");
    memcpy(bad, boxes, sizeof bad);
    bad[3].min[1] = bad[3].max[1] + 1.0f;
    bad[bad_index].max[2] = NAN;
    expect_bad_boxes(w, &want, bad, base_n, BPX_ERR_MIN_GREATER_THAN_MAX, 3, 1);
    memcpy(bad, boxes, sizeof bad);
    bad[5].min[0] = INFINITY; // also min > max
    bad[9].max[1] = NAN;
    expect_bad_boxes(w, &want, bad, base_n, BPX_ERR_NOT_FINITE, 5, 0);
    memcpy(bad, boxes, sizeof bad);
    bad[bad_index].min[0] = bad[bad_index].max[0] + 1.0f;
    bad[bad_index].min[2] = NAN;
    expect_bad_boxes(w, &want, bad, base_n, BPX_ERR_NOT_FINITE, bad_index, 2);
    memcpy(bad, boxes, sizeof bad);
    bad[20].min[2] = bad[20].max[2] + 1.0f;
    bad[30].min[0] = bad[30].max[0] + 1.0f;
    expect_bad_boxes(w, &want, bad, base_n, BPX_ERR_MIN_GREATER_THAN_MAX, 20, 2);

    // Valid edge cases: signed zeros compare equal, the largest finite floats, subnormals.
    check_set_context("valid edge boxes");
    const float tm = FLT_TRUE_MIN;
    bpx_box edge[5] = {
        {{-0.0f, 0.0f, -0.0f}, {0.0f, -0.0f, -0.0f}},
        {{-FLT_MAX, -FLT_MAX, -FLT_MAX}, {FLT_MAX, FLT_MAX, FLT_MAX}},
        {{-tm, -tm, 0.0f}, {0.0f, tm, tm}},
        {{1.0f, 1.0f, 1.0f}, {1.0f, 1.0f, 1.0f}},
        {{2 * tm, 0.0f, 0.0f}, {3 * tm, 0.0f, 0.0f}}, // apart from 0 and 2 unless flushed to 0
    };
    CHECK_STATUS(bpx_validate_boxes(edge, 5, NULL), BPX_OK);
    CHECK_STATUS(bpx_world_set_boxes(w, edge, 5), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    size_t count = 0;
    const bpx_pair *pairs = bpx_world_pairs(w, &count);
    // Box 1 covers everything; 0 and 2 meet at the origin; 3 and 4 meet only box 1.
    const bpx_pair expect[] = {{0, 1}, {0, 2}, {1, 2}, {1, 3}, {1, 4}};
    CHECK_PAIRS_EQ(expect, 5, pairs, count);

    pair_list_free(&want);
    bpx_world_destroy(w);
}

static void test_too_many_boxes(const bpx_box *boxes)
{
    // A one-box array: the library must reject n before reading anything past it (ASan would
    // catch a read).
    bpx_box *one = check_alloc(sizeof(bpx_box));
    *one = boxes[0];
    float *minima = check_alloc(sizeof(float) * 3);
    minima[0] = minima[1] = minima[2] = -1.0f;
    bpx_world *w = new_world(1);
    if (!w) {
        free(one);
        free(minima);
        return;
    }
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, base_n), BPX_OK);
    pair_list want = {0};
    collide_and_keep(w, &want);
    const uint32_t too_many[] = {BPX_MAX_BOXES + 1u, UINT32_MAX};
    for (int k = 0; k < 2; k++) {
        uint32_t n = too_many[k];
        check_set_context("n = %u", n);
        CHECK_STATUS(bpx_world_set_boxes(w, one, n), BPX_ERR_TOO_MANY_BOXES);
        check_world_error(w, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1);
        check_unchanged(w, base_n, &want);
        CHECK_STATUS(bpx_world_load_extents(w, minima, n), BPX_ERR_TOO_MANY_BOXES);
        check_world_error(w, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1);
        check_unchanged(w, base_n, &want);
        bpx_error err;
        CHECK_STATUS(bpx_validate_boxes(one, n, &err), BPX_ERR_TOO_MANY_BOXES);
        CHECK(err.status == BPX_ERR_TOO_MANY_BOXES);
        for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
            if (!bpx_backend_query((bpx_backend)b).available) {
                continue;
            }
            bpx_pair out[4];
            size_t count = 0;
            CHECK_STATUS(bpx_find_pairs(one, n, (bpx_backend)b, out, 4, &count, &err),
                         BPX_ERR_TOO_MANY_BOXES);
            CHECK(err.status == BPX_ERR_TOO_MANY_BOXES);
        }
    }
    bpx_world_destroy(w);
    pair_list_free(&want);
    free(one);
    free(minima);
}

// ---------------------------------------------------------------------------------------------

static void test_updater_errors(const bpx_box *boxes)
{
    float minima[3 * base_n];
    float centres[3 * base_n];
    for (uint32_t i = 0; i < base_n; i++) {
        for (int a = 0; a < 3; a++) {
            float half = (boxes[i].max[a] - boxes[i].min[a]) * 0.5f;
            minima[3 * i + a] = -half;
            centres[3 * i + a] = boxes[i].min[a] + half;
        }
    }
    bpx_world *w = new_world(2);
    if (!w) {
        return;
    }
    check_set_context("update_centres before load_extents");
    CHECK_STATUS(bpx_world_update_centres(w, centres), BPX_ERR_BAD_STATE);
    check_world_error(w, BPX_ERR_BAD_STATE, UINT32_MAX, -1);
    CHECK_EQ_U64(bpx_world_box_count(w), 0);

    check_set_context("load_extents errors on a fresh world");
    float bad[3 * base_n];
    for (int a = 0; a < 3; a++) {
        memcpy(bad, minima, sizeof bad);
        bad[3 * bad_index + a] = 0.5f;
        CHECK_STATUS(bpx_world_load_extents(w, bad, base_n), BPX_ERR_MIN_GREATER_THAN_MAX);
        check_world_error(w, BPX_ERR_MIN_GREATER_THAN_MAX, bad_index, a);
        CHECK_EQ_U64(bpx_world_box_count(w), 0);
        CHECK_STATUS(bpx_world_update_centres(w, centres), BPX_ERR_BAD_STATE);
    }

    check_set_context("load_extents + update_centres");
    CHECK_STATUS(bpx_world_load_extents(w, minima, base_n), BPX_OK);
    check_world_error(w, BPX_OK, UINT32_MAX, -1);
    CHECK_EQ_U64(bpx_world_box_count(w), base_n);
    CHECK_STATUS(bpx_world_update_centres(w, centres), BPX_OK);
    pair_list want = {0};
    collide_and_keep(w, &want);
    CHECK(want.count > 0);

    const float non_finite[] = {NAN, INFINITY, -INFINITY};
    for (int a = 0; a < 3; a++) {
        // Extents: a positive, NaN or infinite minimum; the loaded extents stay.
        check_set_context("load_extents bad minimum axis %d", a);
        memcpy(bad, minima, sizeof bad);
        bad[3 * bad_index + a] = FLT_TRUE_MIN;
        CHECK_STATUS(bpx_world_load_extents(w, bad, base_n), BPX_ERR_MIN_GREATER_THAN_MAX);
        check_world_error(w, BPX_ERR_MIN_GREATER_THAN_MAX, bad_index, a);
        check_unchanged(w, base_n, &want);
        for (int v = 0; v < 3; v++) {
            memcpy(bad, minima, sizeof bad);
            bad[3 * bad_index + a] = non_finite[v];
            CHECK_STATUS(bpx_world_load_extents(w, bad, base_n), BPX_ERR_NOT_FINITE);
            check_world_error(w, BPX_ERR_NOT_FINITE, bad_index, a);
            check_unchanged(w, base_n, &want);
        }
        // Centres: non-finite; the previous boxes stay.
        check_set_context("update_centres bad centre axis %d", a);
        for (int v = 0; v < 3; v++) {
            memcpy(bad, centres, sizeof bad);
            bad[3 * bad_index + a] = non_finite[v];
            CHECK_STATUS(bpx_world_update_centres(w, bad), BPX_ERR_NOT_FINITE);
            check_world_error(w, BPX_ERR_NOT_FINITE, bad_index, a);
            check_unchanged(w, base_n, &want);
        }
        // The extents must still be the ones loaded: the same centres give the same pairs.
        CHECK_STATUS(bpx_world_update_centres(w, centres), BPX_OK);
        check_unchanged(w, base_n, &want);
    }
    CHECK_STATUS(bpx_world_update_centres(w, NULL), BPX_ERR_NULL_ARGUMENT);
    check_unchanged(w, base_n, &want);

    // Finite centre + finite extent overflowing: 3e38 + 3e38 = inf in float.
    check_set_context("update_centres overflow");
    float big_minima[3 * base_n];
    memcpy(big_minima, minima, sizeof big_minima);
    for (int a = 0; a < 3; a++) {
        big_minima[3 * bad_index + a] = -3e38f;
    }
    CHECK_STATUS(bpx_world_load_extents(w, big_minima, base_n), BPX_OK);
    float safe[3 * base_n];
    memcpy(safe, centres, sizeof safe);
    safe[3 * bad_index + 0] = safe[3 * bad_index + 1] = safe[3 * bad_index + 2] = 0.0f;
    CHECK_STATUS(bpx_world_update_centres(w, safe), BPX_OK);
    pair_list big_want = {0};
    collide_and_keep(w, &big_want);
    for (int a = 0; a < 3; a++) {
        const float overflowing[] = {3e38f, -3e38f};
        for (int v = 0; v < 2; v++) {
            memcpy(bad, safe, sizeof bad);
            bad[3 * bad_index + a] = overflowing[v];
            CHECK_STATUS(bpx_world_update_centres(w, bad), BPX_ERR_NOT_FINITE);
            check_world_error(w, BPX_ERR_NOT_FINITE, bad_index, a);
            check_unchanged(w, base_n, &big_want);
        }
    }
    pair_list_free(&want);
    pair_list_free(&big_want);
    bpx_world_destroy(w);
}

// ---------------------------------------------------------------------------------------------
// Allocation failure

static atomic_llong fa_budget; // successful allocations left; negative: unlimited
static atomic_llong fa_live;   // allocations not yet freed
static atomic_int fa_misuse;   // bad alignment, foreign pointer or wrong user pointer
static atomic_llong fa_failed;
static int fa_tag;

typedef struct fa_header {
    alignas(64) size_t magic;
} fa_header;

static void *fa_alloc(size_t size, size_t alignment, void *user)
{
    if (user != &fa_tag || alignment == 0 || (alignment & (alignment - 1)) != 0 ||
        alignment > 4096) {
        atomic_fetch_add(&fa_misuse, 1);
        return NULL;
    }
    if (atomic_load(&fa_budget) >= 0 && atomic_fetch_sub(&fa_budget, 1) <= 0) {
        atomic_fetch_add(&fa_failed, 1);
        return NULL;
    }
    // A header before the block marks our pointers, so a foreign free is caught.
    size_t align = alignment < sizeof(fa_header) ? sizeof(fa_header) : alignment;
    size_t total = (align + size + align - 1) / align * align;
    unsigned char *base = aligned_alloc(align, total);
    if (!base) {
        return NULL;
    }
    unsigned char *p = base + align;
    fa_header h = {.magic = 0xfa11ed00u ^ (size_t)align};
    memcpy(p - sizeof h, &h, sizeof h);
    atomic_fetch_add(&fa_live, 1);
    return p;
}

static void fa_free(void *memory, void *user)
{
    if (user != &fa_tag) {
        atomic_fetch_add(&fa_misuse, 1);
    }
    if (!memory) {
        return;
    }
    unsigned char *p = memory;
    fa_header h;
    memcpy(&h, p - sizeof h, sizeof h);
    size_t align = h.magic ^ 0xfa11ed00u;
    if (align < sizeof(fa_header) || align > 4096 || (align & (align - 1)) != 0) {
        atomic_fetch_add(&fa_misuse, 1);
        return;
    }
    atomic_fetch_sub(&fa_live, 1);
    free(p - align);
}

static bool ok_or_oom(bpx_status s)
{
    return s == BPX_OK || s == BPX_ERR_OUT_OF_MEMORY;
}

// One full run with the first `budget` allocations succeeding; returns whether every call
// succeeded (the run needed no more than `budget` allocations).
static bool alloc_run(long long budget, int workers, const bpx_box *boxes, uint32_t n,
                      const float *minima, const float *centres, const pair_list *want)
{
    atomic_store(&fa_budget, budget);
    bool all_ok = true;
    bpx_world_def def = bpx_default_world_def();
    def.worker_count = workers;
    bpx_world *w = (bpx_world *)&w;
    bpx_status s = bpx_world_create(&def, &w);
    CHECK_MSG(ok_or_oom(s), "create: %s", check_status_name(s));
    if (s != BPX_OK) {
        CHECK(w == NULL);
        return false;
    }
    s = bpx_world_set_boxes(w, boxes, n);
    CHECK_MSG(ok_or_oom(s), "set_boxes: %s", check_status_name(s));
    all_ok &= s == BPX_OK;
    bool have_boxes = s == BPX_OK;
    s = bpx_world_collide(w);
    CHECK_MSG(ok_or_oom(s), "collide: %s", check_status_name(s));
    all_ok &= s == BPX_OK;
    if (s == BPX_OK && have_boxes) {
        size_t count = 0;
        const bpx_pair *pairs = bpx_world_pairs(w, &count);
        CHECK_PAIRS_EQ(want->pairs, want->count, pairs, count);
    }
    bpx_pair small[4];
    size_t count = 0;
    s = bpx_world_collide_into(w, small, 4, &count);
    CHECK_MSG(s == BPX_ERR_CAPACITY || ok_or_oom(s), "collide_into: %s", check_status_name(s));
    all_ok &= s == BPX_ERR_CAPACITY || (s == BPX_OK && !have_boxes);
    s = bpx_world_load_extents(w, minima, n);
    CHECK_MSG(ok_or_oom(s), "load_extents: %s", check_status_name(s));
    all_ok &= s == BPX_OK;
    if (s == BPX_OK) {
        s = bpx_world_update_centres(w, centres);
        CHECK_MSG(ok_or_oom(s), "update_centres: %s", check_status_name(s));
        all_ok &= s == BPX_OK;
        s = bpx_world_collide(w);
        CHECK_MSG(ok_or_oom(s), "collide after update: %s", check_status_name(s));
        all_ok &= s == BPX_OK;
    }
    // With memory back, a world that saw failures recovers.
    atomic_store(&fa_budget, -1);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    size_t got = 0;
    const bpx_pair *pairs = bpx_world_pairs(w, &got);
    CHECK_PAIRS_EQ(want->pairs, want->count, pairs, got);
    bpx_world_destroy(w);
    return all_ok;
}

static void test_allocation_failure(void)
{
    enum { n = 400 };
    const uint64_t seed = 4242;
    check_set_seed(seed);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    CHECK(scene_generate(SCENE_DENSE, n, seed, boxes) == 0);
    float *minima = check_alloc(sizeof(float) * 3 * n);
    float *centres = check_alloc(sizeof(float) * 3 * n);
    for (uint32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            float half = (boxes[i].max[a] - boxes[i].min[a]) * 0.5f;
            minima[3 * i + a] = -half;
            centres[3 * i + a] = boxes[i].min[a] + half;
        }
    }
    pair_list want = {0};
    pair_list_brute(&want, boxes, n);

    int64_t start = bpx_allocated_bytes();
    atomic_store(&fa_budget, -1);
    bpx_set_allocator(fa_alloc, fa_free, &fa_tag);
    static const int worker_counts[] = {1, 2, 3, 8};
    for (size_t wi = 0; wi < sizeof worker_counts / sizeof worker_counts[0]; wi++) {
        int workers = worker_counts[wi];
        long long budget = 0;
        for (; budget < 100000; budget++) {
            check_set_context("allocation failure after %lld allocations, %d workers", budget,
                              workers);
            bool done = alloc_run(budget, workers, boxes, n, minima, centres, &want);
            CHECK_MSG(bpx_allocated_bytes() == start, "allocated %lld bytes, started at %lld",
                      (long long)bpx_allocated_bytes(), (long long)start);
            CHECK_EQ_U64(atomic_load(&fa_live), 0);
            if (done) {
                break;
            }
        }
        printf("  %d workers: a full run needs %lld allocations; every shorter budget failed "
               "cleanly\n",
               workers, budget);
        CHECK(budget > 0);
    }
    check_set_context("allocator hooks");
    CHECK_EQ_U64(atomic_load(&fa_misuse), 0);
    CHECK(atomic_load(&fa_failed) > 0);
    bpx_set_allocator(NULL, NULL, NULL);

    // The default allocator is back: a world works and frees everything.
    bpx_world *w = new_world(2);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    bpx_world_destroy(w);
    CHECK(bpx_allocated_bytes() == start);
    pair_list_free(&want);
    free(boxes);
    free(minima);
    free(centres);
}

// ---------------------------------------------------------------------------------------------
// A call that fails for memory leaves the world as it was: a twin world that never saw the call
// answers every later call the same (statuses, ids handed out, pairs, events).

enum { keep_n = 300, keep_small = 50 };

static struct {
    bpx_box dense[keep_n];
    bpx_box apart[keep_n]; // the same boxes far apart: no pairs
    bpx_box pile[keep_n];  // every pair overlaps
    float minima[3 * keep_n];
    float tiny[3 * keep_n];
    float centres[3 * keep_n]; // with minima, neighbours overlap on x
    bpx_pair out[keep_n * keep_n / 2];
    uint32_t ids[keep_n];
} keep;

static void setup_two_phase(bpx_world *w)
{
    CHECK_STATUS(bpx_world_load_extents(w, keep.minima, 2), BPX_OK);
    CHECK_STATUS(bpx_world_update_centres(w, keep.centres), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
}

static void setup_plain(bpx_world *w)
{
    CHECK_STATUS(bpx_world_set_boxes(w, keep.dense, keep_small), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
}

// Filters, removed ids free for reuse and one removed id still pending.
static void setup_objects(bpx_world *w)
{
    setup_plain(w);
    const uint32_t filtered[2] = {5, 9}, cats[2] = {2, 2}, masks[2] = {0, 1};
    CHECK_STATUS(bpx_world_set_filters(w, filtered, cats, masks, 2), BPX_OK);
    const uint32_t removed[3] = {3, 7, 11};
    CHECK_STATUS(bpx_world_remove_boxes(w, removed, 2), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK_STATUS(bpx_world_remove_boxes(w, removed + 2, 1), BPX_OK);
}

// One pair last cycle, every pair now: the events' lists must grow, and the next events must
// still be reported against that one pair.
static void setup_events(bpx_world *w)
{
    bpx_box one_pair[keep_small];
    memcpy(one_pair, keep.apart, sizeof one_pair);
    one_pair[1] = one_pair[0];
    CHECK_STATUS(bpx_world_set_boxes(w, one_pair, keep_small), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK_STATUS(bpx_world_set_boxes(w, keep.pile, keep_small), BPX_OK);
}

static void setup_events_pending(bpx_world *w)
{
    setup_events(w);
    const uint32_t removed[2] = {3, 11};
    CHECK_STATUS(bpx_world_remove_boxes(w, removed, 2), BPX_OK);
}

static bpx_status call_load(bpx_world *w)
{
    return bpx_world_load_extents(w, keep.tiny, keep_n);
}
static bpx_status call_set(bpx_world *w)
{
    return bpx_world_set_boxes(w, keep.dense, keep_n);
}
static bpx_status call_add(bpx_world *w)
{
    return bpx_world_add_boxes(w, keep.dense, keep_n, keep.ids);
}
static const uint32_t some_ids[3] = {1, 2, 4};
static bpx_status call_remove(bpx_world *w)
{
    return bpx_world_remove_boxes(w, some_ids, 3);
}
static bpx_status call_move(bpx_world *w)
{
    return bpx_world_move_boxes(w, some_ids, keep.apart + keep_n - 3, 3);
}
static bpx_status call_filters(bpx_world *w)
{
    const uint32_t cats[3] = {2, 2, 2}, masks[3] = {0, 0, 0};
    return bpx_world_set_filters(w, some_ids, cats, masks, 3);
}
static bpx_status call_collide(bpx_world *w)
{
    return bpx_world_collide(w);
}
static bpx_status call_collide_into(bpx_world *w)
{
    size_t count = 0;
    return bpx_world_collide_into(w, keep.out, sizeof keep.out / sizeof keep.out[0], &count);
}

typedef struct keep_case {
    const char *name;
    void (*setup)(bpx_world *w);
    bpx_status (*call)(bpx_world *w);
} keep_case;

static void check_same_cycle(bpx_world *w, bpx_world *twin)
{
    CHECK_EQ_U64(bpx_world_box_count(w), bpx_world_box_count(twin));
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK_STATUS(bpx_world_collide(twin), BPX_OK);
    size_t count = 0, want_count = 0;
    const bpx_pair *got = bpx_world_pairs(w, &count);
    const bpx_pair *want = bpx_world_pairs(twin, &want_count);
    CHECK_PAIRS_EQ(want, want_count, got, count);
    bpx_pair_events ev, want_ev;
    CHECK_STATUS(bpx_world_pair_events(w, &ev), BPX_OK);
    CHECK_STATUS(bpx_world_pair_events(twin, &want_ev), BPX_OK);
    CHECK_PAIRS_EQ(want_ev.began, want_ev.began_count, ev.began, ev.began_count);
    CHECK_PAIRS_EQ(want_ev.ended, want_ev.ended_count, ev.ended, ev.ended_count);
}

// Adds a box to both (before a collide: pending ids must still be held back), then cycles.
static void check_same_world(bpx_world *w, bpx_world *twin)
{
    uint32_t id = UINT32_MAX, want_id = UINT32_MAX;
    CHECK_STATUS(bpx_world_add_boxes(w, keep.dense, 1, &id),
                 bpx_world_add_boxes(twin, keep.dense, 1, &want_id));
    CHECK_EQ_U64(id, want_id);
    check_same_cycle(w, twin);
    CHECK_STATUS(bpx_world_update_centres(w, keep.centres),
                 bpx_world_update_centres(twin, keep.centres));
    check_same_cycle(w, twin);
    CHECK_STATUS(bpx_world_add_boxes(w, keep.dense, 2, keep.ids),
                 bpx_world_add_boxes(twin, keep.dense, 2, keep.ids + 2));
    CHECK(keep.ids[0] == keep.ids[2] && keep.ids[1] == keep.ids[3]);
    check_same_cycle(w, twin);
}

static void test_failure_keeps_world(void)
{
    CHECK(scene_generate(SCENE_DENSE, keep_n, 2222, keep.dense) == 0);
    for (uint32_t i = 0; i < keep_n; i++) {
        keep.apart[i] = keep.dense[i];
        keep.apart[i].min[0] += 1000.0f * (float)i;
        keep.apart[i].max[0] += 1000.0f * (float)i;
        keep.pile[i] = (bpx_box){{0, 0, 0}, {1 + 0.01f * (float)i, 1, 1}};
        for (int a = 0; a < 3; a++) {
            keep.minima[3 * i + a] = -0.5f;
            keep.tiny[3 * i + a] = -0.01f;
            keep.centres[3 * i + a] = a == 0 ? 0.75f * (float)i : 0.0f;
        }
    }
    static const keep_case cases[] = {
        {"load_extents over two-phase", setup_two_phase, call_load},
        {"load_extents over objects", setup_objects, call_load},
        {"set_boxes over two-phase", setup_two_phase, call_set},
        {"set_boxes over objects", setup_objects, call_set},
        {"add_boxes", setup_plain, call_add},
        {"add_boxes over objects", setup_objects, call_add},
        {"remove_boxes, first", setup_plain, call_remove},
        {"move_boxes, first", setup_plain, call_move},
        {"set_filters, first", setup_plain, call_filters},
        {"collide with events", setup_events, call_collide},
        {"collide_into with events", setup_events, call_collide_into},
        {"collide with pending ids", setup_events_pending, call_collide},
    };
    int64_t start = bpx_allocated_bytes();
    atomic_store(&fa_budget, -1);
    bpx_set_allocator(fa_alloc, fa_free, &fa_tag);
    bpx_world_def def = bpx_default_world_def();
    def.track_events = true;
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        int failures = 0;
        for (long long budget = 0; budget < 1000; budget++) {
            check_set_context("%s, failing after %lld allocations", cases[c].name, budget);
            bpx_world *w = NULL, *twin = NULL;
            CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
            CHECK_STATUS(bpx_world_create(&def, &twin), BPX_OK);
            if (!w || !twin) {
                bpx_world_destroy(w);
                bpx_world_destroy(twin);
                break;
            }
            cases[c].setup(w);
            cases[c].setup(twin);
            atomic_store(&fa_budget, budget);
            bpx_status s = cases[c].call(w);
            atomic_store(&fa_budget, -1);
            bool done = s == BPX_OK;
            if (!done) {
                failures++;
                check_world_error(w, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1);
                check_same_world(w, twin);
            }
            bpx_world_destroy(w);
            bpx_world_destroy(twin);
            CHECK_EQ_U64(atomic_load(&fa_live), 0);
            if (done)
                break;
        }
        check_set_context("%s", cases[c].name);
        CHECK_MSG(failures > 0, "no allocation of the call failed: the case tests nothing");
    }
    bpx_set_allocator(NULL, NULL, NULL);
    CHECK(bpx_allocated_bytes() == start);
}

int main(void)
{
    const uint64_t seed = 5;
    check_set_seed(seed);
    printf("test_errors: scene uniform_density n=%d seed %" PRIu64 ", allocation scene dense "
           "n=400 seed 4242\n",
           base_n, seed);
    bpx_box boxes[base_n];
    CHECK(scene_generate(SCENE_UNIFORM_DENSITY, base_n, seed, boxes) == 0);
    // Make sure the base scene has pairs, so "unchanged" means something.
    boxes[1] = boxes[0];
    test_status_strings();
    test_names();
    test_create_errors();
    test_null_arguments(boxes);
    test_bad_boxes(boxes);
    test_too_many_boxes(boxes);
    test_updater_errors(boxes);
    test_allocation_failure();
    test_failure_keeps_world();
    return check_finish("test_errors", 1);
}
