// The opencl backend: the paper's coprocessor on an OpenCL device (a GPU, a CPU through PoCL, an
// FPGA toolchain's device). Paper modules: the updater, the comparator and the emitter on the
// device; the CPU-coprocessor interface is the link and its counted transfers.
//
// Per cycle: the updater (centres + stored minima -> boxes, or boxes as given) runs on the device
// and writes keys (twin.h); the comparator (brute.cl: tiles in local memory, or sweep.cl: a radix
// sort on min x and a sweep, for large n) counts each row's hits; a scan turns the counts into
// places and the collision count (the paper's register), which the host reads; the emitter
// kernel writes the pairs in (i, j) order and the host reads them into the world's block. For
// the largest sets a tree (tree.cl: a linear BVH built every cycle) finds the pairs instead, as
// 64-bit keys that a radix sort puts in (i, j) order.
// Buffers live as long as the world and only grow. Boxes beyond the memory limit are streamed in
// blocks; pairs beyond it are read out in windows. Every command gets an event, and the events'
// device times give the cycle's transfer and compute times (bpx_cycle_stats).

#include <string.h>

#include "core/clock.h"
#include "core/log.h"
#include "core/validate.h"
#include "state.h"

// ---------------------------------------------------------------------------------------------
// The backend

static bool opencl_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    const bpx_cl_device *dev;
    return bpx__cl_device_get(def, &dev, reason, detail, size);
}

// How many boxes fit on the device at once under the limit (0: not even one tile).
static uint32_t block_capacity(const bpx_cl_state *st, uint64_t bytes_per_box)
{
    // A minimal pair window, and the rounding of a dozen buffers to 4 KiB.
    uint64_t reserve = (uint64_t)1024 * sizeof(bpx_pair) + 16 * 4096;
    uint64_t free = st->limit > st->used ? st->limit - st->used : 0;
    // Buffers this cycle will reuse count as free.
    free += st->lo.size + st->hi.size + st->lo_b.size + st->hi_b.size + st->input.size +
            st->row_count.size + st->stash.size;
    if (free <= reserve)
        return 0;
    uint64_t boxes = (free - reserve) / bytes_per_box;
    uint64_t by_alloc = st->dev->max_alloc / (6 * sizeof(float) * 2);
    if (boxes > by_alloc)
        boxes = by_alloc;
    boxes = boxes / st->tile * st->tile;
    return boxes > BPX_MAX_BOXES ? BPX_MAX_BOXES : (uint32_t)boxes;
}

// The sort and sweep's and the tree's own buffers (a whole-set cycle keeps them for the next).
void bpx__cl_release_sweep_buffers(bpx_cl_state *st)
{
    bpx_cl_buffer *sweep_set[] = {
        &st->keys[0],   &st->keys[1],    &st->values[0],    &st->values[1],   &st->sorted_lo,
        &st->sorted_hi, &st->counts,     &st->offsets,      &st->pi[0],       &st->pi[1],
        &st->pj[0],     &st->pj[1],      &st->leaf_parent,  &st->node_parent, &st->nodes,
        &st->flags,     &st->walk_tests, &st->pair_keys[0], &st->pair_keys[1]};
    for (size_t k = 0; k < sizeof sweep_set / sizeof sweep_set[0]; k++)
        bpx__cl_dbuf_release(st, sweep_set[k]);
}

// BAD_STATE for boxes from a device buffer in a world whose objects were added and removed one
// by one; host centres give way to the host's boxes there (removed objects are inert in those
// only).
bpx_status bpx__cl_check_source(bpx_cl_state *st, const bpx_cycle *cycle)
{
    if ((st->source == SOURCE_BUFFER || st->source == SOURCE_CENTRES_BUFFER) && cycle->inert_ids)
        return BPX_ERR_BAD_STATE;
    if (st->source == SOURCE_CENTRES && cycle->inert_ids)
        st->source = SOURCE_HOST;
    return BPX_OK;
}

// Whether the cycle streams the boxes in blocks: opencl_block_boxes (rounded to whole tiles,
// *forced; 0 when unset) below n, or more boxes than fit on the device at once under the limit.
bool bpx__cl_streamed(const bpx_cl_state *st, const bpx_cycle *cycle, uint32_t *forced)
{
    *forced = cycle->def->opencl_block_boxes;
    if (*forced) {
        *forced = *forced / st->tile * st->tile;
        if (*forced < st->tile)
            *forced = st->tile;
    }
    return (*forced != 0 && *forced < cycle->n) || block_capacity(st, BYTES_PER_BOX) < cycle->n;
}

// The whole-set path: opencl_method, or the auto rule.
int bpx__cl_method(const bpx_cl_state *st, const bpx_cycle *cycle)
{
    if (cycle->def->opencl_method != BPX_OPENCL_AUTO)
        return cycle->def->opencl_method;
    return cycle->n < TREE_MIN_N || st->last_pairs > (uint64_t)DENSE_PAIRS_PER_BOX * cycle->n
               ? BPX_OPENCL_BRUTE
               : BPX_OPENCL_TREE;
}

static bpx_status run_cycle(bpx_cl_state *st, const bpx_cycle *cycle, bpx_block *block)
{
    uint32_t n = cycle->n;
    if (n == 0)
        return BPX_OK;
    TRY(bpx__cl_check_source(st, cycle)); // add/remove/move_boxes on a world fed from a buffer
    uint32_t forced;
    if (!bpx__cl_streamed(st, cycle, &forced)) {
        int method = bpx__cl_method(st, cycle);
        if (method != BPX_OPENCL_BRUTE) {
            bpx_status status = method == BPX_OPENCL_TREE ? bpx__cl_tree_all(st, cycle, block)
                                                          : bpx__cl_sweep_all(st, cycle, block);
            if (status != BPX_ERR_DEVICE_MEMORY)
                return status;
            // Beyond the limit: brute force reads the pairs out in windows.
            block->hits.count = 0;
            if (method == BPX_OPENCL_TREE)
                st->counters.tree_fallbacks++;
            else
                st->counters.sweep_fallbacks++;
            clFinish(st->queue);
            bpx__cl_release_sweep_buffers(st); // brute force may need the room
        }
        if (n <= st->dev->small_n && !st->small_off)
            return bpx__cl_brute_small(st, cycle, block);
        return bpx__cl_brute_all(st, cycle, block);
    }
    // Streaming: free what a whole-set cycle kept, then blocks as large as the limit allows.
    bpx__cl_release_sweep_buffers(st);
    uint32_t block_boxes = block_capacity(st, BYTES_PER_STREAMED_BOX);
    if (block_boxes < st->tile && st->pairs.size) {
        // A pair buffer grown in an earlier cycle leaves no room: start again from a window.
        bpx__cl_dbuf_release(st, &st->pairs);
        block_boxes = block_capacity(st, BYTES_PER_STREAMED_BOX);
    }
    if (forced && forced < block_boxes)
        block_boxes = forced;
    if (block_boxes < st->tile) {
        bpx__log(0,
                 "opencl: a device memory limit of %llu bytes cannot hold one block of %u "
                 "boxes",
                 (unsigned long long)st->limit, st->tile);
        return BPX_ERR_DEVICE_MEMORY;
    }
    return bpx__cl_brute_streamed(st, cycle, block, block_boxes);
}

static bpx_status opencl_compare(void **state, bpx_cycle *cycle)
{
    bpx_cl_state *st = NULL;
    TRY(bpx__cl_state_get(state, cycle->def, &st));
    bpx__cl_resident_settle(st);  // a device-resident cycle still in flight
    st->resident = RESIDENT_NONE; // this cycle may write over its pairs
    bpx_block *block;
    TRY(bpx__emitter_one_block(cycle->sink, cycle->n, &block));
    st->bytes_in = st->bytes_out = st->tests = 0;
    memset(st->ns, 0, sizeof st->ns);
    bpx_status status = run_cycle(st, cycle, block);
    bpx__cl_events_flush(st);
    if (status != BPX_OK) {
        block->hits.count = 0;
        clFinish(st->queue);
    }
    block->tests = st->tests;
    st->last_pairs = block->hits.count;
    st->pairs_known = status == BPX_OK;
    cycle->report.transfer_in_ns = st->ns[EV_IN];
    cycle->report.transfer_out_ns = st->ns[EV_OUT];
    cycle->report.device_ns = st->ns[EV_DEVICE];
    cycle->report.bytes_in = st->bytes_in;
    cycle->report.bytes_out = st->bytes_out;
    return status;
}

static void opencl_boxes_set(void **state, const bpx_world_def *def, const bpx_boxes_change *change)
{
    bpx_cl_state *st = *state;
    if (!change->centres) {
        if (st) {
            st->source = SOURCE_HOST;
            st->minima_on_device = false; // load_extents may have changed them
            if (st->user_buffer)
                clReleaseMemObject(st->user_buffer);
            st->user_buffer = NULL;
        }
        return;
    }
    // The paper's updating phase: keep the centres for the device's updater. Anything that
    // goes wrong here only means the host's boxes are sent instead.
    if (!st && bpx__cl_state_get(state, def, &st) != BPX_OK)
        return;
    bpx__cl_resident_settle(st); // its upload may still read the staging memory
    if (st->user_buffer)
        clReleaseMemObject(st->user_buffer);
    st->user_buffer = NULL;
    st->source = SOURCE_HOST;
    size_t size = (size_t)change->extents.count * 3 * sizeof(float);
    // Devices that flush subnormals would round the updater's add differently from the host.
    if (change->inert_ids || !st->dev->denormals || size == 0 ||
        bpx__cl_pinned_reserve(st, &st->up_centres, size) != BPX_OK)
        return;
    memcpy(st->up_centres.host, change->centres, size);
    st->source = SOURCE_CENTRES;
}

static void opencl_destroy(void *state)
{
    bpx__cl_state_free(state);
}

// ---------------------------------------------------------------------------------------------
// The device calls (include/bpx/opencl.h through core/device.c)

// Whether `mem` is a cl_mem of the device's context holding at least `need` bytes.
static bpx_status check_buffer(bpx_cl_state *st, bpx_cycle *cycle, cl_mem mem, size_t need,
                               uint32_t n, const char *what)
{
    cl_context context = NULL;
    size_t size = 0;
    if (clGetMemObjectInfo(mem, CL_MEM_CONTEXT, sizeof context, &context, NULL) != CL_SUCCESS ||
        context != st->dev->context)
        return bpx__error(cycle->error, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "buffer is not a cl_mem of the world's context");
    if (clGetMemObjectInfo(mem, CL_MEM_SIZE, sizeof size, &size, NULL) != CL_SUCCESS || size < need)
        return bpx__error(cycle->error, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "buffer holds %zu bytes, %u %s need %zu", size, n, what, need);
    return BPX_OK;
}

// The validity check of n boxes in the caller's buffer: the smallest bad index, then that box
// alone crosses the link and goes through the host's own check, which names the axis.
static bpx_status check_boxes(bpx_cl_state *st, bpx_cycle *cycle, cl_mem mem, uint32_t n)
{
    TRY(check_buffer(st, cycle, mem, (size_t)n * sizeof(bpx_box), n, "boxes"));
    if (n == 0)
        return BPX_OK;
    cl_uint none = UINT32_MAX, n_arg = n, bad = UINT32_MAX;
    bpx_status status = bpx__cl_write_buffer(st, st->check.mem, 0, sizeof none, &none, true);
    const bpx_cl_arg args[] = {ARG(mem), ARG(n_arg), ARG(st->check.mem)};
    if (status == BPX_OK)
        status = bpx__cl_launch(st, K_VALIDATE, n, 0, 3, args);
    if (status == BPX_OK)
        status = bpx__cl_read_buffer(st, st->check.mem, 0, sizeof bad, &bad);
    bpx_box box;
    if (status == BPX_OK && bad != UINT32_MAX)
        status = bpx__cl_read_buffer(st, mem, (size_t)bad * sizeof box, sizeof box, &box);
    bpx__cl_events_flush(st);
    if (status != BPX_OK)
        return bpx__error(cycle->error, status, UINT32_MAX, -1,
                          "opencl: checking the device buffer failed");
    if (bad == UINT32_MAX)
        return BPX_OK;
    bpx_error detail;
    bpx_status why = bpx__check_boxes(&box, 1, &detail);
    return bpx__error(cycle->error, why, bad, detail.axis, "device buffer box %u, axis %d: %s", bad,
                      detail.axis, bpx_status_string(why));
}

// The same for n centres with the loaded extents: the minima go over now (once per
// load_extents), then the check names the smallest object whose box is not finite.
static bpx_status check_centres(bpx_cl_state *st, bpx_cycle *cycle, cl_mem mem, uint32_t n)
{
    if (!st->dev->denormals)
        return bpx__error(cycle->error, BPX_ERR_BACKEND_UNAVAILABLE, UINT32_MAX, -1,
                          "the device flushes subnormal floats: its updater would round "
                          "differently from the host's");
    TRY(check_buffer(st, cycle, mem, (size_t)n * 3 * sizeof(float), n, "centres"));
    if (n == 0)
        return BPX_OK;
    cl_uint none = UINT32_MAX, n_arg = n, bad = UINT32_MAX;
    float centre[3];
    bpx_status status = bpx__cl_upload_minima(st, cycle);
    if (status == BPX_OK)
        status = bpx__cl_write_buffer(st, st->check.mem, 0, sizeof none, &none, true);
    const bpx_cl_arg args[] = {ARG(mem), ARG(st->minima.mem), ARG(n_arg), ARG(n_arg),
                               ARG(st->check.mem)};
    if (status == BPX_OK)
        status = bpx__cl_launch(st, K_VALIDATE_CENTRES, n, 0, 5, args);
    if (status == BPX_OK)
        status = bpx__cl_read_buffer(st, st->check.mem, 0, sizeof bad, &bad);
    if (status == BPX_OK && bad != UINT32_MAX)
        status = bpx__cl_read_buffer(st, mem, (size_t)bad * sizeof centre, sizeof centre, centre);
    bpx__cl_events_flush(st);
    if (status != BPX_OK)
        return bpx__error(cycle->error, status, UINT32_MAX, -1,
                          "opencl: checking the device centres failed");
    if (bad == UINT32_MAX)
        return BPX_OK;
    const float *const *m = cycle->extents.minima;
    const float *const minima[3] = {m[0] + bad, m[1] + bad, m[2] + bad};
    bpx_error detail = {0};
    bpx_status why = bpx__check_centres(centre, minima, 1, &detail);
    if (why == BPX_OK) // the device saw another centre than it gave back: changed since
        why = BPX_ERR_NOT_FINITE;
    return bpx__error(cycle->error, why, bad, detail.axis, "device centres, object %u, axis %d: %s",
                      bad, detail.axis, bpx_status_string(why));
}

// The backend's state for a device call, or the error.
static bpx_status device_state(void **state, bpx_cycle *cycle, bpx_cl_state **st)
{
    bpx_status status = bpx__cl_state_get(state, cycle->def, st);
    if (status != BPX_OK)
        return bpx__error(cycle->error, status, UINT32_MAX, -1, "opencl: no device state: %s",
                          bpx_status_string(status));
    return BPX_OK;
}

static bpx_status opencl_check_input(void **state, bpx_cycle *cycle, void *input, uint32_t n,
                                     bool centres)
{
    if (!input) // a cl_mem, even for no boxes
        return bpx__error(cycle->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "buffer is NULL");
    bpx_cl_state *st = NULL;
    TRY(device_state(state, cycle, &st));
    bpx__cl_resident_settle(st); // the checks flush the queue's events
    return centres ? check_centres(st, cycle, input, n) : check_boxes(st, cycle, input, n);
}

static bpx_status opencl_use_input(void **state, bpx_cycle *cycle, void *input, uint32_t n,
                                   bool centres)
{
    (void)cycle, (void)n;
    bpx_cl_state *st = *state; // made by check_input
    clRetainMemObject(input);
    if (st->user_buffer)
        clReleaseMemObject(st->user_buffer);
    st->user_buffer = input;
    st->source = centres ? SOURCE_CENTRES_BUFFER : SOURCE_BUFFER;
    return BPX_OK;
}

static bpx_status opencl_handles(void **state, bpx_cycle *cycle, void **context, void **queue,
                                 void **device)
{
    bpx_cl_state *st = NULL;
    TRY(device_state(state, cycle, &st));
    if (context)
        *context = st->dev->context;
    if (queue)
        *queue = st->queue;
    if (device)
        *device = st->dev->device;
    return BPX_OK;
}

static const bpx_device_ops opencl_device_ops = {
    .check_input = opencl_check_input,
    .use_input = opencl_use_input,
    .collide = bpx__cl_collide_device,
    .pairs = bpx__cl_device_pairs,
    .finish = bpx__cl_finish,
    .handles = opencl_handles,
};

const bpx_backend_impl bpx__opencl_backend = {
    .id = BPX_BACKEND_OPENCL,
    .name = "opencl",
    .query = opencl_query,
    .compare = opencl_compare,
    .destroy = opencl_destroy,
    .boxes_set = opencl_boxes_set,
    .device = &opencl_device_ops,
};

// ---------------------------------------------------------------------------------------------
// Test hooks

bool bpx__opencl_get_counters(const bpx_world *w, bpx__opencl_counters *out)
{
    const bpx_cl_state *st = bpx__world_backend_state(w, &bpx__opencl_backend);
    if (!st)
        return false;
    *out = st->counters;
    return true;
}
