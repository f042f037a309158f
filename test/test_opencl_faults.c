// The opencl backend when the device fails under it: every OpenCL call that touches the device
// (enqueues, waits, buffer creation) is wrapped at link time (-Wl,--wrap, see CMakeLists.txt),
// and each case is run again with its k-th call failing, for every k of a cycle (or a spread of
// them), in three ways:
//   transient: only call k fails (a launch refused, a read that did not happen);
//   lost:      call k and every later one fail, as on a device lost mid-cycle;
//   no memory: buffer creation k fails with CL_MEM_OBJECT_ALLOCATION_FAILURE.
// Each cycle must then end, without hanging, with the pairs of the reference or with DEVICE,
// DEVICE_MEMORY or OUT_OF_MEMORY and a message; never OK with wrong pairs. After a transient
// fault or a failed allocation the same world answers the next cycle exactly (nothing lost);
// after a loss it keeps failing with an error, is destroyed without a leak, and a new world
// works. Covered: the small-n kernel, brute force (tiled and streamed, with a pair buffer that
// must grow), the sweep, the tree, the two-phase mode (centres from the host), device-resident
// cycles (bpx_opencl_collide_device / _finish) and the hybrid backend's device side.
// Without OpenCL in the build or without a platform it is skipped (77).
#include <signal.h>
#include <unistd.h>

#include "opencl_util.h"

#if BPX_TEST_OPENCL

// ---------------------------------------------------------------------------------------------
// The wrapped calls

typedef enum fault_mode { FAULT_OFF, FAULT_TRANSIENT, FAULT_LOST, FAULT_NO_MEMORY } fault_mode;

static struct {
    fault_mode mode;
    long target;    // the call (or, for FAULT_NO_MEMORY, the buffer creation) that fails
    long calls;     // device calls since faults_arm
    long creations; // clCreateBuffer calls since faults_arm
    long fired;     // calls failed
    bool plain;     // FAULT_TRANSIENT: fail with a code that is no memory error
} fault;

static long tally_trials[4], tally_errors[4]; // per mode: trials, and those a cycle failed

static void faults_arm(fault_mode mode, long target)
{
    fault.mode = mode;
    fault.target = target;
    fault.calls = fault.creations = fault.fired = 0;
}

// Whether this device call fails, and with which code (CL_SUCCESS: it goes through).
static cl_int device_call(void)
{
    long k = fault.calls++;
    bool fails = (fault.mode == FAULT_TRANSIENT && k == fault.target) ||
                 (fault.mode == FAULT_LOST && k >= fault.target);
    if (!fails)
        return CL_SUCCESS;
    fault.fired++;
    // What NVIDIA's driver answers: the failing command, then a queue that is gone. A memory
    // error may be absorbed (the backend falls back to a path that needs less room), so half
    // the transient trials fail with a code that must reach the caller.
    if (fault.mode == FAULT_TRANSIENT)
        return fault.plain ? CL_INVALID_OPERATION : CL_OUT_OF_RESOURCES;
    return k > fault.target ? CL_INVALID_COMMAND_QUEUE : CL_OUT_OF_RESOURCES;
}

cl_int __real_clEnqueueNDRangeKernel(cl_command_queue, cl_kernel, cl_uint, const size_t *,
                                     const size_t *, const size_t *, cl_uint, const cl_event *,
                                     cl_event *);
cl_int __wrap_clEnqueueNDRangeKernel(cl_command_queue q, cl_kernel k, cl_uint dims,
                                     const size_t *offset, const size_t *global,
                                     const size_t *local, cl_uint waits, const cl_event *wait,
                                     cl_event *event)
{
    cl_int err = device_call();
    return err != CL_SUCCESS ? err
                             : __real_clEnqueueNDRangeKernel(q, k, dims, offset, global, local,
                                                             waits, wait, event);
}

cl_int __real_clEnqueueReadBuffer(cl_command_queue, cl_mem, cl_bool, size_t, size_t, void *,
                                  cl_uint, const cl_event *, cl_event *);
cl_int __wrap_clEnqueueReadBuffer(cl_command_queue q, cl_mem mem, cl_bool blocking, size_t offset,
                                  size_t size, void *host, cl_uint waits, const cl_event *wait,
                                  cl_event *event)
{
    cl_int err = device_call();
    return err != CL_SUCCESS ? err
                             : __real_clEnqueueReadBuffer(q, mem, blocking, offset, size, host,
                                                          waits, wait, event);
}

cl_int __real_clEnqueueWriteBuffer(cl_command_queue, cl_mem, cl_bool, size_t, size_t,
                                   const void *, cl_uint, const cl_event *, cl_event *);
cl_int __wrap_clEnqueueWriteBuffer(cl_command_queue q, cl_mem mem, cl_bool blocking, size_t offset,
                                   size_t size, const void *host, cl_uint waits,
                                   const cl_event *wait, cl_event *event)
{
    cl_int err = device_call();
    return err != CL_SUCCESS ? err
                             : __real_clEnqueueWriteBuffer(q, mem, blocking, offset, size, host,
                                                           waits, wait, event);
}

cl_int __real_clEnqueueFillBuffer(cl_command_queue, cl_mem, const void *, size_t, size_t, size_t,
                                  cl_uint, const cl_event *, cl_event *);
cl_int __wrap_clEnqueueFillBuffer(cl_command_queue q, cl_mem mem, const void *pattern,
                                  size_t pattern_size, size_t offset, size_t size, cl_uint waits,
                                  const cl_event *wait, cl_event *event)
{
    cl_int err = device_call();
    return err != CL_SUCCESS ? err
                             : __real_clEnqueueFillBuffer(q, mem, pattern, pattern_size, offset,
                                                          size, waits, wait, event);
}

cl_int __real_clEnqueueCopyBuffer(cl_command_queue, cl_mem, cl_mem, size_t, size_t, size_t,
                                  cl_uint, const cl_event *, cl_event *);
cl_int __wrap_clEnqueueCopyBuffer(cl_command_queue q, cl_mem src, cl_mem dst, size_t src_offset,
                                  size_t dst_offset, size_t size, cl_uint waits,
                                  const cl_event *wait, cl_event *event)
{
    cl_int err = device_call();
    return err != CL_SUCCESS ? err
                             : __real_clEnqueueCopyBuffer(q, src, dst, src_offset, dst_offset,
                                                          size, waits, wait, event);
}

void *__real_clEnqueueMapBuffer(cl_command_queue, cl_mem, cl_bool, cl_map_flags, size_t, size_t,
                                cl_uint, const cl_event *, cl_event *, cl_int *);
void *__wrap_clEnqueueMapBuffer(cl_command_queue q, cl_mem mem, cl_bool blocking,
                                cl_map_flags flags, size_t offset, size_t size, cl_uint waits,
                                const cl_event *wait, cl_event *event, cl_int *errcode)
{
    cl_int err = device_call();
    if (err != CL_SUCCESS) {
        if (errcode)
            *errcode = err;
        return NULL;
    }
    return __real_clEnqueueMapBuffer(q, mem, blocking, flags, offset, size, waits, wait, event,
                                     errcode);
}

// A failed wait still waits: a driver that reports a lost device has stopped writing into the
// host's memory by then, and the test must not free memory PoCL is still filling.
cl_int __real_clFinish(cl_command_queue);
cl_int __wrap_clFinish(cl_command_queue q)
{
    cl_int real = __real_clFinish(q);
    cl_int err = device_call();
    return err != CL_SUCCESS ? err : real;
}

cl_int __real_clWaitForEvents(cl_uint, const cl_event *);
cl_int __wrap_clWaitForEvents(cl_uint count, const cl_event *events)
{
    cl_int real = __real_clWaitForEvents(count, events);
    cl_int err = device_call();
    return err != CL_SUCCESS ? err : real;
}

cl_int __real_clFlush(cl_command_queue);
cl_int __wrap_clFlush(cl_command_queue q)
{
    cl_int err = device_call();
    return err != CL_SUCCESS ? err : __real_clFlush(q);
}

cl_mem __real_clCreateBuffer(cl_context, cl_mem_flags, size_t, void *, cl_int *);
cl_mem __wrap_clCreateBuffer(cl_context context, cl_mem_flags flags, size_t size, void *host,
                             cl_int *errcode)
{
    long k = fault.creations++;
    cl_int err = fault.mode == FAULT_NO_MEMORY && k == fault.target ? CL_MEM_OBJECT_ALLOCATION_FAILURE
                                                                     : device_call();
    if (err != CL_SUCCESS) {
        if (fault.mode == FAULT_NO_MEMORY)
            fault.fired++;
        if (errcode)
            *errcode = err;
        return NULL;
    }
    return __real_clCreateBuffer(context, flags, size, host, errcode);
}

// ---------------------------------------------------------------------------------------------
// A hang is a failure, named

static char hang_context[256];

static void on_alarm(int sig)
{
    (void)sig;
    static const char head[] = "test_opencl_faults: HANG (no answer in 120 s): ";
    ssize_t ignored = write(2, head, sizeof head - 1);
    ignored = write(2, hang_context, strlen(hang_context));
    ignored = write(2, "\n", 1);
    (void)ignored;
    _exit(1);
}

// ---------------------------------------------------------------------------------------------
// The cases

typedef enum feed { FEED_BOXES, FEED_CENTRES, FEED_RESIDENT } feed;

typedef struct fault_case {
    const char *name;
    bpx_backend backend;
    int method;
    uint32_t block_boxes, pair_capacity;
    feed feed;
    scene_kind scene;
    uint32_t n;
} fault_case;

static const fault_case cases[] = {
    {"small", BPX_BACKEND_OPENCL, BPX_OPENCL_AUTO, 0, 0, FEED_BOXES, SCENE_DENSE, 300},
    {"brute", BPX_BACKEND_OPENCL, BPX_OPENCL_BRUTE, 0, 0, FEED_BOXES, SCENE_MIXED_SIZES, 3000},
    {"streamed", BPX_BACKEND_OPENCL, BPX_OPENCL_BRUTE, 192, 1024, FEED_BOXES, SCENE_DENSE, 1500},
    {"sweep", BPX_BACKEND_OPENCL, BPX_OPENCL_SWEEP, 0, 0, FEED_BOXES, SCENE_SHARED_COORD, 3000},
    {"tree", BPX_BACKEND_OPENCL, BPX_OPENCL_TREE, 0, 1024, FEED_BOXES, SCENE_UNIFORM_DENSITY,
     20000},
    {"centres", BPX_BACKEND_OPENCL, BPX_OPENCL_AUTO, 0, 0, FEED_CENTRES, SCENE_MIXED_SIZES, 5000},
    {"resident", BPX_BACKEND_OPENCL, BPX_OPENCL_TREE, 0, 1024, FEED_RESIDENT,
     SCENE_UNIFORM_DENSITY, 20000},
    {"hybrid", BPX_BACKEND_HYBRID, BPX_OPENCL_AUTO, 0, 0, FEED_BOXES, SCENE_UNIFORM_DENSITY,
     30000},
};
enum { case_count = sizeof cases / sizeof cases[0], cycles = 2 };

// One case's inputs: per cycle, the boxes (FEED_BOXES, FEED_RESIDENT) or the centres
// (FEED_CENTRES, with minima), and the pairs the reference finds.
typedef struct inputs {
    uint32_t n;
    bpx_box *boxes[cycles];
    float *minima, *centres[cycles];
    pair_list want[cycles];
} inputs;

static void inputs_make(const fault_case *c, inputs *in)
{
    memset(in, 0, sizeof *in);
    in->n = c->n;
    bpx_box *base = check_alloc(sizeof(bpx_box) * c->n);
    CHECK(scene_generate(c->scene, c->n, 11, base) == 0);
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_REFERENCE;
    bpx_world *oracle = make(&def);
    if (c->feed == FEED_CENTRES) {
        in->minima = check_alloc(sizeof(float) * 3 * c->n);
        for (uint32_t i = 0; i < c->n; i++)
            for (int a = 0; a < 3; a++)
                in->minima[3 * i + a] = 0.5f * (base[i].min[a] - base[i].max[a]);
        CHECK_STATUS(bpx_world_load_extents(oracle, in->minima, c->n), BPX_OK);
    }
    for (int t = 0; t < cycles; t++) {
        // Cycle t moves every box by t quarter units along a diagonal.
        float d = 0.25f * (float)t;
        if (c->feed == FEED_CENTRES) {
            in->centres[t] = check_alloc(sizeof(float) * 3 * c->n);
            for (uint32_t i = 0; i < c->n; i++)
                for (int a = 0; a < 3; a++)
                    in->centres[t][3 * i + a] = 0.5f * (base[i].min[a] + base[i].max[a]) + d;
            CHECK_STATUS(bpx_world_update_centres(oracle, in->centres[t]), BPX_OK);
        } else {
            in->boxes[t] = check_alloc(sizeof(bpx_box) * c->n);
            for (uint32_t i = 0; i < c->n; i++)
                for (int a = 0; a < 3; a++) {
                    in->boxes[t][i].min[a] = base[i].min[a] + d;
                    in->boxes[t][i].max[a] = base[i].max[a] + d;
                }
            CHECK_STATUS(bpx_world_set_boxes(oracle, in->boxes[t], c->n), BPX_OK);
        }
        CHECK_STATUS(bpx_world_collide(oracle), BPX_OK);
        size_t count = 0;
        const bpx_pair *pairs = bpx_world_pairs(oracle, &count);
        pair_list_reserve(&in->want[t], count ? count : 1);
        memcpy(in->want[t].pairs, pairs, sizeof(bpx_pair) * count);
        in->want[t].count = count;
    }
    bpx_world_destroy(oracle);
    free(base);
}

static void inputs_free(inputs *in)
{
    free(in->minima);
    for (int t = 0; t < cycles; t++) {
        free(in->boxes[t]);
        free(in->centres[t]);
        free(in->want[t].pairs);
    }
}

static bpx_world *case_world(const fault_case *c, const inputs *in)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = c->backend;
    def.opencl_method = c->method;
    def.opencl_block_boxes = c->block_boxes;
    def.opencl_pair_capacity = c->pair_capacity;
    if (c->backend == BPX_BACKEND_HYBRID)
        def.hybrid_device_share = 0.5f;
    bpx_world *world = make(&def);
    if (world && c->feed == FEED_CENTRES)
        CHECK_STATUS(bpx_world_load_extents(world, in->minima, in->n), BPX_OK);
    return world;
}

// The pairs of a device-resident cycle, read back from the world's device buffer.
static bpx_status resident_pairs(bpx_world *world, pair_list *got)
{
    size_t count = 0;
    bpx_status s = bpx_opencl_finish(world, &count);
    if (s != BPX_OK)
        return s;
    void *pairs_buffer = NULL, *count_buffer = NULL, *queue = NULL;
    size_t capacity = 0;
    CHECK_STATUS(bpx_opencl_device_pairs(world, &pairs_buffer, &count_buffer, &capacity), BPX_OK);
    CHECK_STATUS(bpx_opencl_world_handles(world, NULL, &queue, NULL), BPX_OK);
    pair_list_reserve(got, count ? count : 1);
    got->count = count;
    if (count > 0) {
        cl_int err = __real_clEnqueueReadBuffer(queue, pairs_buffer, CL_TRUE, 0,
                                                sizeof(bpx_pair) * count, got->pairs, 0, NULL,
                                                NULL);
        CHECK(err == CL_SUCCESS);
    }
    return BPX_OK;
}

// One cycle of the case on `world`: its status, with the pairs in got when OK.
static bpx_status run_cycle(const fault_case *c, const inputs *in, bpx_world *world, int t,
                            pair_list *got)
{
    bpx_status s = c->feed == FEED_CENTRES ? bpx_world_update_centres(world, in->centres[t])
                                           : bpx_world_set_boxes(world, in->boxes[t], in->n);
    if (s != BPX_OK)
        return s;
    if (c->feed == FEED_RESIDENT) {
        if ((s = bpx_opencl_collide_device(world)) != BPX_OK)
            return s;
        return resident_pairs(world, got);
    }
    if ((s = bpx_world_collide(world)) != BPX_OK)
        return s;
    size_t count = 0;
    const bpx_pair *pairs = bpx_world_pairs(world, &count);
    pair_list_reserve(got, count ? count : 1);
    memcpy(got->pairs, pairs, sizeof(bpx_pair) * count);
    got->count = count;
    return BPX_OK;
}

// A cycle that ended: exact when OK, else a device or memory status with a message.
static void check_outcome(bpx_world *world, bpx_status s, const pair_list *got,
                          const pair_list *want)
{
    if (s == BPX_OK) {
        CHECK_PAIRS_EQ(want->pairs, want->count, got->pairs, got->count);
        return;
    }
    CHECK_MSG(s == BPX_ERR_DEVICE || s == BPX_ERR_DEVICE_MEMORY || s == BPX_ERR_OUT_OF_MEMORY,
              "status %s (%s)", check_status_name(s), bpx_world_error(world)->message);
    CHECK_MSG(fault.fired > 0, "%s with no fault", check_status_name(s));
    const bpx_error *e = bpx_world_error(world);
    CHECK_MSG(e->status == s && e->message[0] != '\0', "error %s: '%s'",
              check_status_name(e->status), e->message);
    CHECK_MSG(strstr(log_text, "failed") != NULL, "no failed call logged: %.120s", log_text);
}

// The calls (device calls, buffer creations) of a case's cycles without faults, from a new
// world on: the range of k to try.
static void count_calls(const fault_case *c, const inputs *in, long *calls, long *creations)
{
    faults_arm(FAULT_OFF, 0);
    bpx_world *world = case_world(c, in);
    pair_list got = {0};
    for (int t = 0; world && t < cycles; t++) {
        bpx_status s = run_cycle(c, in, world, t, &got);
        CHECK_MSG(s == BPX_OK, "no fault: %s (%s)", check_status_name(s),
                  bpx_world_error(world)->message);
        if (s == BPX_OK)
            CHECK_PAIRS_EQ(in->want[t].pairs, in->want[t].count, got.pairs, got.count);
    }
    *calls = fault.calls;
    *creations = fault.creations;
    bpx_world_destroy(world);
    free(got.pairs);
}

// One trial: a new world, the case's cycles with the fault armed, then what must follow.
static void trial(const fault_case *c, const inputs *in, fault_mode mode, long target, bool plain)
{
    static const char *mode_names[] = {"off", "transient", "lost", "no memory"};
    check_set_context("case=%s mode=%s%s k=%ld", c->name, mode_names[mode],
                      plain ? " (plain)" : "", target);
    snprintf(hang_context, sizeof hang_context, "%s", check_context);
    alarm(120);
    log_reset();
    faults_arm(mode, target);
    fault.plain = plain;
    bpx_world *world = case_world(c, in);
    pair_list got = {0};
    bool failed = false;
    for (int t = 0; world && t < cycles; t++) {
        bpx_status s = run_cycle(c, in, world, t, &got);
        check_outcome(world, s, &got, &in->want[t]);
        failed |= s != BPX_OK;
        // A lost device stays lost: once a cycle failed, every later one must too.
        if (mode == FAULT_LOST && failed)
            CHECK_MSG(s != BPX_OK, "cycle %d OK on a lost device", t);
    }
    tally_trials[mode]++;
    tally_errors[mode] += failed;
    if (world && mode == FAULT_LOST && fault.fired > 0) {
        // Still lost: an error again, not a hang, not OK.
        bpx_status s = run_cycle(c, in, world, cycles - 1, &got);
        CHECK_MSG(s == BPX_ERR_DEVICE || s == BPX_ERR_DEVICE_MEMORY, "lost, again: %s",
                  check_status_name(s));
        bpx_world_destroy(world);
        faults_arm(FAULT_OFF, 0);
        world = case_world(c, in); // the device back: a new world works
    }
    faults_arm(FAULT_OFF, 0);
    for (int t = 0; world && t < cycles; t++) {
        bpx_status s = run_cycle(c, in, world, t, &got);
        CHECK_MSG(s == BPX_OK, "after the fault, cycle %d: %s (%s)", t, check_status_name(s),
                  bpx_world_error(world)->message);
        if (s == BPX_OK)
            CHECK_PAIRS_EQ(in->want[t].pairs, in->want[t].count, got.pairs, got.count);
    }
    bpx_world_destroy(world);
    free(got.pairs);
    alarm(0);
}

// Every k up to `limit` trials, else an even spread that keeps the first and last calls.
static void trials(const fault_case *c, const inputs *in, fault_mode mode, long range, long limit)
{
    long step = range <= limit ? 1 : (range + limit - 1) / limit, made = 0;
    for (long k = 0; k < range; k += step)
        trial(c, in, mode, k, made++ % 2 == 1);
    if (range > 0 && (range - 1) % step != 0)
        trial(c, in, mode, range - 1, made % 2 == 1);
}

int main(void)
{
    bpx_backend_info info = opencl_info("test_opencl_faults");
    if (!info.available)
        return opencl_unavailable("test_opencl_faults", info);
    bpx_set_logger(capture_log, NULL);
    signal(SIGALRM, on_alarm);
    long limit = check_quick() ? 12 : 48;
    for (int ci = 0; ci < case_count; ci++) {
        const fault_case *c = &cases[ci];
        if (c->backend == BPX_BACKEND_HYBRID && !bpx_backend_query(BPX_BACKEND_HYBRID).available)
            continue;
        inputs in;
        inputs_make(c, &in);
        long calls = 0, creations = 0;
        check_set_context("case=%s, no fault", c->name);
        count_calls(c, &in, &calls, &creations);
        memset(tally_trials, 0, sizeof tally_trials);
        memset(tally_errors, 0, sizeof tally_errors);
        trials(c, &in, FAULT_TRANSIENT, calls, limit);
        trials(c, &in, FAULT_LOST, calls, limit);
        trials(c, &in, FAULT_NO_MEMORY, creations, limit);
        printf("  %-9s n=%-6u %4ld device calls, %3ld buffers in %d cycles; trials with an error: "
               "transient %ld/%ld, lost %ld/%ld, no memory %ld/%ld\n",
               c->name, c->n, calls, creations, cycles, tally_errors[FAULT_TRANSIENT],
               tally_trials[FAULT_TRANSIENT], tally_errors[FAULT_LOST], tally_trials[FAULT_LOST],
               tally_errors[FAULT_NO_MEMORY], tally_trials[FAULT_NO_MEMORY]);
        inputs_free(&in);
    }
    bpx_set_logger(NULL, NULL);
    return check_finish("test_opencl_faults", 1);
}

#else

int main(void)
{
    return check_finish("test_opencl_faults", 0);
}

#endif
