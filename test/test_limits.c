// The limits of include/bpx/types.h, each answered by a status and a message, never by a
// wrapped index or a silent truncation. SPDX-License-Identifier: MIT
//
//   test_limits            counts past BPX_MAX_BOXES (2^32 - 1 requested, and BPX_MAX_BOXES + 1
//                          reached by adding), allocation failing at 10 million boxes, and
//                          the pair set past 2^32 below under a 1 GB allocation budget
//   test_limits --pairs    a pair set past 2^32 (92,683 boxes that all overlap: 4,295,022,903
//                          pairs, 34 GB each copy): brute reports every one, prune and grid
//                          refuse with TOO_MANY_PAIRS. Skips (77) below 81 GB available.
#include <stdatomic.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"

// ---------------------------------------------------------------------------------------------
// An allocator that refuses blocks of `refuse_from` bytes or more (0: refuses none).

static atomic_size_t refuse_from;
static atomic_long refused;

static void *limit_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    size_t limit = atomic_load(&refuse_from);
    if (limit && size >= limit) {
        atomic_fetch_add(&refused, 1);
        return NULL;
    }
    return aligned_alloc(alignment, size);
}

static void limit_free(void *memory, void *user)
{
    (void)user;
    free(memory);
}

static bool message_has(const bpx_world *w, const char *text)
{
    return strstr(bpx_world_error(w)->message, text) != NULL;
}

// ---------------------------------------------------------------------------------------------
// Counts: 2^32 - 1 boxes requested, and BPX_MAX_BOXES + 1 reached by adding. Every call is
// refused on the count alone, before it reads the (one-box) array it was given.

static void test_counts(void)
{
    check_set_context("counts");
    const uint32_t huge = UINT32_MAX;
    bpx_box one = {{0, 0, 0}, {1, 1, 1}};
    float minimum[3] = {-1, -1, -1};

    bpx_world_def def = bpx_default_world_def();
    def.capacity_hint = huge;
    bpx_world *w = (bpx_world *)&def;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_ERR_INVALID_ARGUMENT);
    CHECK(w == NULL);

    def = bpx_default_world_def();
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    bpx_box two[2] = {one, one};
    CHECK_STATUS(bpx_world_set_boxes(w, two, 2), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);

    CHECK_STATUS(bpx_world_set_boxes(w, &one, huge), BPX_ERR_TOO_MANY_BOXES);
    CHECK(message_has(w, "4294967295 boxes exceed BPX_MAX_BOXES (1073741824)"));
    CHECK_STATUS(bpx_world_set_boxes(w, &one, BPX_MAX_BOXES + 1u), BPX_ERR_TOO_MANY_BOXES);
    CHECK_STATUS(bpx_world_load_extents(w, minimum, huge), BPX_ERR_TOO_MANY_BOXES);
    CHECK(message_has(w, "4294967295 objects exceed BPX_MAX_BOXES"));
    uint32_t id;
    CHECK_STATUS(bpx_world_add_boxes(w, &one, huge, &id), BPX_ERR_TOO_MANY_BOXES);
    CHECK(message_has(w, "4294967295 boxes added to 2 make 4294967297"));
    // The world is as it was: two boxes, one pair, and it still runs.
    CHECK(bpx_world_box_count(w) == 2);
    size_t count = 0;
    CHECK(bpx_world_pairs(w, &count) != NULL && count == 1);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    CHECK(bpx_world_pairs(w, &count) != NULL && count == 1);
    bpx_world_destroy(w);

    bpx_error err;
    bpx_pair pair;
    CHECK_STATUS(bpx_find_pairs(&one, huge, BPX_BACKEND_AUTO, &pair, 1, &count, &err),
                 BPX_ERR_TOO_MANY_BOXES);
    CHECK(strstr(err.message, "4294967295") != NULL && count == 0);
    CHECK_STATUS(bpx_validate_boxes(&one, huge, &err), BPX_ERR_TOO_MANY_BOXES);
}

// ---------------------------------------------------------------------------------------------
// Allocation failing at 10 million boxes: set_boxes, load_extents and the collide of every
// backend that allocates per cycle refuse with OUT_OF_MEMORY, the world unchanged; then the
// same world, given memory, runs the cycle right.

enum { BIG_N = 10 * 1000 * 1000 };

// Boxes on a line, each touching the next: exactly n - 1 pairs, (i, i + 1).
static void line_boxes(bpx_box *boxes, uint32_t n)
{
    for (uint32_t i = 0; i < n; i++) {
        float x = (float)i; // exact up to 2^24
        boxes[i] = (bpx_box){{x, 0, 0}, {x + 1.0f, 1, 1}};
    }
}

static bool line_pairs_right(bpx_world *w, uint32_t n)
{
    size_t count = 0;
    const bpx_pair *pairs = bpx_world_pairs(w, &count);
    if (!pairs || count != (size_t)n - 1)
        return false;
    for (uint32_t k = 0; k + 1 < n; k++)
        if (pairs[k].i != k || pairs[k].j != k + 1)
            return false;
    return true;
}

static void test_ten_million(void)
{
    bpx_box *boxes = malloc(sizeof(bpx_box) * BIG_N);
    float *minima = calloc((size_t)BIG_N * 3, sizeof(float));
    if (!boxes || !minima) {
        printf("test_limits: no memory for %d boxes here; the 10M case is skipped\n", BIG_N);
        free(boxes);
        free(minima);
        return;
    }
    line_boxes(boxes, BIG_N);
    bpx_set_allocator(limit_alloc, limit_free, NULL);

    // The updater: the first array of 10M floats (40 MB) is refused.
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_PRUNE;
    bpx_world *w;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    bpx_box two[2] = {{{0, 0, 0}, {1, 1, 1}}, {{1, 0, 0}, {2, 1, 1}}};
    CHECK_STATUS(bpx_world_set_boxes(w, two, 2), BPX_OK);
    CHECK_STATUS(bpx_world_collide(w), BPX_OK);
    atomic_store(&refuse_from, (size_t)16 << 20);
    check_set_context("10M set_boxes");
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, BIG_N), BPX_ERR_OUT_OF_MEMORY);
    CHECK(message_has(w, "no memory for 10000000 boxes"));
    check_set_context("10M load_extents");
    CHECK_STATUS(bpx_world_load_extents(w, minima, BIG_N), BPX_ERR_OUT_OF_MEMORY);
    CHECK(message_has(w, "no memory for 10000000 objects"));
    CHECK(bpx_world_box_count(w) == 2 && line_pairs_right(w, 2));
    bpx_world_destroy(w);

    // The comparators: set_boxes gets its memory; then each backend's collide is refused
    // every block past 1 MB, and succeeds once memory is there again.
    static const bpx_backend backends[] = {BPX_BACKEND_PRUNE, BPX_BACKEND_SAP, BPX_BACKEND_GRID,
                                           BPX_BACKEND_AUTO};
    for (size_t b = 0; b < sizeof backends / sizeof backends[0]; b++) {
        check_set_context("10M collide, backend %s", bpx_backend_name(backends[b]));
        atomic_store(&refuse_from, 0);
        def.backend = backends[b];
        def.worker_count = 2;
        CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
        CHECK_STATUS(bpx_world_set_boxes(w, boxes, BIG_N), BPX_OK);
        atomic_store(&refuse_from, (size_t)1 << 20);
        long before = atomic_load(&refused);
        CHECK_STATUS(bpx_world_collide(w), BPX_ERR_OUT_OF_MEMORY);
        CHECK(atomic_load(&refused) > before);
        CHECK(message_has(w, "10000000 boxes") || message_has(w, "no memory"));
        size_t count = 1;
        CHECK(bpx_world_pairs(w, &count) == NULL && count == 0); // nothing partial
        CHECK(bpx_world_box_count(w) == BIG_N);
        if (backends[b] == BPX_BACKEND_AUTO) { // one full cycle at 10M: the world runs on
            atomic_store(&refuse_from, 0);
            CHECK_STATUS(bpx_world_collide(w), BPX_OK);
            CHECK(line_pairs_right(w, BIG_N));
        }
        bpx_world_destroy(w);
    }
    atomic_store(&refuse_from, 0);
    bpx_set_allocator(NULL, NULL, NULL);
    free(boxes);
    free(minima);
}

// ---------------------------------------------------------------------------------------------
// A pair set past 2^32: n identical boxes pair with each other, n (n - 1) / 2 pairs.

enum { PAIRS_N = 92683 }; // 4,295,022,903 pairs: the smallest n past 2^32 - 1

static uint64_t available_bytes(void)
{
    FILE *f = fopen("/proc/meminfo", "r");
    if (!f)
        return 0;
    char line[256];
    unsigned long long kb = 0;
    while (fgets(line, sizeof line, f))
        if (sscanf(line, "MemAvailable: %llu kB", &kb) == 1)
            break;
    fclose(f);
    return (uint64_t)kb * 1024;
}

static int test_pairs_past_2_32(int workers)
{
    uint64_t want = (uint64_t)PAIRS_N * (PAIRS_N - 1) / 2;
    uint64_t need = 2 * want * sizeof(bpx_pair) + ((uint64_t)12 << 30);
    if (available_bytes() < need) {
        printf("test_limits --pairs: %.1f GB available, %.1f GB needed: skipped\n",
               (double)available_bytes() / 1e9, (double)need / 1e9);
        return CHECK_SKIP;
    }
    bpx_box *boxes = malloc(sizeof(bpx_box) * PAIRS_N);
    if (!boxes)
        return CHECK_SKIP;
    for (uint32_t i = 0; i < PAIRS_N; i++)
        boxes[i] = (bpx_box){{0, 0, 0}, {1, 1, 1}};
    printf("%u boxes, %llu pairs expected (2^32 - 1 = %u), %d workers\n", (unsigned)PAIRS_N,
           (unsigned long long)want, UINT32_MAX, workers);

    // prune and grid order their pairs with 32-bit offsets: they refuse, and say so.
    bpx_world_def def = bpx_default_world_def();
    def.worker_count = workers;
    bpx_world *w;
    size_t count = 1;
    static const bpx_backend refusing[] = {BPX_BACKEND_PRUNE, BPX_BACKEND_GRID};
    for (int b = 0; b < 2; b++) {
        check_set_context("pairs past 2^32, %s", bpx_backend_name(refusing[b]));
        def.backend = refusing[b];
        CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
        CHECK_STATUS(bpx_world_set_boxes(w, boxes, PAIRS_N), BPX_OK);
        CHECK_STATUS(bpx_world_collide(w), BPX_ERR_TOO_MANY_PAIRS);
        printf("%s: %s\n", bpx_backend_name(refusing[b]), bpx_world_error(w)->message);
        CHECK(bpx_world_pairs(w, &count) == NULL && count == 0);
        bpx_world_destroy(w);
    }

    // brute counts in size_t: every pair, in order, the last one (n - 2, n - 1).
    check_set_context("pairs past 2^32, brute");
    def.backend = BPX_BACKEND_BRUTE;
    CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
    CHECK_STATUS(bpx_world_set_boxes(w, boxes, PAIRS_N), BPX_OK);
    bpx_status status = bpx_world_collide(w);
    CHECK(status == BPX_OK || status == BPX_ERR_OUT_OF_MEMORY);
    if (status == BPX_OK) {
        const bpx_pair *pairs = bpx_world_pairs(w, &count);
        CHECK_EQ_U64(count, want);
        CHECK_EQ_U64(bpx_world_stats(w).pair_count, want);
        bool ordered = pairs != NULL;
        uint64_t k = 0;
        for (uint32_t i = 0; ordered && i < PAIRS_N; i++)
            for (uint32_t j = i + 1; j < PAIRS_N; j++, k++)
                if (pairs[k].i != i || pairs[k].j != j) {
                    ordered = false;
                    break;
                }
        CHECK(ordered);
        printf("brute: %llu pairs, the last (%u, %u)\n", (unsigned long long)count,
               pairs[count - 1].i, pairs[count - 1].j);
    } else {
        printf("brute: %s\n", bpx_world_error(w)->message);
    }
    bpx_world_destroy(w);
    free(boxes);
    return check_finish("test_limits --pairs", 1);
}

// The same pair set on the way past 2^32 where memory is short: under a 1 GB budget every
// backend stops with OUT_OF_MEMORY (grid and sap may see TOO_MANY_PAIRS first), reports no
// pair, and the world runs on once the boxes are fewer.
static atomic_llong budget_left;

static void *budget_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    if (atomic_fetch_sub(&budget_left, (long long)size) < (long long)size) {
        atomic_fetch_add(&budget_left, (long long)size);
        return NULL;
    }
    size_t *p = aligned_alloc(alignment < 64 ? 64 : alignment, size + 64);
    if (!p) {
        atomic_fetch_add(&budget_left, (long long)size);
        return NULL;
    }
    p[0] = size;
    return (char *)p + 64;
}

static void budget_free(void *memory, void *user)
{
    (void)user;
    if (!memory)
        return;
    size_t *p = (size_t *)((char *)memory - 64);
    atomic_fetch_add(&budget_left, (long long)p[0]);
    free(p);
}

static void test_pairs_budget(void)
{
    bpx_box *boxes = malloc(sizeof(bpx_box) * PAIRS_N);
    if (!boxes)
        return;
    for (uint32_t i = 0; i < PAIRS_N; i++)
        boxes[i] = (bpx_box){{0, 0, 0}, {1, 1, 1}};
    static const bpx_backend backends[] = {BPX_BACKEND_BRUTE, BPX_BACKEND_PRUNE,
                                           BPX_BACKEND_SAP, BPX_BACKEND_GRID, BPX_BACKEND_AUTO};
    bpx_set_allocator(budget_alloc, budget_free, NULL);
    for (size_t b = 0; b < sizeof backends / sizeof backends[0]; b++) {
        check_set_context("pairs past 2^32 in 1 GB, backend %s", bpx_backend_name(backends[b]));
        atomic_store(&budget_left, 1ll << 30);
        bpx_world_def def = bpx_default_world_def();
        def.backend = backends[b];
        def.worker_count = 2;
        bpx_world *w;
        CHECK_STATUS(bpx_world_create(&def, &w), BPX_OK);
        CHECK_STATUS(bpx_world_set_boxes(w, boxes, PAIRS_N), BPX_OK);
        bpx_status status = bpx_world_collide(w);
        CHECK_MSG(status == BPX_ERR_OUT_OF_MEMORY || status == BPX_ERR_TOO_MANY_PAIRS,
                  "status %s: %s", bpx_status_name(status), bpx_world_error(w)->message);
        CHECK(message_has(w, "92683 boxes") || message_has(w, "pairs"));
        size_t count = 1;
        CHECK(bpx_world_pairs(w, &count) == NULL && count == 0);
        CHECK_STATUS(bpx_world_set_boxes(w, boxes, 100), BPX_OK); // 4950 pairs
        CHECK_STATUS(bpx_world_collide(w), BPX_OK);
        CHECK(bpx_world_pairs(w, &count) != NULL && count == 4950);
        bpx_world_destroy(w);
    }
    bpx_set_allocator(NULL, NULL, NULL);
    free(boxes);
}

int main(int argc, char **argv)
{
    if (argc > 1 && strcmp(argv[1], "--pairs") == 0)
        return test_pairs_past_2_32(argc > 2 ? atoi(argv[2]) : 2);
    test_counts();
    test_ten_million();
    test_pairs_budget();
    return check_finish("test_limits", 1);
}
