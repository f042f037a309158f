// Every error through the public API: exact status, reported index/axis, world state unchanged
// after the error, status strings. Allocation failure at every allocation: test_out_of_memory.c.
#include <float.h>
#include <limits.h>
#include <math.h>

#include "error_util.h"
#include "pairs_util.h"
#include "scenes.h"

enum { base_n = 64, bad_index = 37 };

static const char *name_or(const char *s)
{
    return s ? s : "?";
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

// The rtl backend: its box limit (the chip's RAMs) through a world and the one-shot call, the
// world unchanged by a refused cycle; an allocation that fails under it at every point gives
// OUT_OF_MEMORY and leaks nothing. Without Verilator: unavailable, saying why.
static void test_rtl(void)
{
    check_set_context("rtl backend");
    bpx_backend_info info = bpx_backend_query(BPX_BACKEND_RTL);
    if (!info.available) {
        CHECK_MSG(strcmp(name_or(info.reason), "built without Verilator") == 0, "reason '%s'",
                  name_or(info.reason));
        printf("  rtl: unavailable (%s)\n", name_or(info.reason));
        return;
    }
    enum { limit = BPX_RTL_MAX_BOXES };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * (limit + 1));
    CHECK(scene_generate(SCENE_UNIFORM_DENSITY, limit + 1, 9, boxes) == 0);
    pair_list want = {0}, over = {0};
    pair_list_brute(&want, boxes, limit);
    pair_list_brute(&over, boxes, limit + 1);
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_RTL;
    bpx_world *w = NULL;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    if (!w) {
        free(boxes);
        return;
    }
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, limit), BPX_OK);
    collide_and_keep(w, &over);
    CHECK_PAIRS_EQ(want.pairs, want.count, over.pairs, over.count);
    // The same chip as the model backend's (m = 4, 512-box RAMs): the same comparator clocks,
    // so the same pair tests.
    if (bpx_backend_query(BPX_BACKEND_MODEL).available) {
        bpx_world_def model_def = bpx_default_world_def();
        model_def.backend = BPX_BACKEND_MODEL;
        bpx_world *model = NULL;
        CHECK_STATUS(bpx_world_create(&model_def, &model), BPX_OK);
        if (model) {
            CHECK_STATUS(bpx_world_set_boxes(model, boxes, limit), BPX_OK);
            CHECK_STATUS(bpx_world_collide(model), BPX_OK);
            CHECK_EQ_U64(bpx_world_stats(w).pair_tests, bpx_world_stats(model).pair_tests);
            CHECK(bpx_world_stats(w).pair_tests > 0);
            bpx_world_destroy(model);
        }
    }
    // One box more: the set is taken, the cycle refused with the limit named.
    check_set_context("rtl backend, %u boxes", limit + 1);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, limit + 1), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_ERR_TOO_MANY_BOXES);
    check_world_error(w, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1);
    CHECK_MSG(strstr(bpx_world_error(w)->message, "512") != NULL, "message '%s'",
              bpx_world_error(w)->message);
    size_t count = 0;
    bpx_pair out[4];
    bpx_error err;
    CHECK_STATUS(bpx_find_pairs(boxes, limit + 1, BPX_BACKEND_RTL, out, 4, &count, &err),
                 BPX_ERR_TOO_MANY_BOXES);
    check_error(&err, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1);
    // Back within the limit, the world works again.
    check_set_context("rtl backend, back to %u boxes", limit);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, limit), BPX_OK);
    collide_and_keep(w, &over);
    CHECK_PAIRS_EQ(want.pairs, want.count, over.pairs, over.count);
    bpx_world_destroy(w);

    // Allocation failure: world, board, sort scratch, pairs, through general boxes and the two
    // phases; each budget fails cleanly.
    enum { n = 60 };
    float minima[3 * n], centres[3 * n];
    extents_of(boxes, n, minima, centres);
    bpx_box remade[n]; // the boxes the two phases make, in float as documented
    for (uint32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            remade[i].min[a] = centres[3 * i + a] + minima[3 * i + a];
            remade[i].max[a] = centres[3 * i + a] - minima[3 * i + a];
        }
    }
    pair_list_brute(&want, remade, n);
    int64_t start = bpx_allocated_bytes();
    bpx_set_allocator(budget_alloc, budget_free, &budget_tag);
    long long budget = 0;
    for (; budget < 1000; budget++) {
        check_set_context("rtl backend: allocation failure after %lld allocations", budget);
        budget_left = budget;
        w = NULL;
        bpx_status s = bpx_world_create(&def, &w);
        CHECK_MSG(ok_or_oom(s), "create: %s", check_status_name(s));
        if (s == BPX_OK) {
            s = bpx_world_set_boxes(w, remade, n);
            CHECK_MSG(ok_or_oom(s), "set_boxes: %s", check_status_name(s));
        }
        if (s == BPX_OK) {
            s = bpx_world_collide(w);
            CHECK_MSG(ok_or_oom(s), "collide: %s", check_status_name(s));
        }
        // The paper's two phases: the chip's initialisation, then a centres cycle.
        if (s == BPX_OK) {
            s = bpx_world_load_extents(w, minima, n);
            CHECK_MSG(ok_or_oom(s), "load_extents: %s", check_status_name(s));
        }
        if (s == BPX_OK) {
            s = bpx_world_update_centres(w, centres);
            CHECK_MSG(ok_or_oom(s), "update_centres: %s", check_status_name(s));
        }
        if (s == BPX_OK) {
            s = bpx_world_collide(w);
            CHECK_MSG(ok_or_oom(s), "two-phase collide: %s", check_status_name(s));
            if (s == BPX_OK) {
                size_t got = 0;
                const bpx_pair *pairs = bpx_world_pairs(w, &got);
                CHECK_PAIRS_EQ(want.pairs, want.count, pairs, got);
            }
        }
        if (w) {
            budget_left = -1; // memory back: the world recovers
            CHECK_STATUS(bpx_world_set_boxes(w, remade, n), BPX_OK);
            collide_and_keep(w, &over);
            CHECK_PAIRS_EQ(want.pairs, want.count, over.pairs, over.count);
        }
        bpx_world_destroy(w);
        budget_left = -1;
        CHECK_EQ_U64(budget_live, 0);
        CHECK(bpx_allocated_bytes() == start);
        if (s == BPX_OK)
            break;
    }
    bpx_set_allocator(NULL, NULL, NULL);
    printf("  rtl: limit %u boxes; a cycle needs %lld allocations, every shorter budget failed "
           "cleanly\n",
           limit, budget);
    CHECK(budget > 2 && budget < 1000);
    pair_list_free(&want);
    pair_list_free(&over);
    free(boxes);
}

// ---------------------------------------------------------------------------------------------

static void test_updater_errors(const bpx_box *boxes)
{
    float minima[3 * base_n];
    float centres[3 * base_n];
    extents_of(boxes, base_n, minima, centres);
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
int main(void)
{
    const uint64_t seed = 5;
    check_set_seed(seed);
    printf("test_errors: scene uniform_density n=%d seed %" PRIu64 "\n", base_n, seed);
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
    test_rtl();
    return check_finish("test_errors", 1);
}
