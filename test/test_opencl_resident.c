// The opencl backend's device-resident cycles (bpx_opencl_collide_device, _device_pairs,
// _finish): pairs left in a device buffer with their count. Each cycle's buffers are read back
// and compared byte for byte with bpx_find_pairs(reference), and a kernel of the test's own
// reads the pairs on the device behind the cycle (the caller's next kernel: it counts the pairs
// whose i is even and folds i ^ j), before the host waits for anything. Covered: every path
// forced (brute force, small and tiled; tree; sweep; auto) on random, dense, heavy-tailed,
// shared-x, all-overlap, touching and -0.0 scenes over several cycles of moving boxes, with the
// boxes from the host, from a device buffer of boxes and from a device buffer of centres (moved
// by the test's kernels: nothing but the count crosses the link); a room too small (CAPACITY
// with the count, nothing lost, then grown); the memory limit (the tree giving way to brute
// force, room past the limit, streaming refused); removed objects; host and device cycles
// mixed on one world; and the errors (filters, events, another backend, calls out of order).
// Without OpenCL in the build or without a platform it is skipped (77).
#include "opencl_util.h"

#if BPX_TEST_OPENCL

// ---------------------------------------------------------------------------------------------
// The test's own kernels: they move boxes or centres on the device (the caller's integrator)
// and read the pairs where the cycle left them (the caller's narrow phase).

static const char *kernel_source =
    "#pragma OPENCL FP_CONTRACT OFF\n"
    "__constant float steps[8] = {0.25f, -0.125f, 0.5f, -0.375f, 0.0625f, -0.25f, 0.125f,\n"
    "                             -0.5f};\n"
    "__kernel void move_boxes(__global float *boxes, uint n, uint cycle)\n"
    "{\n"
    "    uint k = get_global_id(0);\n"
    "    if (k < n)\n"
    "        for (uint a = 0; a < 3; a++) {\n"
    "            float d = steps[(k + cycle + a) % 8];\n"
    "            boxes[6 * k + a] += d;\n"
    "            boxes[6 * k + 3 + a] += d;\n"
    "        }\n"
    "}\n"
    "__kernel void move_centres(__global float *centres, uint n, uint cycle)\n"
    "{\n"
    "    uint k = get_global_id(0);\n"
    "    if (k < n)\n"
    "        for (uint a = 0; a < 3; a++)\n"
    "            centres[3 * k + a] += steps[(k + cycle + a) % 8];\n"
    "}\n"
    "// out[0]: pairs with i even; out[1]: the sum of i ^ j; out[2]: 1 when the room was short.\n"
    "__kernel void consume(__global const uint2 *pairs, __global const ulong *count,\n"
    "                      ulong capacity, __global uint *out)\n"
    "{\n"
    "    ulong k = get_global_id(0), c = *count;\n"
    "    if (k == 0 && c > capacity)\n"
    "        out[2] = 1u;\n"
    "    if (c > capacity || k >= c)\n"
    "        return;\n"
    "    uint2 p = pairs[k];\n"
    "    if ((p.x & 1u) == 0u)\n"
    "        atomic_inc(&out[0]);\n"
    "    atomic_add(&out[1], p.x ^ p.y);\n"
    "}\n";

static const float steps[8] = {0.25f, -0.125f, 0.5f, -0.375f, 0.0625f, -0.25f, 0.125f, -0.5f};

// The host's twins of move_boxes and move_centres (one float add each: the same result).
static void move_boxes(bpx_box *boxes, uint32_t n, uint32_t cycle)
{
    for (uint32_t k = 0; k < n; k++)
        for (uint32_t a = 0; a < 3; a++) {
            float d = steps[(k + cycle + a) % 8];
            boxes[k].min[a] += d;
            boxes[k].max[a] += d;
        }
}

static void move_centres(float *centres, uint32_t n, uint32_t cycle)
{
    for (uint32_t k = 0; k < n; k++)
        for (uint32_t a = 0; a < 3; a++)
            centres[3 * k + a] += steps[(k + cycle + a) % 8];
}

static struct {
    cl_context context;
    cl_program program;
    cl_kernel move_boxes, move_centres, consume;
} rig;

static bool rig_ready(bpx_world *world)
{
    void *context_handle = NULL, *device_handle = NULL;
    CHECK_STATUS(bpx_opencl_world_handles(world, &context_handle, NULL, &device_handle), BPX_OK);
    cl_context context = context_handle;
    cl_device_id device = device_handle;
    if (rig.program)
        return rig.context == context; // one context per device, kept for the process
    cl_int err;
    rig.context = context;
    rig.program = clCreateProgramWithSource(context, 1, &kernel_source, NULL, &err);
    CHECK(rig.program != NULL);
    if (!rig.program)
        return false;
    err = clBuildProgram(rig.program, 1, &device, "", NULL, NULL);
    CHECK_MSG(err == CL_SUCCESS, "the test's kernels did not build: %d", (int)err);
    rig.move_boxes = clCreateKernel(rig.program, "move_boxes", &err);
    rig.move_centres = clCreateKernel(rig.program, "move_centres", &err);
    rig.consume = clCreateKernel(rig.program, "consume", &err);
    CHECK(rig.move_boxes && rig.move_centres && rig.consume);
    return err == CL_SUCCESS;
}

static void rig_free(void)
{
    if (rig.move_boxes)
        clReleaseKernel(rig.move_boxes);
    if (rig.move_centres)
        clReleaseKernel(rig.move_centres);
    if (rig.consume)
        clReleaseKernel(rig.consume);
    if (rig.program)
        clReleaseProgram(rig.program);
    memset(&rig, 0, sizeof rig);
}

static size_t round_up(size_t value, size_t multiple)
{
    return (value + multiple - 1) / multiple * multiple;
}

// move_boxes or move_centres over n items of buffer, on queue.
static void enqueue_move(cl_command_queue queue, cl_kernel kernel, cl_mem buffer, uint32_t n,
                         uint32_t cycle)
{
    cl_uint n_arg = n, cycle_arg = cycle;
    CHECK(clSetKernelArg(kernel, 0, sizeof buffer, &buffer) == CL_SUCCESS);
    CHECK(clSetKernelArg(kernel, 1, sizeof n_arg, &n_arg) == CL_SUCCESS);
    CHECK(clSetKernelArg(kernel, 2, sizeof cycle_arg, &cycle_arg) == CL_SUCCESS);
    size_t global = round_up(n ? n : 1, 64);
    CHECK(clEnqueueNDRangeKernel(queue, kernel, 1, NULL, &global, NULL, 0, NULL, NULL) ==
          CL_SUCCESS);
}

// ---------------------------------------------------------------------------------------------
// Helpers

static bpx_world_def def_for(int method)
{
    bpx_world_def def = opencl_def();
    def.opencl_method = method;
    return def;
}

static cl_command_queue queue_of(bpx_world *world)
{
    void *queue = NULL;
    CHECK_STATUS(bpx_opencl_world_handles(world, NULL, &queue, NULL), BPX_OK);
    return queue;
}

static cl_context context_of(bpx_world *world)
{
    void *context = NULL;
    CHECK_STATUS(bpx_opencl_world_handles(world, &context, NULL, NULL), BPX_OK);
    return context;
}

// The device buffers of the world's last device-resident cycle, read back: the count, and the
// pairs (min(count, capacity) of them) into got.
static uint64_t read_back(bpx_world *world, pair_list *got, size_t *capacity)
{
    void *pairs = NULL, *count = NULL;
    CHECK_STATUS(bpx_opencl_device_pairs(world, &pairs, &count, capacity), BPX_OK);
    cl_command_queue queue = queue_of(world);
    cl_ulong found = 0;
    CHECK(clEnqueueReadBuffer(queue, count, CL_TRUE, 0, sizeof found, &found, 0, NULL, NULL) ==
          CL_SUCCESS);
    size_t have = found < *capacity ? (size_t)found : *capacity;
    pair_list_reserve(got, have ? have : 1);
    got->count = have;
    if (have)
        CHECK(clEnqueueReadBuffer(queue, pairs, CL_TRUE, 0, have * sizeof(bpx_pair), got->pairs, 0,
                                  NULL, NULL) == CL_SUCCESS);
    return found;
}

static int capacity_reports; // cycles that said CAPACITY (then ran again)

// One device-resident cycle against want: collide_device, the test's consumer kernel enqueued
// behind it on the world's queue (no wait between), finish, then both buffers read back and
// compared byte for byte, and the consumer's findings with the host's. Returns finish's status
// (OK, or CAPACITY with the count and a consumer that saw the short room).
static bpx_status device_cycle(bpx_world *world, const pair_list *want)
{
    bpx_status s = bpx_opencl_collide_device(world);
    CHECK_MSG(s == BPX_OK, "collide_device: %s (%s)", check_status_name(s),
              bpx_world_error(world)->message);
    if (s != BPX_OK)
        return s;
    void *pairs = NULL, *count = NULL;
    size_t capacity = 0;
    CHECK_STATUS(bpx_opencl_device_pairs(world, &pairs, &count, &capacity), BPX_OK);
    cl_command_queue queue = queue_of(world);
    cl_mem out =
        clCreateBuffer(context_of(world), CL_MEM_READ_WRITE, 3 * sizeof(cl_uint), NULL, NULL);
    CHECK(out != NULL);
    cl_uint zero = 0, seen[3] = {0, 0, 0};
    cl_ulong capacity_arg = capacity;
    cl_mem pairs_mem = pairs, count_mem = count;
    CHECK(clEnqueueFillBuffer(queue, out, &zero, sizeof zero, 0, sizeof seen, 0, NULL, NULL) ==
          CL_SUCCESS);
    CHECK(clSetKernelArg(rig.consume, 0, sizeof pairs_mem, &pairs_mem) == CL_SUCCESS);
    CHECK(clSetKernelArg(rig.consume, 1, sizeof count_mem, &count_mem) == CL_SUCCESS);
    CHECK(clSetKernelArg(rig.consume, 2, sizeof capacity_arg, &capacity_arg) == CL_SUCCESS);
    CHECK(clSetKernelArg(rig.consume, 3, sizeof out, &out) == CL_SUCCESS);
    size_t global = round_up(capacity ? capacity : 1, 64);
    CHECK(clEnqueueNDRangeKernel(queue, rig.consume, 1, NULL, &global, NULL, 0, NULL, NULL) ==
          CL_SUCCESS);
    size_t found = 0;
    s = bpx_opencl_finish(world, &found);
    CHECK_MSG(s == BPX_OK || s == BPX_ERR_CAPACITY, "finish: %s (%s)", check_status_name(s),
              bpx_world_error(world)->message);
    CHECK_EQ_U64(found, want->count);
    if (s == BPX_ERR_CAPACITY)
        CHECK(bpx_world_error(world)->status == BPX_ERR_CAPACITY &&
              strstr(bpx_world_error(world)->message, "the next device-resident cycle has room"));
    CHECK(clEnqueueReadBuffer(queue, out, CL_TRUE, 0, sizeof seen, seen, 0, NULL, NULL) ==
          CL_SUCCESS);
    clReleaseMemObject(out);
    pair_list got = {0};
    size_t read_capacity = 0;
    CHECK_EQ_U64(read_back(world, &got, &read_capacity), want->count);
    CHECK_EQ_U64(read_capacity, capacity);
    if (s == BPX_OK) {
        CHECK(capacity >= want->count);
        CHECK_PAIRS_EQ(want->pairs, want->count, got.pairs, got.count);
        uint32_t even = 0, folded = 0;
        for (size_t k = 0; k < want->count; k++) {
            even += (want->pairs[k].i & 1u) == 0;
            folded += want->pairs[k].i ^ want->pairs[k].j;
        }
        CHECK_EQ_U64(seen[0], even);
        CHECK_EQ_U64(seen[1], folded);
        CHECK_EQ_U64(seen[2], 0);
        bpx_cycle_stats stats = bpx_world_stats(world);
        CHECK_EQ_U64(stats.pair_count, want->count);
        CHECK_EQ_U64(stats.bytes_out, sizeof(cl_ulong)); // the count alone comes back
    } else if (s == BPX_ERR_CAPACITY) {
        CHECK(capacity < want->count);
        CHECK_EQ_U64(seen[2], 1);
        CHECK_EQ_U64(seen[0] + seen[1], 0);
    }
    pair_list_free(&got);
    return s;
}

// A device-resident cycle that may find its room short once: then the next one, on the same
// boxes, has room and gives every pair.
static void checked_cycle(bpx_world *world, const pair_list *want)
{
    if (device_cycle(world, want) == BPX_ERR_CAPACITY) {
        capacity_reports++;
        CHECK_STATUS(device_cycle(world, want), BPX_OK);
    }
}

// ---------------------------------------------------------------------------------------------
// Every scene through every path, the boxes from each source, moving

typedef enum source { FROM_HOST, FROM_BOXES_BUFFER, FROM_CENTRES_BUFFER, SOURCE_COUNT } source;
static const char *const source_names[] = {"host boxes", "device boxes", "device centres"};

static const path paths[] = {
    {"brute", BPX_OPENCL_BRUTE, 0, 0},
    {"tree", BPX_OPENCL_TREE, 0, 0},
    {"sweep", BPX_OPENCL_SWEEP, 0, 0},
    {"auto", BPX_OPENCL_AUTO, 0, 0},
};

typedef struct scene {
    const char *name;
    int kind;
} scene;

static const scene scenes[] = {
    {"random", SCENE_UNIFORM_DENSITY},   {"dense", SCENE_DENSE},
    {"heavy-tailed", SCENE_MIXED_SIZES}, {"shared-x", SCENE_SHARED_COORD},
    {"all-overlap", SCENE_ALL_OVERLAP},  {"touching", SCENE_TOUCHING},
    {"signed-zero", SCENE_SIGNED_ZERO},
};

enum { CYCLES = 3 };

// The cycles a path ran, from the counters' change.
static uint64_t path_cycles(const bpx__opencl_counters *a, const bpx__opencl_counters *b,
                            int method, uint32_t n)
{
    if (method == BPX_OPENCL_AUTO)
        method = n < 2048 ? BPX_OPENCL_BRUTE : BPX_OPENCL_TREE;
    if (method == BPX_OPENCL_TREE)
        return b->tree_cycles - a->tree_cycles;
    if (method == BPX_OPENCL_SWEEP)
        return b->sweep_cycles - a->sweep_cycles;
    return b->brute_cycles - a->brute_cycles;
}

// CYCLES device-resident cycles of one scene through one path from one source, the boxes moved
// between cycles (on the host, or by the test's kernels on the device).
static void run_case(const scene *sc, uint32_t n, const path *p, source from)
{
    check_set_context("%s n=%u path=%s from %s", sc->name, n, p->name, source_names[from]);
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    CHECK(scene_generate(sc->kind, n, 31 + n, boxes) == 0);
    float *minima = check_alloc(sizeof(float) * 3 * n);
    float *centres = check_alloc(sizeof(float) * 3 * n);
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            float half = (boxes[i].max[a] - boxes[i].min[a]) * 0.5f;
            minima[3 * i + a] = -half;
            centres[3 * i + a] = boxes[i].min[a] + half;
        }
    bpx_world_def def = def_for(p->method);
    bpx_world *world = make(&def);
    cl_mem buffer = NULL;
    pair_list want = {0};
    if (!world)
        goto done;
    cl_command_queue queue = queue_of(world);
    cl_context context = context_of(world);
    cl_int err;
    if (from == FROM_BOXES_BUFFER) {
        buffer = clCreateBuffer(context, CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR,
                                sizeof(bpx_box) * n, boxes, &err);
        CHECK_STATUS(bpx_opencl_set_boxes_buffer(world, buffer, n), BPX_OK);
    } else if (from == FROM_CENTRES_BUFFER) {
        buffer = clCreateBuffer(context, CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR,
                                sizeof(float) * 3 * n, centres, &err);
        CHECK_STATUS(bpx_world_load_extents(world, minima, n), BPX_OK);
        CHECK_STATUS(bpx_opencl_set_centres_buffer(world, buffer, n), BPX_OK);
    }
    bpx__opencl_counters before = counters(world);
    for (uint32_t cycle = 0; cycle < CYCLES; cycle++) {
        if (from == FROM_CENTRES_BUFFER) {
            if (cycle > 0) {
                move_centres(centres, n, cycle);
                enqueue_move(queue, rig.move_centres, buffer, n, cycle);
            }
            for (uint32_t i = 0; i < n; i++)
                for (int a = 0; a < 3; a++) {
                    boxes[i].min[a] = centres[3 * i + a] + minima[3 * i + a];
                    boxes[i].max[a] = centres[3 * i + a] - minima[3 * i + a];
                }
        } else if (cycle > 0) {
            move_boxes(boxes, n, cycle);
            if (from == FROM_BOXES_BUFFER)
                enqueue_move(queue, rig.move_boxes, buffer, n, cycle);
        }
        if (from == FROM_HOST)
            CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
        reference_pairs(boxes, n, &want);
        checked_cycle(world, &want);
        if (from != FROM_HOST) // fully device-resident: only the count crossed the link
            CHECK_EQ_U64(bpx_world_stats(world).bytes_in, 0);
    }
    bpx__opencl_counters after = counters(world);
    CHECK(path_cycles(&before, &after, p->method, n) >= CYCLES);
    CHECK_EQ_U64(after.tree_fallbacks + after.sweep_fallbacks, 0);
    CHECK_EQ_U64(bpx_world_stats(world).cycle_count,
                 after.brute_cycles + after.tree_cycles + after.sweep_cycles);
done:
    if (buffer)
        clReleaseMemObject(buffer);
    bpx_world_destroy(world);
    pair_list_free(&want);
    free(boxes);
    free(minima);
    free(centres);
}

static void test_round_trips(void)
{
    // 190: the small-set kernel (brute force, up to 256 boxes on a CPU device, 512 on a GPU);
    // 1000: the tiled comparator; 2600: auto takes the tree.
    static const uint32_t sizes[] = {190, 1000};
    for (size_t s = 0; s < sizeof scenes / sizeof scenes[0]; s++)
        for (size_t z = 0; z < sizeof sizes / sizeof sizes[0]; z++)
            for (size_t p = 0; p < sizeof paths / sizeof paths[0]; p++)
                for (int from = 0; from < SOURCE_COUNT; from++)
                    run_case(&scenes[s], sizes[z], &paths[p], (source)from);
    for (int from = 0; from < SOURCE_COUNT; from++) {
        run_case(&scenes[0], 2600, &paths[3], (source)from);
        run_case(&scenes[2], 2600, &paths[3], (source)from);
    }
}

// ---------------------------------------------------------------------------------------------
// A room too small: CAPACITY with the count, nothing reported short, then room

static void test_capacity(void)
{
    for (size_t p = 0; p < 3; p++) {
        for (uint32_t n = 200; n <= 700; n += 500) { // the small-set kernel, then the tiled one
            check_set_context("capacity n=%u path=%s", n, paths[p].name);
            bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
            CHECK(scene_generate(SCENE_ALL_OVERLAP, n, 5, boxes) == 0);
            pair_list want = {0};
            reference_pairs(boxes, n, &want);
            bpx_world_def def = def_for(paths[p].method);
            def.opencl_pair_capacity = 1; // the first room: 2 pairs per box
            bpx_world *world = make(&def);
            if (world) {
                CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
                CHECK_STATUS(device_cycle(world, &want), BPX_ERR_CAPACITY);
                // Asked again, finish says the same; the next cycle has room for the count.
                size_t count = 0;
                CHECK_STATUS(bpx_opencl_finish(world, &count), BPX_ERR_CAPACITY);
                CHECK_EQ_U64(count, want.count);
                CHECK_STATUS(device_cycle(world, &want), BPX_OK);
                CHECK_STATUS(bpx_opencl_finish(world, &count), BPX_OK);
                CHECK_EQ_U64(count, want.count);
                bpx_world_destroy(world);
            }
            pair_list_free(&want);
            free(boxes);
        }
    }
    // A jump in the pair count between cycles (the room follows the last count): the boxes of
    // a device buffer turn from a sparse scene into one where all overlap.
    enum { n = 1500 };
    check_set_context("capacity: the count jumps");
    bpx_box *sparse = check_alloc(sizeof(bpx_box) * n), *all = check_alloc(sizeof(bpx_box) * n);
    CHECK(scene_generate(SCENE_SPARSE, n, 6, sparse) == 0);
    CHECK(scene_generate(SCENE_ALL_OVERLAP, n, 6, all) == 0);
    pair_list want_sparse = {0}, want_all = {0};
    reference_pairs(sparse, n, &want_sparse);
    reference_pairs(all, n, &want_all);
    bpx_world_def def = def_for(BPX_OPENCL_TREE);
    bpx_world *world = make(&def);
    if (world) {
        cl_mem buffer = clCreateBuffer(context_of(world), CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR,
                                       sizeof(bpx_box) * n, sparse, NULL);
        CHECK_STATUS(bpx_opencl_set_boxes_buffer(world, buffer, n), BPX_OK);
        CHECK_STATUS(device_cycle(world, &want_sparse), BPX_OK);
        CHECK(clEnqueueWriteBuffer(queue_of(world), buffer, CL_FALSE, 0, sizeof(bpx_box) * n, all,
                                   0, NULL, NULL) == CL_SUCCESS);
        CHECK_STATUS(device_cycle(world, &want_all), BPX_ERR_CAPACITY);
        CHECK_STATUS(device_cycle(world, &want_all), BPX_OK);
        // And back: the room stays, the sort covers the last count and a quarter more.
        CHECK(clEnqueueWriteBuffer(queue_of(world), buffer, CL_TRUE, 0, sizeof(bpx_box) * n, sparse,
                                   0, NULL, NULL) == CL_SUCCESS);
        CHECK_STATUS(device_cycle(world, &want_sparse), BPX_OK);
        CHECK_STATUS(device_cycle(world, &want_sparse), BPX_OK);
        clReleaseMemObject(buffer);
        bpx_world_destroy(world);
    }
    pair_list_free(&want_sparse);
    pair_list_free(&want_all);
    free(sparse);
    free(all);
}

// ---------------------------------------------------------------------------------------------
// The memory limit: the tree gives way to brute force, room past the limit, streaming refused

static void test_memory_limit(void)
{
    enum { n = 1000 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    pair_list want = {0};
    CHECK(scene_generate(SCENE_DENSE, n, 7, boxes) == 0);
    reference_pairs(boxes, n, &want);
    // The first room (65536 pairs) fits as brute force's pairs (8 bytes each) but not as the
    // tree's keys, sorted keys and pairs (24 bytes each).
    for (int method = BPX_OPENCL_SWEEP; method <= BPX_OPENCL_TREE; method++) {
        check_set_context("memory limit: %s gives way",
                          method == BPX_OPENCL_TREE ? "tree" : "sweep");
        bpx_world_def def = def_for(method);
        def.opencl_memory_limit = 1200 * 1024;
        bpx_world *world = make(&def);
        if (!world)
            continue;
        CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
        CHECK_STATUS(device_cycle(world, &want), BPX_OK);
        bpx__opencl_counters c = counters(world);
        CHECK_EQ_U64(c.brute_cycles, 1);
        CHECK_EQ_U64(method == BPX_OPENCL_TREE ? c.tree_fallbacks : c.sweep_fallbacks, 1);
        bpx_world_destroy(world);
    }
    // Room past the limit: CAPACITY first (the first room fits), then DEVICE_MEMORY when the
    // next cycle needs room for the count.
    check_set_context("memory limit: room for the pairs");
    CHECK(scene_generate(SCENE_ALL_OVERLAP, n, 7, boxes) == 0);
    reference_pairs(boxes, n, &want);
    bpx_world_def def = def_for(BPX_OPENCL_BRUTE);
    def.opencl_memory_limit = 2u << 20;
    bpx_world *world = make(&def);
    if (world) {
        CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
        CHECK_STATUS(device_cycle(world, &want), BPX_ERR_CAPACITY);
        CHECK_STATUS(bpx_opencl_collide_device(world), BPX_ERR_DEVICE_MEMORY);
        CHECK(strstr(bpx_world_error(world)->message, "memory limit") != NULL);
        CHECK_STATUS(bpx_opencl_device_pairs(world, NULL, NULL, NULL), BPX_ERR_BAD_STATE);
        // The host's cycle still reads them out in windows.
        CHECK_STATUS(bpx_world_collide(world), BPX_OK);
        size_t count = 0;
        const bpx_pair *pairs = bpx_world_pairs(world, &count);
        CHECK_PAIRS_EQ(want.pairs, want.count, pairs, count);
        bpx_world_destroy(world);
    }
    // Streamed blocks are refused, whether asked for or forced by the limit.
    check_set_context("memory limit: streaming refused");
    CHECK(scene_generate(SCENE_UNIFORM_DENSITY, n, 7, boxes) == 0);
    def = def_for(BPX_OPENCL_AUTO);
    def.opencl_block_boxes = 256;
    world = make(&def);
    if (world) {
        CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
        CHECK_STATUS(bpx_opencl_collide_device(world), BPX_ERR_BAD_STATE);
        CHECK(strstr(bpx_world_error(world)->message, "opencl_block_boxes") != NULL);
        bpx_world_destroy(world);
    }
    def = def_for(BPX_OPENCL_AUTO);
    def.opencl_memory_limit = 128 * 1024;
    world = make(&def);
    if (world) {
        CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
        CHECK_STATUS(bpx_opencl_collide_device(world), BPX_ERR_BAD_STATE);
        CHECK(strstr(bpx_world_error(world)->message, "memory limit") != NULL);
        CHECK_STATUS(bpx_opencl_finish(world, NULL), BPX_ERR_BAD_STATE);
        reference_pairs(boxes, n, &want);
        CHECK_STATUS(bpx_world_collide(world), BPX_OK); // the host's cycle streams them
        size_t count = 0;
        const bpx_pair *pairs = bpx_world_pairs(world, &count);
        CHECK_PAIRS_EQ(want.pairs, want.count, pairs, count);
        CHECK(counters(world).streamed_blocks > 0);
        bpx_world_destroy(world);
    }
    pair_list_free(&want);
    free(boxes);
}

// ---------------------------------------------------------------------------------------------
// Host and device cycles on one world, removed objects, sizes 0 and 1, and the errors

static void test_mixed_and_objects(void)
{
    enum { n = 400 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    CHECK(scene_generate(SCENE_DENSE, n, 8, boxes) == 0);
    pair_list want = {0}, got = {0};
    reference_pairs(boxes, n, &want);
    bpx_world_def def = def_for(BPX_OPENCL_AUTO);
    bpx_world *world = make(&def);
    if (!world)
        goto done;
    check_set_context("mixed host and device cycles");
    CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_world_collide(world), BPX_OK);
    CHECK_STATUS(device_cycle(world, &want), BPX_OK);
    size_t count = 7;
    CHECK(bpx_world_pairs(world, &count) == NULL); // the host's pairs are not the last cycle's
    CHECK_EQ_U64(count, 0);
    CHECK_STATUS(bpx_world_collide(world), BPX_OK);
    const bpx_pair *pairs = bpx_world_pairs(world, &count);
    CHECK_PAIRS_EQ(want.pairs, want.count, pairs, count);
    CHECK_STATUS(bpx_opencl_device_pairs(world, NULL, NULL, NULL), BPX_ERR_BAD_STATE);
    CHECK_STATUS(bpx_opencl_finish(world, &count), BPX_ERR_BAD_STATE);
    // A host cycle and the setters wait for a device cycle still in flight.
    CHECK_STATUS(bpx_opencl_collide_device(world), BPX_OK);
    CHECK_STATUS(bpx_world_collide(world), BPX_OK);
    pairs = bpx_world_pairs(world, &count);
    CHECK_PAIRS_EQ(want.pairs, want.count, pairs, count);
    CHECK_STATUS(bpx_opencl_collide_device(world), BPX_OK);
    CHECK_STATUS(bpx_opencl_collide_device(world), BPX_OK); // the previous one unfinished
    CHECK_STATUS(bpx_opencl_finish(world, &count), BPX_OK);
    CHECK_EQ_U64(count, want.count);
    size_t capacity = 0;
    CHECK_EQ_U64(read_back(world, &got, &capacity), want.count);
    CHECK_PAIRS_EQ(want.pairs, want.count, got.pairs, got.count);

    // Removed objects are inert in the device's cycle too; their ids are reused after it.
    check_set_context("removed objects");
    uint32_t removed[] = {3, 17, 200, 399};
    CHECK_STATUS(bpx_world_remove_boxes(world, removed, 4), BPX_OK);
    pair_list want_inert = {0};
    pair_list_reserve(&want_inert, want.count);
    for (size_t k = 0; k < want.count; k++) {
        bool gone = false;
        for (int r = 0; r < 4; r++)
            gone |= want.pairs[k].i == removed[r] || want.pairs[k].j == removed[r];
        if (!gone)
            want_inert.pairs[want_inert.count++] = want.pairs[k];
    }
    CHECK(want_inert.count < want.count);
    CHECK_STATUS(device_cycle(world, &want_inert), BPX_OK);
    uint32_t ids[4] = {0};
    CHECK_STATUS(bpx_world_add_boxes(world, boxes + 3, 1, ids), BPX_OK);
    CHECK(ids[0] == 3 || ids[0] == 17 || ids[0] == 200 || ids[0] == 399);
    CHECK_STATUS(bpx_world_collide(world), BPX_OK);

    // Nothing or one box: an empty set, on the device too.
    check_set_context("sizes 0 and 1");
    pair_list none = {0};
    for (uint32_t m = 0; m < 2; m++) {
        CHECK_STATUS(bpx_world_set_boxes(world, boxes, m), BPX_OK);
        CHECK_STATUS(device_cycle(world, &none), BPX_OK);
    }
    // Destroyed with a device cycle in flight.
    CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
    CHECK_STATUS(bpx_opencl_collide_device(world), BPX_OK);
    bpx_world_destroy(world);
    pair_list_free(&want_inert);
done:
    pair_list_free(&want);
    pair_list_free(&got);
    free(boxes);
}

static void test_errors(void)
{
    enum { n = 100 };
    bpx_box *boxes = check_alloc(sizeof(bpx_box) * n);
    CHECK(scene_generate(SCENE_DENSE, n, 9, boxes) == 0);
    check_set_context("errors: calls out of order");
    bpx_world_def def = def_for(BPX_OPENCL_AUTO);
    bpx_world *world = make(&def);
    if (world) {
        void *pairs = &def, *count = &def;
        size_t capacity = 5, found = 5;
        CHECK_STATUS(bpx_opencl_device_pairs(world, &pairs, &count, &capacity), BPX_ERR_BAD_STATE);
        CHECK(strstr(bpx_world_error(world)->message, "no device-resident cycle") != NULL);
        CHECK_STATUS(bpx_opencl_finish(world, &found), BPX_ERR_BAD_STATE);
        CHECK_EQ_U64(found, 0);
        CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
        // Filters need the host's pairs: refused once set.
        check_set_context("errors: filters");
        uint32_t category = 2, mask = 1;
        CHECK_STATUS(bpx_world_set_filters(world, NULL, &category, &mask, 1), BPX_OK);
        CHECK_STATUS(bpx_opencl_collide_device(world), BPX_ERR_BAD_STATE);
        CHECK(strstr(bpx_world_error(world)->message, "filters") != NULL);
        CHECK_STATUS(bpx_opencl_device_pairs(world, NULL, NULL, NULL), BPX_ERR_BAD_STATE);
        bpx_world_destroy(world);
    }
    check_set_context("errors: events");
    def.track_events = true;
    world = make(&def);
    if (world) {
        CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
        CHECK_STATUS(bpx_opencl_collide_device(world), BPX_ERR_BAD_STATE);
        CHECK(strstr(bpx_world_error(world)->message, "events") != NULL);
        CHECK_STATUS(bpx_world_collide(world), BPX_OK); // the host's cycle applies them
        bpx_world_destroy(world);
    }
    check_set_context("errors: another backend, no world");
    bpx_world_def cpu = bpx_default_world_def();
    world = make(&cpu);
    if (world) {
        CHECK_STATUS(bpx_world_set_boxes(world, boxes, n), BPX_OK);
        CHECK_STATUS(bpx_opencl_collide_device(world), BPX_ERR_BACKEND_UNAVAILABLE);
        CHECK_STATUS(bpx_opencl_device_pairs(world, NULL, NULL, NULL), BPX_ERR_BACKEND_UNAVAILABLE);
        CHECK_STATUS(bpx_opencl_finish(world, NULL), BPX_ERR_BACKEND_UNAVAILABLE);
        bpx_world_destroy(world);
    }
    CHECK_STATUS(bpx_opencl_collide_device(NULL), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_opencl_device_pairs(NULL, NULL, NULL, NULL), BPX_ERR_NULL_ARGUMENT);
    CHECK_STATUS(bpx_opencl_finish(NULL, NULL), BPX_ERR_NULL_ARGUMENT);
    free(boxes);
}

#endif

int main(void)
{
#if !BPX_TEST_OPENCL
    printf("test_opencl_resident: no OpenCL in this build\n");
    CHECK_STATUS(bpx_opencl_collide_device(NULL), BPX_ERR_NULL_ARGUMENT);
    return check_finish("test_opencl_resident", 0);
#else
    bpx_backend_info info = opencl_info("test_opencl_resident");
    if (!info.available)
        return opencl_unavailable("test_opencl_resident", info);
    bpx_world_def def = def_for(BPX_OPENCL_AUTO);
    bpx_world *world = make(&def);
    bool ready = world && rig_ready(world); // the test's kernels, in the device's context
    bpx_world_destroy(world);
    if (!ready)
        return check_finish("test_opencl_resident", 1);
    test_errors();
    test_mixed_and_objects();
    test_capacity();
    test_memory_limit();
    test_round_trips();
    printf("test_opencl_resident: %d cycles found their room short and ran again\n",
           capacity_reports);
    rig_free();
    return check_finish("test_opencl_resident", 1);
#endif
}
