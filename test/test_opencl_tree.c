// The opencl backend's linear BVH (src/opencl/tree.c, kernels/lbvh.h) beyond the paths that
// test_opencl runs on every scene kind: inert (removed) boxes among live and moving ones; large
// scenes, the tree forced and chosen by the auto rule, against prune with the tests per box
// bounded; the tree (and sort and sweep) giving way to brute force's windows when its keys pass
// the memory limit; and the centres already on the device (bpx_opencl_set_centres_buffer) on
// every path, queries refused meanwhile. Skipped (77) without OpenCL in the build or without a
// platform.
#include <math.h>

#include "error_util.h"
#include "opencl_util.h"

#if BPX_TEST_OPENCL

// ---------------------------------------------------------------------------------------------
// The tree: inert (removed) boxes among live ones, and large scenes through the auto rule

static void test_tree(void)
{
    // Removed ids are inert boxes (min +inf, max -inf): no centre, the last Morton code, empty
    // bounds. Both worlds see the same adds, removes and moves.
    enum { n = 3000 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    uint32_t *ids = check_alloc(sizeof(uint32_t) * n);
    uint32_t *gone = check_alloc(sizeof(uint32_t) * n);
    CHECK(scene_generate(SCENE_MIXED_SIZES, n, 31, boxes) == 0);
    bpx_world_def def = opencl_def();
    def.opencl_method = BPX_OPENCL_TREE;
    bpx_world *tree = make(&def);
    bpx_world_def ref_def = bpx_default_world_def();
    ref_def.backend = BPX_BACKEND_REFERENCE;
    bpx_world *ref = make(&ref_def);
    if (tree && ref) {
        CHECK_STATUS(bpx_world_add_boxes(tree, boxes, n, ids), BPX_OK);
        CHECK_STATUS(bpx_world_add_boxes(ref, boxes, n, ids), BPX_OK);
        uint32_t removed = 0;
        for (uint32_t i = 0; i < n; i += 3)
            gone[removed++] = ids[i];
        for (int step = 0; step < 3; step++) {
            check_set_context("tree with inert boxes, step %d", step);
            if (step == 1) {
                CHECK_STATUS(bpx_world_remove_boxes(tree, gone, removed), BPX_OK);
                CHECK_STATUS(bpx_world_remove_boxes(ref, gone, removed), BPX_OK);
            }
            if (step == 2) { // the survivors move: every box of the first third shifts
                scene_rng r;
                scene_rng_seed(&r, 32);
                scene_move(boxes, n, 0.5f, &r);
                uint32_t moved = 0;
                for (uint32_t i = 1; i < n / 3; i += 3)
                    gone[moved++] = ids[i];
                bpx_box *to = check_alloc(sizeof(bpx_box) * moved);
                for (uint32_t k = 0; k < moved; k++)
                    to[k] = boxes[3 * k + 1];
                CHECK_STATUS(bpx_world_move_boxes(tree, gone, to, moved), BPX_OK);
                CHECK_STATUS(bpx_world_move_boxes(ref, gone, to, moved), BPX_OK);
                free(to);
            }
            CHECK_STATUS(bpx_world_collide(tree), BPX_OK);
            CHECK_STATUS(bpx_world_collide(ref), BPX_OK);
            size_t got = 0, want = 0;
            const bpx_pair *g = bpx_world_pairs(tree, &got);
            const bpx_pair *w = bpx_world_pairs(ref, &want);
            CHECK_PAIRS_EQ(w, want, g, got);
        }
        CHECK(counters(tree).tree_cycles == 3);
    }
    bpx_world_destroy(tree);
    bpx_world_destroy(ref);
    free(boxes);
    free(ids);
    free(gone);

    // Large scenes that matter for the tree (constant density, heavy-tailed sizes, one shared x,
    // identical centres), forced, against prune; and the auto rule taking the tree past
    // TREE_MIN_N on the scene it is meant for.
    static const struct {
        scene_kind kind;
        uint32_t n;
        int method;
    } big[] = {{SCENE_UNIFORM_DENSITY, 40000, BPX_OPENCL_AUTO},
               {SCENE_MIXED_SIZES, 40000, BPX_OPENCL_TREE},
               {SCENE_SHARED_COORD, 20000, BPX_OPENCL_TREE},
               {SCENE_IDENTICAL, 20000, BPX_OPENCL_TREE}};
    bpx_box *many = check_alloc(sizeof(bpx_box) * 40000);
    pair_list want = {0};
    bpx_world *world = NULL;
    for (size_t k = 0; k < sizeof big / sizeof big[0]; k++) {
        check_set_context("scene=%s n=%u method=%d", scene_kind_name(big[k].kind), big[k].n,
                          big[k].method);
        def = opencl_def();
        def.opencl_method = big[k].method;
        world = make(&def);
        if (!world)
            continue;
        CHECK(scene_generate(big[k].kind, big[k].n, 40 + k, many) == 0);
        pairs_of(many, big[k].n, BPX_BACKEND_PRUNE, &want);
        check_world(world, many, big[k].n, &want);
        CHECK(counters(world).tree_cycles == 1);
        // Each box tests a few dozen nodes and a few per pair, not a share of the set.
        uint64_t tests = bpx_world_stats(world).pair_tests;
        printf("  tree: %s n=%u: %zu pairs, %.1f tests per box\n", scene_kind_name(big[k].kind),
               big[k].n, want.count, (double)tests / big[k].n);
        CHECK_MSG(tests > 0 && tests < (uint64_t)big[k].n * 200 + 16 * want.count, "%llu tests",
                  (unsigned long long)tests);
        bpx_world_destroy(world);
    }
    world = NULL;
    bpx_world_destroy(world);
    pair_list_free(&want);
    free(many);
}

// ---------------------------------------------------------------------------------------------
// Past the memory limit: the sweep's and the tree's pairs do not fit, brute force's windows take
// the cycle (all-overlapping sets on both sides of the one-launch kernel's limits)

static void test_fallback(void)
{
    static const struct {
        uint32_t n;
        uint64_t memory_limit;
    } cases[] = {{250, 160u << 10}, {1000, 2u << 20}, {1234, 2u << 20}};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        uint32_t n = cases[k].n;
        bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
        CHECK(scene_generate(SCENE_ALL_OVERLAP, n, 3, boxes) == 0);
        pair_list want = {0};
        pair_list_brute(&want, boxes, n);
        for (int method = BPX_OPENCL_SWEEP; method <= BPX_OPENCL_TREE; method++) {
            bool tree = method == BPX_OPENCL_TREE;
            check_set_context("n=%u %s falls back under a memory limit", n,
                              tree ? "tree" : "sweep");
            bpx_world_def def = opencl_def();
            def.opencl_method = method;
            def.opencl_memory_limit = cases[k].memory_limit;
            bpx_world *world = make(&def);
            if (!world)
                continue;
            check_world(world, boxes, n, &want);
            bpx__opencl_counters c = counters(world);
            CHECK(tree ? c.tree_fallbacks > 0 : c.sweep_fallbacks > 0);
            if (tree) // and again, from the state the fallback left
                check_world(world, boxes, n, &want);
            bpx_world_destroy(world);
        }
        pair_list_free(&want);
        free(boxes);
    }
}

// The centres already on the device (bpx_opencl_set_centres_buffer): every path, streamed
// blocks too, against the reference of the same boxes made on the host; the caller changing
// them between cycles on the world's queue; each error, the world unchanged after it; queries
// refused until host centres come back.
static void test_device_centres(void)
{
    enum { n = 3001 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    bpx_box *equivalent = check_alloc(sizeof(bpx_box) * n);
    float *minima = check_alloc(sizeof(float) * 3 * n);
    float *centres = check_alloc(sizeof(float) * 3 * n);
    CHECK(scene_generate(SCENE_MIXED_SIZES, n, 12, boxes) == 0);
    extents_of(boxes, n, minima, centres);
    pair_list want = {0};
    static const path centre_paths[] = {{"auto", BPX_OPENCL_AUTO, 0, 0},
                                        {"brute", BPX_OPENCL_BRUTE, 0, 0},
                                        {"sweep", BPX_OPENCL_SWEEP, 0, 0},
                                        {"tree", BPX_OPENCL_TREE, 0, 0},
                                        {"streamed-640", BPX_OPENCL_BRUTE, 640, 0}};
    for (size_t p = 0; p < sizeof centre_paths / sizeof centre_paths[0]; p++) {
        check_set_context("device centres, path %s", centre_paths[p].name);
        bpx_world_def def = opencl_def();
        def.opencl_method = centre_paths[p].method;
        def.opencl_block_boxes = centre_paths[p].block_boxes;
        bpx_world *world = make(&def);
        if (!world)
            continue;
        void *context = NULL, *queue = NULL;
        CHECK_STATUS(bpx_opencl_world_handles(world, &context, &queue, NULL), BPX_OK);
        cl_int err;
        cl_mem buffer = clCreateBuffer(context, CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR,
                                       sizeof(float) * 3 * n, centres, &err);
        CHECK(buffer != NULL);
        // Before load_extents: no minima to add to.
        CHECK_STATUS(bpx_opencl_set_centres_buffer(world, buffer, n), BPX_ERR_BAD_STATE);
        CHECK_STATUS(bpx_world_load_extents(world, minima, n), BPX_OK);
        CHECK_STATUS(bpx_opencl_set_centres_buffer(world, buffer, n - 1), BPX_ERR_INVALID_ARGUMENT);
        CHECK_STATUS(bpx_opencl_set_centres_buffer(world, NULL, n), BPX_ERR_NULL_ARGUMENT);
        CHECK_STATUS(bpx_opencl_set_centres_buffer(world, buffer, n), BPX_OK);
        clReleaseMemObject(buffer); // the world keeps its own reference
        scene_rng motion;
        scene_rng_seed(&motion, 12);
        for (int cycle = 0; cycle < 3; cycle++) {
            if (cycle > 0) { // the caller moves the objects on the device, on the world's queue
                for (uint32_t i = 0; i < 3 * n; i++)
                    centres[i] += scene_rng_range(&motion, -0.5f, 0.5f);
                CHECK(clEnqueueWriteBuffer(queue, buffer, CL_FALSE, 0, sizeof(float) * 3 * n,
                                           centres, 0, NULL, NULL) == CL_SUCCESS);
            }
            for (uint32_t i = 0; i < n; i++)
                for (int a = 0; a < 3; a++) {
                    equivalent[i].min[a] = centres[3 * i + a] + minima[3 * i + a];
                    equivalent[i].max[a] = centres[3 * i + a] - minima[3 * i + a];
                }
            reference_pairs(equivalent, n, &want);
            CHECK_STATUS(bpx_world_collide(world), BPX_OK);
            size_t count = 0;
            const bpx_pair *pairs = bpx_world_pairs(world, &count);
            CHECK_PAIRS_EQ(want.pairs, want.count, pairs, count);
            if (centre_paths[p].block_boxes == 0)
                CHECK_EQ_U64(bpx_world_stats(world).bytes_in, 0); // nothing crossed the link
        }
        clFinish(queue); // the last write's host memory is reused below
        // The boxes are made on the device: queries are refused (until host centres come).
        const bpx_query q = bpx_query_box(equivalent[0]);
        check_query_refused(world, &q);

        // A centre whose box overflows: named with its object and axis; the world keeps the
        // previous centres.
        check_set_context("device centres errors, path %s", centre_paths[p].name);
        float *bad_centres = check_alloc(sizeof(float) * 3 * n);
        memcpy(bad_centres, centres, sizeof(float) * 3 * n);
        bad_centres[3 * 2345 + 2] = INFINITY;
        bad_centres[3 * 2999 + 0] = NAN;
        cl_mem bad = clCreateBuffer(context, CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR,
                                    sizeof(float) * 3 * n, bad_centres, &err);
        CHECK_STATUS(bpx_opencl_set_centres_buffer(world, bad, n), BPX_ERR_NOT_FINITE);
        CHECK(bpx_world_error(world)->index == 2345 && bpx_world_error(world)->axis == 2);
        clReleaseMemObject(bad);
        cl_mem small =
            clCreateBuffer(context, CL_MEM_READ_WRITE, sizeof(float) * 3 * (n - 1), NULL, &err);
        CHECK_STATUS(bpx_opencl_set_centres_buffer(world, small, n), BPX_ERR_INVALID_ARGUMENT);
        clReleaseMemObject(small);
        CHECK_STATUS(bpx_world_collide(world), BPX_OK);
        size_t count = 0;
        const bpx_pair *pairs = bpx_world_pairs(world, &count);
        CHECK_PAIRS_EQ(want.pairs, want.count, pairs, count);
        // Host centres take over again, and queries see their boxes.
        check_query_refused(world, &q);
        CHECK_STATUS(bpx_world_update_centres(world, centres), BPX_OK);
        check_query_sees(world, &q, equivalent, n);
        CHECK_STATUS(bpx_world_collide(world), BPX_OK);
        pairs = bpx_world_pairs(world, &count);
        CHECK_PAIRS_EQ(want.pairs, want.count, pairs, count);
        free(bad_centres);
        bpx_world_destroy(world);
    }
    // Not an opencl world; general mode.
    check_set_context("device centres, other backends");
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_BRUTE;
    bpx_world *other = make(&def);
    int dummy;
    if (other)
        CHECK_STATUS(bpx_opencl_set_centres_buffer(other, &dummy, 1), BPX_ERR_BACKEND_UNAVAILABLE);
    bpx_world_destroy(other);
    CHECK_STATUS(bpx_opencl_set_centres_buffer(NULL, &dummy, 1), BPX_ERR_NULL_ARGUMENT);
    pair_list_free(&want);
    free(boxes);
    free(equivalent);
    free(minima);
    free(centres);
}

#endif

int main(void)
{
#if !BPX_TEST_OPENCL
    printf("test_opencl_tree: no OpenCL in this build\n");
    return check_finish("test_opencl_tree", 0);
#else
    bpx_set_logger(capture_log, NULL);
    bpx_backend_info info = opencl_info("test_opencl_tree");
    if (!info.available)
        return opencl_unavailable("test_opencl_tree", info);
    test_tree();
    test_fallback();
    test_device_centres();
    bpx_set_logger(NULL, NULL);
    return check_finish("test_opencl_tree", 1);
#endif
}
