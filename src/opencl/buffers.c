// The opencl backend's plumbing: errors, events (each command's device time), device buffers
// and pinned host memory, kernel launches and transfers, and the state made per world.

#include <string.h>

#include "core/log.h"
#include "state.h"

static const char *const kernel_names[K_COUNT] = {
    "bpx_update",        "bpx_convert",          "bpx_validate",         "bpx_brute_count",
    "bpx_brute_emit",    "bpx_scan_reduce",      "bpx_scan_sums",        "bpx_scan_apply",
    "bpx_radix_count",   "bpx_radix_scatter",    "bpx_sweep_keys",       "bpx_sweep_gather",
    "bpx_sweep_count",   "bpx_sweep_write",      "bpx_sweep_interleave", "bpx_brute_small",
    "bpx_radix_count64", "bpx_radix_scatter64",  "bpx_tree_reset",       "bpx_tree_bounds",
    "bpx_tree_codes",    "bpx_tree_build",       "bpx_tree_refit",       "bpx_tree_walk",
    "bpx_tree_unpack",   "bpx_validate_centres", "bpx_tree_count",
};

// ---------------------------------------------------------------------------------------------
// Errors, events, buffers

// Logs the failing call and maps the OpenCL error to a status.
bpx_status bpx__cl_cl_fail(bpx_cl_state *st, cl_int err, const char *what)
{
    bpx__log(0, "opencl: %s failed: %s", what, bpx__cl_error_name(err));
    if (st && st->queue)
        clFinish(st->queue); // nothing may still write into host memory
    return err == CL_OUT_OF_HOST_MEMORY   ? BPX_ERR_OUT_OF_MEMORY
           : bpx__cl_is_memory_error(err) ? BPX_ERR_DEVICE_MEMORY
                                          : BPX_ERR_DEVICE;
}

// Adds each finished event's device time to its class and releases it.
void bpx__cl_events_flush(bpx_cl_state *st)
{
    if (st->event_count == 0)
        return;
    clWaitForEvents((cl_uint)st->event_count, st->events);
    for (int k = 0; k < st->event_count; k++) {
        cl_ulong start = 0, end = 0;
        if (clGetEventProfilingInfo(st->events[k], CL_PROFILING_COMMAND_START, sizeof start, &start,
                                    NULL) == CL_SUCCESS &&
            clGetEventProfilingInfo(st->events[k], CL_PROFILING_COMMAND_END, sizeof end, &end,
                                    NULL) == CL_SUCCESS &&
            end > start)
            st->ns[st->event_class[k]] += end - start;
        clReleaseEvent(st->events[k]);
    }
    st->event_count = 0;
}

// A slot for the next command's event (flushing the list when full).
static cl_event *event_slot(bpx_cl_state *st, int class)
{
    if (st->event_count == EVENTS_MAX)
        bpx__cl_events_flush(st);
    st->event_class[st->event_count] = (unsigned char)class;
    return &st->events[st->event_count];
}

// Counts the event written into the last slot (call after the command succeeded).
static void event_commit(bpx_cl_state *st)
{
    st->event_count++;
}

void bpx__cl_dbuf_release(bpx_cl_state *st, bpx_cl_buffer *b)
{
    if (b->mem) {
        clReleaseMemObject(b->mem);
        st->used -= b->size;
    }
    *b = (bpx_cl_buffer){0};
}

// Makes b hold at least size bytes (contents not kept), rounded up to 4 KiB. Exact, not
// geometric: buffers follow n, which changes rarely, and spare room would only take memory a
// streamed cycle needs.
bpx_status bpx__cl_dbuf_reserve(bpx_cl_state *st, bpx_cl_buffer *b, size_t size)
{
    size = round_up(size ? size : 1, 4096);
    if (b->size >= size)
        return BPX_OK;
    uint64_t others = st->used - b->size;
    size_t grown = size;
    if (grown > st->dev->max_alloc || others + grown > st->limit) {
        bpx__log(1, "opencl: %zu more device bytes would pass the limit of %llu", size,
                 (unsigned long long)st->limit);
        return BPX_ERR_DEVICE_MEMORY;
    }
    // The new buffer is made before the old one goes, so a failure leaves b as it was.
    cl_int err;
    cl_mem mem = clCreateBuffer(st->dev->context, CL_MEM_READ_WRITE, grown, NULL, &err);
    if (!mem)
        return bpx__cl_cl_fail(st, err, "clCreateBuffer");
    bpx__cl_dbuf_release(st, b);
    *b = (bpx_cl_buffer){mem, grown};
    st->used += grown;
    return BPX_OK;
}

static void pinned_release(bpx_cl_state *st, bpx_cl_pinned *p)
{
    if (p->mem) {
        if (p->host)
            clEnqueueUnmapMemObject(st->queue, p->mem, p->host, 0, NULL, NULL);
        clFinish(st->queue);
        clReleaseMemObject(p->mem);
    }
    *p = (bpx_cl_pinned){0};
}

// Host memory the device reads and writes directly where the platform offers it
// (CL_MEM_ALLOC_HOST_PTR, mapped for the world's life). Contents not kept.
bpx_status bpx__cl_pinned_reserve(bpx_cl_state *st, bpx_cl_pinned *p, size_t size)
{
    if (size == 0)
        size = 64;
    if (p->size >= size)
        return BPX_OK;
    size_t grown = size + size / 2;
    pinned_release(st, p);
    cl_int err;
    cl_mem mem = clCreateBuffer(st->dev->context, CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR, grown,
                                NULL, &err);
    if (!mem)
        return bpx__cl_cl_fail(st, err, "clCreateBuffer (pinned)");
    void *host = clEnqueueMapBuffer(st->queue, mem, CL_TRUE, CL_MAP_READ | CL_MAP_WRITE, 0, grown,
                                    0, NULL, NULL, &err);
    if (!host) {
        clReleaseMemObject(mem);
        return bpx__cl_cl_fail(st, err, "clEnqueueMapBuffer");
    }
    *p = (bpx_cl_pinned){mem, host, grown};
    return BPX_OK;
}

// Sets the arguments and enqueues kernel k over `global` work-items in work-groups of `local`
// (0: the tile width, with global rounded up; such kernels check their index). The size is
// always given: an implementation that compiles per work-group size (PoCL) then compiles each
// kernel once, not once per n. Nothing to do for global 0.
bpx_status bpx__cl_launch(bpx_cl_state *st, int k, size_t global, size_t local, int arg_count,
                          const bpx_cl_arg *args)
{
    if (global == 0)
        return BPX_OK;
    if (local == 0) {
        local = st->tile;
        global = round_up(global, local);
    }
    for (int a = 0; a < arg_count; a++)
        CL_CHECK(st, clSetKernelArg(st->kernels[k], (cl_uint)a, args[a].size, args[a].value),
                 kernel_names[k]);
    CL_CHECK(st,
             clEnqueueNDRangeKernel(st->queue, st->kernels[k], 1, NULL, &global,
                                    local ? &local : NULL, 0, NULL, event_slot(st, EV_DEVICE)),
             kernel_names[k]);
    event_commit(st);
    return BPX_OK;
}

bpx_status bpx__cl_write_buffer(bpx_cl_state *st, cl_mem mem, size_t offset, size_t size,
                                const void *host, bool blocking)
{
    if (size == 0)
        return BPX_OK;
    CL_CHECK(st,
             clEnqueueWriteBuffer(st->queue, mem, blocking ? CL_TRUE : CL_FALSE, offset, size, host,
                                  0, NULL, event_slot(st, EV_IN)),
             "clEnqueueWriteBuffer");
    event_commit(st);
    st->bytes_in += size;
    return BPX_OK;
}

// Sets `size` bytes of mem to `byte` on the device (nothing crosses the link).
bpx_status bpx__cl_fill(bpx_cl_state *st, cl_mem mem, unsigned char byte, size_t size)
{
    if (size == 0)
        return BPX_OK;
    CL_CHECK(
        st,
        clEnqueueFillBuffer(st->queue, mem, &byte, 1, 0, size, 0, NULL, event_slot(st, EV_DEVICE)),
        "clEnqueueFillBuffer");
    event_commit(st);
    return BPX_OK;
}

// Copies `size` bytes from src at src_offset to the start of dst, on the device.
bpx_status bpx__cl_copy(bpx_cl_state *st, cl_mem src, size_t src_offset, cl_mem dst, size_t size)
{
    CL_CHECK(st,
             clEnqueueCopyBuffer(st->queue, src, dst, src_offset, 0, size, 0, NULL,
                                 event_slot(st, EV_DEVICE)),
             "clEnqueueCopyBuffer");
    event_commit(st);
    return BPX_OK;
}

// Reads device memory into host memory, waiting for it, or (bpx__cl_read_later) only enqueued: the
// host memory is filled once the queue has run that far (clFinish).
static bpx_status read_some(bpx_cl_state *st, cl_mem mem, size_t offset, size_t size, void *host,
                            cl_bool blocking)
{
    if (size == 0)
        return BPX_OK;
    CL_CHECK(st,
             clEnqueueReadBuffer(st->queue, mem, blocking, offset, size, host, 0, NULL,
                                 event_slot(st, EV_OUT)),
             "clEnqueueReadBuffer");
    event_commit(st);
    st->bytes_out += size;
    return BPX_OK;
}

bpx_status bpx__cl_read_buffer(bpx_cl_state *st, cl_mem mem, size_t offset, size_t size, void *host)
{
    return read_some(st, mem, offset, size, host, CL_TRUE);
}

bpx_status bpx__cl_read_later(bpx_cl_state *st, cl_mem mem, size_t offset, size_t size, void *host)
{
    return read_some(st, mem, offset, size, host, CL_FALSE);
}

bpx_status bpx__cl_read_register(bpx_cl_state *st, cl_uint slot, uint64_t *value)
{
    TRY(bpx__cl_read_buffer(st, st->registers.mem, slot * sizeof(cl_ulong), sizeof(cl_ulong),
                            (char *)st->reg.host + slot * sizeof(cl_ulong)));
    cl_ulong v;
    memcpy(&v, (char *)st->reg.host + slot * sizeof(cl_ulong), sizeof v);
    *value = v;
    return BPX_OK;
}

// Reads count pairs from the device buffer into out (appended), through pinned memory.
bpx_status bpx__cl_read_pairs(bpx_cl_state *st, cl_mem pairs, size_t count, bpx_pair_list *out)
{
    if (count == 0)
        return BPX_OK;
    if (!bpx__list_reserve(out, count))
        return BPX_ERR_OUT_OF_MEMORY;
    TRY(bpx__cl_pinned_reserve(st, &st->down, count * sizeof(bpx_pair)));
    TRY(bpx__cl_read_buffer(st, pairs, 0, count * sizeof(bpx_pair), st->down.host));
    memcpy(out->pairs + out->count, st->down.host, count * sizeof(bpx_pair));
    out->count += count;
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// State

void bpx__cl_state_free(bpx_cl_state *st)
{
    if (!st)
        return;
    if (st->queue) {
        clFinish(st->queue);
        bpx__cl_events_flush(st);
    }
    bpx_cl_pinned *pins[] = {&st->up, &st->up_centres, &st->down, &st->reg, &st->resident_host};
    for (size_t k = 0; k < sizeof pins / sizeof pins[0]; k++)
        pinned_release(st, pins[k]);
    bpx_cl_buffer *bufs[] = {
        &st->registers,   &st->check,      &st->input,      &st->minima,       &st->lo,
        &st->hi,          &st->lo_b,       &st->hi_b,       &st->row_count,    &st->stash,
        &st->group_sum,   &st->group_long, &st->pairs,      &st->keys[0],      &st->keys[1],
        &st->values[0],   &st->values[1],  &st->sorted_lo,  &st->sorted_hi,    &st->counts,
        &st->offsets,     &st->sums,       &st->hist,       &st->hist_offsets, &st->pi[0],
        &st->pi[1],       &st->pj[0],      &st->pj[1],      &st->leaf_parent,  &st->node_parent,
        &st->nodes,       &st->flags,      &st->tree_small, &st->walk_tests,   &st->pair_keys[0],
        &st->pair_keys[1]};
    for (size_t k = 0; k < sizeof bufs / sizeof bufs[0]; k++)
        bpx__cl_dbuf_release(st, bufs[k]);
    bpx__cl_dbuf_release(st, &st->resident_count);
    if (st->user_buffer)
        clReleaseMemObject(st->user_buffer);
    for (int k = 0; k < K_COUNT; k++)
        if (st->kernels[k])
            clReleaseKernel(st->kernels[k]);
    if (st->queue)
        clReleaseCommandQueue(st->queue);
    bpx__free(st->row_hist, st->row_hist_count * sizeof(uint32_t));
    bpx__free(st, sizeof *st);
}

static bpx_status state_create(const bpx_world_def *def, bpx_cl_state **out)
{
    const bpx_cl_device *dev;
    const char *reason;
    if (!bpx__cl_device_get(def, &dev, &reason, NULL, 0)) {
        bpx__log(0, "opencl: %s", reason);
        return BPX_ERR_DEVICE;
    }
    bpx_cl_state *st = bpx__alloc(sizeof *st);
    if (!st)
        return BPX_ERR_OUT_OF_MEMORY;
    *st = (bpx_cl_state){.dev = dev, .tile = dev->tile, .source = SOURCE_HOST};
    st->first_pair_capacity =
        def->opencl_pair_capacity ? def->opencl_pair_capacity : DEFAULT_PAIR_CAPACITY;
    uint64_t half = dev->global_memory / 2;
    st->limit = def->opencl_memory_limit && def->opencl_memory_limit < dev->global_memory
                    ? def->opencl_memory_limit
                    : half;
    cl_int err;
    st->queue = clCreateCommandQueue(dev->context, dev->device, CL_QUEUE_PROFILING_ENABLE, &err);
    bpx_status status = BPX_OK;
    if (!st->queue)
        status = bpx__cl_cl_fail(st, err, "clCreateCommandQueue");
    for (int k = 0; k < K_COUNT && status == BPX_OK; k++)
        if (!(st->kernels[k] = clCreateKernel(dev->program, kernel_names[k], &err)))
            status = bpx__cl_cl_fail(st, err, kernel_names[k]);
    if (status == BPX_OK)
        status = bpx__cl_pinned_reserve(st, &st->reg, REGISTER_SLOTS * sizeof(cl_ulong));
    if (status == BPX_OK) {
        // The registers are tiny and always needed: they do not count against the limit.
        uint64_t limit = st->limit;
        st->limit = UINT64_MAX;
        status = bpx__cl_dbuf_reserve(st, &st->registers, REGISTER_SLOTS * sizeof(cl_ulong));
        if (status == BPX_OK)
            status = bpx__cl_dbuf_reserve(st, &st->check, sizeof(cl_uint));
        st->limit = limit;
    }
    if (status != BPX_OK) {
        bpx__cl_state_free(st);
        return status;
    }
    *out = st;
    return BPX_OK;
}

bpx_status bpx__cl_state_get(void **state, const bpx_world_def *def, bpx_cl_state **out)
{
    if (!*state) {
        bpx_cl_state *st;
        TRY(state_create(def, &st));
        *state = st;
    }
    *out = *state;
    return BPX_OK;
}
