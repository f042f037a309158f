// The opencl backend: the paper's coprocessor on an OpenCL device (a GPU, a CPU through PoCL, an
// FPGA toolchain's device).
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

#include "core/boxes.h"
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
static uint32_t block_capacity(const cl_state *st, uint64_t bytes_per_box)
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
void bpx__cl_release_sweep_buffers(cl_state *st)
{
    dbuf *sweep_set[] = {&st->keys[0],     &st->keys[1],      &st->values[0],   &st->values[1],
                         &st->sorted_lo,   &st->sorted_hi,    &st->counts,      &st->offsets,
                         &st->pi[0],       &st->pi[1],        &st->pj[0],       &st->pj[1],
                         &st->leaf_parent, &st->node_parent,  &st->nodes,       &st->flags,
                         &st->walk_tests,  &st->pair_keys[0], &st->pair_keys[1]};
    for (size_t k = 0; k < sizeof sweep_set / sizeof sweep_set[0]; k++)
        bpx__cl_dbuf_release(st, sweep_set[k]);
}

// BAD_STATE for boxes from a device buffer in a world whose objects were added and removed one
// by one; host centres give way to the host's boxes there (removed objects are inert in those
// only).
bpx_status bpx__cl_check_source(cl_state *st, const bpx_world *w)
{
    if ((st->source == SOURCE_BUFFER || st->source == SOURCE_CENTRES_BUFFER) && w->dead)
        return BPX_ERR_BAD_STATE;
    if (st->source == SOURCE_CENTRES && w->dead)
        st->source = SOURCE_HOST;
    return BPX_OK;
}

// Whether the cycle streams the boxes in blocks: opencl_block_boxes (rounded to whole tiles,
// *forced; 0 when unset) below n, or more boxes than fit on the device at once under the limit.
bool bpx__cl_streamed(const cl_state *st, const bpx_world *w, uint32_t *forced)
{
    *forced = w->def.opencl_block_boxes;
    if (*forced) {
        *forced = *forced / st->tile * st->tile;
        if (*forced < st->tile)
            *forced = st->tile;
    }
    return (*forced != 0 && *forced < w->n) || block_capacity(st, BYTES_PER_BOX) < w->n;
}

// The whole-set path: opencl_method, or the auto rule.
int bpx__cl_method(const cl_state *st, const bpx_world *w)
{
    if (w->def.opencl_method != BPX_OPENCL_AUTO)
        return w->def.opencl_method;
    return w->n < TREE_MIN_N || st->last_pairs > (uint64_t)DENSE_PAIRS_PER_BOX * w->n
               ? BPX_OPENCL_BRUTE
               : BPX_OPENCL_TREE;
}

static bpx_status run_cycle(cl_state *st, bpx_world *w, bpx_block *block)
{
    uint32_t n = w->n;
    if (n == 0)
        return BPX_OK;
    TRY(bpx__cl_check_source(st, w)); // add/remove/move_boxes on a world fed from a buffer
    uint32_t forced;
    if (!bpx__cl_streamed(st, w, &forced)) {
        int method = bpx__cl_method(st, w);
        if (method != BPX_OPENCL_BRUTE) {
            bpx_status status = method == BPX_OPENCL_TREE ? bpx__cl_tree_all(st, w, block)
                                                          : bpx__cl_sweep_all(st, w, block);
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
            return bpx__cl_brute_small(st, w, block);
        return bpx__cl_brute_all(st, w, block);
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
    return bpx__cl_brute_streamed(st, w, block, block_boxes);
}

static bpx_status opencl_compare(bpx_world *w)
{
    cl_state *st = NULL;
    TRY(bpx__cl_state_get(w, &st));
    bpx__cl_resident_settle(w, st); // a device-resident cycle still in flight
    st->resident = RESIDENT_NONE;   // this cycle may write over its pairs
    bpx_block *block;
    TRY(bpx__emitter_one_block(w, &block));
    st->bytes_in = st->bytes_out = st->tests = 0;
    memset(st->ns, 0, sizeof st->ns);
    bpx_status status = run_cycle(st, w, block);
    bpx__cl_events_flush(st);
    if (status != BPX_OK) {
        block->hits.count = 0;
        clFinish(st->queue);
    }
    block->tests = st->tests;
    st->last_pairs = block->hits.count;
    st->pairs_known = status == BPX_OK;
    w->stats.transfer_in_ns = st->ns[EV_IN];
    w->stats.transfer_out_ns = st->ns[EV_OUT];
    w->stats.device_ns = st->ns[EV_DEVICE];
    w->stats.bytes_in = st->bytes_in;
    w->stats.bytes_out = st->bytes_out;
    return status;
}

static void opencl_boxes_set(bpx_world *w, const float *centres)
{
    cl_state *st = w->backend_state;
    if (!centres) {
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
    if (!st && bpx__cl_state_get(w, &st) != BPX_OK)
        return;
    bpx__cl_resident_settle(w, st); // its upload may still read the staging memory
    if (st->user_buffer)
        clReleaseMemObject(st->user_buffer);
    st->user_buffer = NULL;
    st->source = SOURCE_HOST;
    size_t size = (size_t)w->extent_count * 3 * sizeof(float);
    // Devices that flush subnormals would round the updater's add differently from the host.
    if (w->dead || !st->dev->denormals || size == 0 ||
        bpx__cl_pinned_reserve(st, &st->up_centres, size) != BPX_OK)
        return;
    memcpy(st->up_centres.host, centres, size);
    st->source = SOURCE_CENTRES;
}

static void opencl_destroy(bpx_world *w)
{
    bpx__cl_state_free(w->backend_state);
    w->backend_state = NULL;
}

const bpx_backend_impl bpx__opencl_backend = {
    .id = BPX_BACKEND_OPENCL,
    .name = "opencl",
    .query = opencl_query,
    .compare = opencl_compare,
    .destroy = opencl_destroy,
    .boxes_set = opencl_boxes_set,
};

// ---------------------------------------------------------------------------------------------
// Public calls and test hooks

bool bpx__opencl_get_counters(const bpx_world *w, bpx__opencl_counters *out)
{
    if (!w || w->backend != &bpx__opencl_backend || !w->backend_state)
        return false;
    *out = ((const cl_state *)w->backend_state)->counters;
    return true;
}

bpx_status bpx__cl_world_state(bpx_world *w, cl_state **st)
{
    if (w->backend != &bpx__opencl_backend)
        return bpx__error(&w->error, BPX_ERR_BACKEND_UNAVAILABLE, UINT32_MAX, -1,
                          "the world's backend is %s, not opencl", w->backend->name);
    bpx_status status = bpx__cl_state_get(w, st);
    if (status != BPX_OK)
        return bpx__error(&w->error, status, UINT32_MAX, -1, "opencl: no device state: %s",
                          bpx_status_string(status));
    return BPX_OK;
}

bpx_status bpx_opencl_world_handles(bpx_world *w, void **context, void **queue, void **device)
{
    if (!w)
        return BPX_ERR_NULL_ARGUMENT;
    bpx__error_clear(&w->error);
    cl_state *st = NULL;
    TRY(bpx__cl_world_state(w, &st));
    if (context)
        *context = st->dev->context;
    if (queue)
        *queue = st->queue;
    if (device)
        *device = st->dev->device;
    return BPX_OK;
}

bpx_status bpx_opencl_set_boxes_buffer(bpx_world *w, void *buffer, uint32_t n)
{
    if (!w)
        return BPX_ERR_NULL_ARGUMENT;
    bpx__error_clear(&w->error);
    if (n > BPX_MAX_BOXES)
        return bpx__error(&w->error, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "%u boxes exceed BPX_MAX_BOXES (%u)", n, BPX_MAX_BOXES);
    if (!buffer)
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "buffer is NULL");
    cl_state *st = NULL;
    TRY(bpx__cl_world_state(w, &st));
    bpx__cl_resident_settle(w, st); // the checks below flush the queue's events
    if (w->dead)
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "set_boxes_buffer: the world's boxes are managed by add/remove");
    cl_mem mem = buffer;
    cl_context context = NULL;
    size_t size = 0;
    if (clGetMemObjectInfo(mem, CL_MEM_CONTEXT, sizeof context, &context, NULL) != CL_SUCCESS ||
        context != st->dev->context)
        return bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "buffer is not a cl_mem of the world's context");
    if (clGetMemObjectInfo(mem, CL_MEM_SIZE, sizeof size, &size, NULL) != CL_SUCCESS ||
        size / sizeof(bpx_box) < n)
        return bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "buffer holds %zu bytes, %u boxes need %zu", size, n,
                          (size_t)n * sizeof(bpx_box));
    uint64_t start = bpx__now_ns();
    bpx_status status = BPX_OK;
    if (n > 0) {
        // The validity check: the smallest bad index, then that box alone crosses the link.
        cl_uint none = UINT32_MAX, n_arg = n, bad = UINT32_MAX;
        status = bpx__cl_write_buffer(st, st->check.mem, 0, sizeof none, &none, true);
        const kernel_arg args[] = {ARG(mem), ARG(n_arg), ARG(st->check.mem)};
        if (status == BPX_OK)
            status = bpx__cl_launch(st, K_VALIDATE, n, 0, 3, args);
        if (status == BPX_OK)
            status = bpx__cl_read_buffer(st, st->check.mem, 0, sizeof bad, &bad);
        bpx_box box;
        if (status == BPX_OK && bad != UINT32_MAX)
            status = bpx__cl_read_buffer(st, mem, (size_t)bad * sizeof box, sizeof box, &box);
        bpx__cl_events_flush(st);
        if (status != BPX_OK)
            return bpx__error(&w->error, status, UINT32_MAX, -1,
                              "opencl: checking the device buffer failed");
        if (bad != UINT32_MAX) {
            bpx_error detail;
            bpx_status why = bpx__check_boxes(&box, 1, &detail);
            return bpx__error(&w->error, why, bad, detail.axis, "device buffer box %u, axis %d: %s",
                              bad, detail.axis, bpx_status_string(why));
        }
    }
    // The host's arrays hold n inert boxes, so that nothing sized by n reads past them.
    uint32_t old_n = w->n;
    w->n = 0;
    if (!bpx__boxes_resize(w, n)) {
        w->n = old_n;
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %u boxes", n);
    }
    clRetainMemObject(mem);
    if (st->user_buffer)
        clReleaseMemObject(st->user_buffer);
    st->user_buffer = mem;
    st->source = SOURCE_BUFFER;
    w->boxes_on_device = true;
    w->stats.update_ns = bpx__now_ns() - start;
    return BPX_OK;
}

bpx_status bpx_opencl_set_centres_buffer(bpx_world *w, void *buffer, uint32_t n)
{
    if (!w)
        return BPX_ERR_NULL_ARGUMENT;
    bpx__error_clear(&w->error);
    if (!buffer)
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "buffer is NULL");
    cl_state *st = NULL;
    TRY(bpx__cl_world_state(w, &st));
    bpx__cl_resident_settle(w, st); // the checks below flush the queue's events
    if (!w->extents_loaded || w->dead)
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          w->dead ? "set_centres_buffer: objects were removed by id"
                                  : "set_centres_buffer before load_extents");
    if (n != w->extent_count)
        return bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "%u centres for %u loaded extents", n, w->extent_count);
    if (!st->dev->denormals)
        return bpx__error(&w->error, BPX_ERR_BACKEND_UNAVAILABLE, UINT32_MAX, -1,
                          "the device flushes subnormal floats: its updater would round "
                          "differently from the host's");
    cl_mem mem = buffer;
    cl_context context = NULL;
    size_t size = 0;
    if (clGetMemObjectInfo(mem, CL_MEM_CONTEXT, sizeof context, &context, NULL) != CL_SUCCESS ||
        context != st->dev->context)
        return bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "buffer is not a cl_mem of the world's context");
    size_t need = (size_t)n * 3 * sizeof(float);
    if (clGetMemObjectInfo(mem, CL_MEM_SIZE, sizeof size, &size, NULL) != CL_SUCCESS || size < need)
        return bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "buffer holds %zu bytes, %u centres need %zu", size, n, need);
    uint64_t start = bpx__now_ns();
    if (n > 0) {
        // The minima go over now (once per load_extents), then the check: the smallest bad
        // object, and that centre alone crosses the link.
        cl_uint none = UINT32_MAX, n_arg = n, bad = UINT32_MAX;
        float centre[3];
        bpx_status status = bpx__cl_upload_minima(st, w);
        if (status == BPX_OK)
            status = bpx__cl_write_buffer(st, st->check.mem, 0, sizeof none, &none, true);
        const kernel_arg args[] = {ARG(mem), ARG(st->minima.mem), ARG(n_arg), ARG(n_arg),
                                   ARG(st->check.mem)};
        if (status == BPX_OK)
            status = bpx__cl_launch(st, K_VALIDATE_CENTRES, n, 0, 5, args);
        if (status == BPX_OK)
            status = bpx__cl_read_buffer(st, st->check.mem, 0, sizeof bad, &bad);
        if (status == BPX_OK && bad != UINT32_MAX)
            status =
                bpx__cl_read_buffer(st, mem, (size_t)bad * sizeof centre, sizeof centre, centre);
        bpx__cl_events_flush(st);
        if (status != BPX_OK)
            return bpx__error(&w->error, status, UINT32_MAX, -1,
                              "opencl: checking the device centres failed");
        if (bad != UINT32_MAX) {
            // The host's own check names the axis, on that one object.
            const float *const minima[3] = {w->minima[0] + bad, w->minima[1] + bad,
                                            w->minima[2] + bad};
            bpx_error detail = {0};
            bpx_status why = bpx__check_centres(centre, minima, 1, &detail);
            if (why == BPX_OK) // the device saw another centre than it gave back: changed since
                why = BPX_ERR_NOT_FINITE;
            return bpx__error(&w->error, why, bad, detail.axis,
                              "device centres, object %u, axis %d: %s", bad, detail.axis,
                              bpx_status_string(why));
        }
    }
    clRetainMemObject(mem);
    if (st->user_buffer)
        clReleaseMemObject(st->user_buffer);
    st->user_buffer = mem;
    st->source = SOURCE_CENTRES_BUFFER;
    w->boxes_on_device = true; // the host's boxes are the last host centres': no queries
    w->stats.update_ns = bpx__now_ns() - start;
    return BPX_OK;
}
