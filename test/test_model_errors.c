// The clock-by-clock model of the paper's FPGA (include/bpx/model.h, src/hw/) at its limits and
// on bad input: the 512-box limit, every error a call reports, and allocation failure at every
// allocation of the model and of a world on the model backend (no crash, no leak).
#include <math.h>

#include "error_util.h"
#include "model_util.h"
#include "scenes.h"

// ---------------------------------------------------------------------------------------------
// Limits and errors

static void test_limits(void)
{
    check_set_context("the paper's 512-box limit");
    bpx_model_config config = bpx_model_default_config();
    CHECK(config.m == 4 && config.clock_hz == 108e6 && config.ram_depth == 512 &&
          config.store == BPX_MODEL_STORE_ON_CHIP && config.ssram_depth == 524288);
    bpx_model *model = new_model(&config);
    if (!model)
        return;
    enum { n = 513 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    float *minima = check_alloc(sizeof(float) * 3 * n);
    CHECK(scene_generate(SCENE_SPARSE, n, 9, boxes) == 0);
    for (int k = 0; k < 3 * n; k++)
        minima[k] = -1.0f;
    CHECK_STATUS(bpx_model_run_boxes(model, boxes, 512, NULL), BPX_OK);
    size_t before = 0;
    bpx_model_pairs(model, &before);
    CHECK_STATUS(bpx_model_run_boxes(model, boxes, n, NULL), BPX_ERR_TOO_MANY_BOXES);
    const bpx_error *e = bpx_model_error(model);
    CHECK(e->status == BPX_ERR_TOO_MANY_BOXES);
    CHECK_MSG(strstr(e->message, "512") && strstr(e->message, "513"), "message: %s", e->message);
    size_t after = 0;
    bpx_model_pairs(model, &after);
    CHECK_EQ_U64(after, before); // the last result stays
    CHECK_STATUS(bpx_model_load_extents(model, minima, n, NULL), BPX_ERR_TOO_MANY_BOXES);
    CHECK_STATUS(bpx_model_load_extents(model, minima, 512, NULL), BPX_OK);
    bpx_model_destroy(model);

    check_set_context("SSRAM limit");
    config.store = BPX_MODEL_STORE_SSRAM;
    config.ssram_depth = 600;
    model = new_model(&config);
    if (model) {
        CHECK_STATUS(bpx_model_run_boxes(model, boxes, n, NULL), BPX_OK);
        bpx_box *more = check_alloc(sizeof(bpx_box) * 601);
        CHECK(scene_generate(SCENE_SPARSE, 601, 9, more) == 0);
        CHECK_STATUS(bpx_model_run_boxes(model, more, 601, NULL), BPX_ERR_TOO_MANY_BOXES);
        free(more);
        bpx_model_destroy(model);
    }
    free(boxes);
    free(minima);
}

static void test_errors(void)
{
    check_set_context("config errors");
    bpx_model *model = (bpx_model *)&model;
    CHECK_STATUS(bpx_model_create(NULL, &model), BPX_ERR_NULL_ARGUMENT);
    CHECK(model == NULL);
    bpx_model_config good = bpx_model_default_config();
    CHECK_STATUS(bpx_model_create(&good, NULL), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_model_check_config(&good, NULL), BPX_OK);
    for (int k = 0; k < 14; k++) {
        bpx_model_config c = good;
        switch (k) {
        case 0:
            c.m = 0;
            break;
        case 1:
            c.m = BPX_MODEL_MAX_M + 1;
            break;
        case 2:
            c.clock_hz = 0;
            break;
        case 3:
            c.clock_hz = NAN;
            break;
        case 4:
            c.ram_depth = 15;
            break; // below 4m
        case 5:
            c.ram_depth = 101;
            break; // odd
        case 6:
            c.fifo_depth = 0;
            break;
        case 7:
            c.ssram_latency = 0;
            break;
        case 8:
            c.ssram_latency = 9;
            break;
        case 9:
            c.link.bytes_per_s = 0;
            break;
        case 10:
            c.link.setup_ns = -1;
            break;
        case 11:
            c.link.register_ns = INFINITY;
            break;
        case 12:
            c.store = BPX_MODEL_STORE_COUNT;
            break;
        default:
            c.ssram_depth = 0;
            break;
        }
        check_set_context("config error %d", k);
        bpx_error err;
        CHECK_STATUS(bpx_model_check_config(&c, &err), BPX_ERR_INVALID_ARGUMENT);
        CHECK(err.message[0] != '\0');
        model = (bpx_model *)&model;
        CHECK_STATUS(bpx_model_create(&c, &model), BPX_ERR_INVALID_ARGUMENT);
        CHECK(model == NULL);
    }

    check_set_context("call errors");
    CHECK(bpx_model_error(NULL)->status == BPX_ERR_NULL_ARGUMENT);
    CHECK(bpx_model_pairs(NULL, NULL) == NULL);
    bpx_model_destroy(NULL);
    model = new_model(&good);
    if (!model)
        return;
    size_t count = 7;
    CHECK(bpx_model_pairs(model, &count) == NULL && count == 0);
    float centres[6] = {0, 0, 0, 1, 1, 1};
    float minima[6] = {-1, -1, -1, -1, -1, -1};
    CHECK_STATUS(bpx_model_run_centres(model, centres, NULL), BPX_ERR_BAD_STATE);
    CHECK_STATUS(bpx_model_run_centres(NULL, centres, NULL), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_model_load_extents(model, NULL, 2, NULL), BPX_ERR_NULL_ARGUMENT);
    minima[4] = 0.5f;
    CHECK_STATUS(bpx_model_load_extents(model, minima, 2, NULL), BPX_ERR_MIN_GREATER_THAN_MAX);
    CHECK(bpx_model_error(model)->index == 1 && bpx_model_error(model)->axis == 1);
    minima[4] = NAN;
    CHECK_STATUS(bpx_model_load_extents(model, minima, 2, NULL), BPX_ERR_NOT_FINITE);
    minima[4] = -1;
    CHECK_STATUS(bpx_model_load_extents(model, minima, 2, NULL), BPX_OK);
    CHECK_STATUS(bpx_model_run_centres(model, NULL, NULL), BPX_ERR_NULL_ARGUMENT);
    centres[5] = INFINITY;
    CHECK_STATUS(bpx_model_run_centres(model, centres, NULL), BPX_ERR_NOT_FINITE);
    centres[5] = 1;
    CHECK_STATUS(bpx_model_run_centres(model, centres, NULL), BPX_OK);
    const bpx_pair *pairs = bpx_model_pairs(model, &count);
    CHECK(count == 1 && pairs && pairs[0].i == 0 && pairs[0].j == 1);
    bpx_box bad[2] = {{{0, 0, 0}, {1, 1, 1}}, {{2, 0, 0}, {1, 1, 1}}};
    CHECK_STATUS(bpx_model_run_boxes(model, bad, 2, NULL), BPX_ERR_MIN_GREATER_THAN_MAX);
    CHECK_STATUS(bpx_model_run_boxes(model, NULL, 2, NULL), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_model_run_boxes(model, NULL, 0, NULL), BPX_OK);
    CHECK(bpx_model_pairs(model, &count) != NULL || count == 0);
    CHECK_EQ_U64(count, 0);
    bpx_model_destroy(model);
}

// ---------------------------------------------------------------------------------------------
// Allocation failure: every allocation of the model and of a world on the model backend may
// fail; each call then returns OK or OUT_OF_MEMORY, and nothing leaks.

static bool alloc_run(long long budget, const bpx_box *boxes, const float *minima,
                      const float *centres, uint32_t n, const pair_list *want)
{
    budget_left = budget;
    bool all_ok = true;
    bpx_model_config config = bpx_model_default_config();
    config.store = BPX_MODEL_STORE_STREAM;
    config.ram_depth = 64;
    bpx_model *model = NULL;
    bpx_status s = bpx_model_create(&config, &model);
    CHECK_MSG(ok_or_oom(s), "create: %s", check_status_name(s));
    all_ok &= s == BPX_OK;
    if (s == BPX_OK) {
        s = bpx_model_load_extents(model, minima, n, NULL);
        CHECK_MSG(ok_or_oom(s), "load_extents: %s", check_status_name(s));
        all_ok &= s == BPX_OK;
        if (s == BPX_OK) {
            s = bpx_model_run_centres(model, centres, NULL);
            CHECK_MSG(ok_or_oom(s), "run_centres: %s", check_status_name(s));
            all_ok &= s == BPX_OK;
        }
        s = bpx_model_run_boxes(model, boxes, n, NULL);
        CHECK_MSG(ok_or_oom(s), "run_boxes: %s", check_status_name(s));
        all_ok &= s == BPX_OK;
        if (s == BPX_OK) {
            size_t count = 0;
            const bpx_pair *pairs = bpx_model_pairs(model, &count);
            CHECK_PAIRS_EQ(want->pairs, want->count, pairs, count);
        }
        bpx_model_destroy(model);
    }
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_MODEL;
    bpx_world *world = NULL;
    s = bpx_world_create(&def, &world);
    CHECK_MSG(ok_or_oom(s), "world create: %s", check_status_name(s));
    all_ok &= s == BPX_OK;
    if (s == BPX_OK) {
        s = bpx_world_set_boxes(world, boxes, n);
        all_ok &= s == BPX_OK;
        if (s == BPX_OK) {
            s = bpx_world_collide(world);
            CHECK_MSG(ok_or_oom(s), "collide: %s", check_status_name(s));
            all_ok &= s == BPX_OK;
        }
        budget_left = -1; // memory back: the world recovers
        CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
        CHECK_STATUS(bpx_world_collide(world), BPX_OK);
        size_t count = 0;
        const bpx_pair *pairs = bpx_world_pairs(world, &count);
        CHECK_PAIRS_EQ(want->pairs, want->count, pairs, count);
        bpx_world_destroy(world);
    }
    budget_left = -1;
    return all_ok;
}

static void test_allocation_failure(void)
{
    enum { n = 300 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    float *minima = check_alloc(sizeof(float) * 3 * n);
    float *centres = check_alloc(sizeof(float) * 3 * n);
    CHECK(scene_generate(SCENE_DENSE, n, 31, boxes) == 0);
    extents_of(boxes, n, minima, centres);
    pair_list want = {0};
    bpx_world *reference = reference_world();
    if (reference)
        reference_pairs(reference, boxes, n, &want);
    bpx_world_destroy(reference);
    int64_t start = bpx_allocated_bytes();
    bpx_set_allocator(budget_alloc, budget_free, &budget_tag);
    long long budget = 0;
    for (; budget < 10000; budget++) {
        check_set_context("model: allocation failure after %lld allocations", budget);
        bool done = alloc_run(budget, boxes, minima, centres, n, &want);
        CHECK_MSG(bpx_allocated_bytes() == start, "allocated %lld bytes, started at %lld",
                  (long long)bpx_allocated_bytes(), (long long)start);
        CHECK_EQ_U64(budget_live, 0);
        if (done)
            break;
    }
    bpx_set_allocator(NULL, NULL, NULL);
    printf("  allocation failure: a full run needs %lld allocations; every shorter budget "
           "failed cleanly\n",
           budget);
    CHECK(budget > 3 && budget < 10000);
    pair_list_free(&want);
    free(boxes);
    free(minima);
    free(centres);
}

int main(void)
{
    double t0 = now_s();
    printf("test_model_errors: limits, errors, allocation failure\n");
    test_limits();
    test_errors();
    test_allocation_failure();
    printf("  %.2f s\n", now_s() - t0);
    return check_finish("test_model_errors", 1);
}
