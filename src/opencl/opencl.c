// The opencl backend: the paper's coprocessor on an OpenCL device (a GPU, a CPU through PoCL, an
// FPGA toolchain's device).
//
// Per cycle: the updater (centres + stored minima -> boxes, or boxes as given) runs on the device
// and writes keys (twin.h); the comparator (brute.cl: tiles in local memory, or sweep.cl: a radix
// sort on min x and a sweep, for large n) counts each row's hits; a scan turns the counts into
// places and the collision count (the paper's register), which the host reads; the emitter
// kernel writes the pairs in (i, j) order and the host reads them into the world's block.
// Buffers live as long as the world and only grow. Boxes beyond the memory limit are streamed in
// blocks; pairs beyond it are read out in windows. Every command gets an event, and the events'
// device times give the cycle's transfer and compute times (bpx_cycle_stats).
#include <string.h>

#include "core/alloc.h"
#include "core/clock.h"
#include "core/log.h"
#include "core/validate.h"
#include "core/world.h"
#include "device.h"
#include "opencl_internal.h"

enum kernel_id {
    K_UPDATE,
    K_CONVERT,
    K_VALIDATE,
    K_BRUTE_COUNT,
    K_BRUTE_EMIT,
    K_SCAN_REDUCE,
    K_SCAN_SUMS,
    K_SCAN_APPLY,
    K_RADIX_COUNT,
    K_RADIX_SCATTER,
    K_SWEEP_KEYS,
    K_SWEEP_GATHER,
    K_SWEEP_COUNT,
    K_SWEEP_WRITE,
    K_SWEEP_INTERLEAVE,
    K_BRUTE_SMALL,
    K_COUNT
};

static const char *const kernel_names[K_COUNT] = {
    "bpx_update",      "bpx_convert",       "bpx_validate",         "bpx_brute_count",
    "bpx_brute_emit",  "bpx_scan_reduce",   "bpx_scan_sums",        "bpx_scan_apply",
    "bpx_radix_count", "bpx_radix_scatter", "bpx_sweep_keys",       "bpx_sweep_gather",
    "bpx_sweep_count", "bpx_sweep_write",   "bpx_sweep_interleave", "bpx_brute_small",
};

enum {
    EVENTS_MAX = 128,
    DEFAULT_PAIR_CAPACITY = 65536,
    // Auto method: sort and sweep from this many boxes on, unless the last cycle found more than
    // DENSE_PAIRS_PER_BOX pairs per box (then ordering the pairs costs the sweep more than brute
    // force's second pass). Measured on PoCL: docs/opencl.md.
    SWEEP_MIN_N = 4096,
    DENSE_PAIRS_PER_BOX = 16,
    // Device bytes per box: keys (2 x 16), per-row count and stash (4 + 16), input (24).
    BYTES_PER_BOX = 2 * 16 + 4 + 4 * BPX_CL_STASH + 24,
    // Streaming keeps two blocks of keys and of input.
    BYTES_PER_STREAMED_BOX = BYTES_PER_BOX + 2 * 16 + 24,
    REGISTER_SLOTS = 4, // 0: brute count, 1: sweep count, 2: scratch scans
};

enum { EV_IN, EV_OUT, EV_DEVICE, EV_CLASSES };

typedef enum box_source {
    SOURCE_HOST,    // the world's boxes, uploaded as six planes (24 bytes per box)
    SOURCE_CENTRES, // this cycle's centres (12 bytes per object) + minima kept on the device
    SOURCE_BUFFER,  // the caller's device buffer of bpx_box (nothing uploaded)
} box_source;

typedef struct dbuf {
    cl_mem mem;
    size_t size;
} dbuf;

typedef struct pinned {
    cl_mem mem;
    void *host;
    size_t size;
} pinned;

typedef struct cl_state {
    const bpx_cl_device *dev;
    cl_command_queue queue;
    cl_kernel kernels[K_COUNT];
    unsigned tile;
    size_t first_pair_capacity;
    uint64_t limit; // device bytes this world may use
    uint64_t used;  // device bytes held now

    box_source source;
    bool minima_on_device; // the current extents are in `minima`
    cl_mem user_buffer;    // SOURCE_BUFFER (retained)

    pinned up;         // uploads: six planes, two regions (row block, column block)
    pinned up_centres; // the centres of the last update_centres
    pinned down;       // pair read-back
    pinned reg;        // count registers read-back
    dbuf registers;    // REGISTER_SLOTS ulongs
    dbuf check;        // bpx_validate's answer
    dbuf input, minima;
    dbuf lo, hi, lo_b, hi_b;
    dbuf row_count, stash, group_sum, group_long;
    dbuf pairs;
    // Sort and sweep.
    dbuf keys[2], values[2], sorted_lo, sorted_hi, counts, offsets, sums, hist, hist_offsets;
    dbuf pi[2], pj[2];

    cl_event events[EVENTS_MAX];
    unsigned char event_class[EVENTS_MAX];
    int event_count;
    uint64_t ns[EV_CLASSES];
    uint64_t bytes_in, bytes_out, tests;
    uint64_t last_pairs; // the previous cycle's, for the auto method
    bool small_off;      // the small-set kernel's pairs did not fit under the memory limit

    uint32_t *row_hist; // streaming: per-row counts of one row block (host)
    size_t row_hist_count;

    bpx__opencl_counters counters;
} cl_state;

// ---------------------------------------------------------------------------------------------
// Errors, events, buffers

// Logs the failing call and maps the OpenCL error to a status.
static bpx_status cl_fail(cl_state *st, cl_int err, const char *what)
{
    bpx__log(0, "opencl: %s failed: %s", what, bpx__cl_error_name(err));
    if (st && st->queue)
        clFinish(st->queue); // nothing may still write into host memory
    return err == CL_OUT_OF_HOST_MEMORY   ? BPX_ERR_OUT_OF_MEMORY
           : bpx__cl_is_memory_error(err) ? BPX_ERR_DEVICE_MEMORY
                                          : BPX_ERR_DEVICE;
}

#define CL_CHECK(st, call, what)                                                                   \
    do {                                                                                           \
        cl_int check_err_ = (call);                                                                \
        if (check_err_ != CL_SUCCESS)                                                              \
            return cl_fail((st), check_err_, (what));                                              \
    } while (0)

#define TRY(expr)                                                                                  \
    do {                                                                                           \
        bpx_status try_status_ = (expr);                                                           \
        if (try_status_ != BPX_OK)                                                                 \
            return try_status_;                                                                    \
    } while (0)

// Adds each finished event's device time to its class and releases it.
static void events_flush(cl_state *st)
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
static cl_event *event_slot(cl_state *st, int class)
{
    if (st->event_count == EVENTS_MAX)
        events_flush(st);
    st->event_class[st->event_count] = (unsigned char)class;
    return &st->events[st->event_count];
}

// Counts the event written into the last slot (call after the command succeeded).
static void event_commit(cl_state *st)
{
    st->event_count++;
}

static size_t round_up(size_t value, size_t multiple)
{
    return (value + multiple - 1) / multiple * multiple;
}

static void dbuf_release(cl_state *st, dbuf *b)
{
    if (b->mem) {
        clReleaseMemObject(b->mem);
        st->used -= b->size;
    }
    *b = (dbuf){0};
}

// Makes b hold at least size bytes (contents not kept), rounded up to 4 KiB. Exact, not
// geometric: buffers follow n, which changes rarely, and spare room would only take memory a
// streamed cycle needs.
static bpx_status dbuf_reserve(cl_state *st, dbuf *b, size_t size)
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
        return cl_fail(st, err, "clCreateBuffer");
    dbuf_release(st, b);
    *b = (dbuf){mem, grown};
    st->used += grown;
    return BPX_OK;
}

static void pinned_release(cl_state *st, pinned *p)
{
    if (p->mem) {
        if (p->host)
            clEnqueueUnmapMemObject(st->queue, p->mem, p->host, 0, NULL, NULL);
        clFinish(st->queue);
        clReleaseMemObject(p->mem);
    }
    *p = (pinned){0};
}

// Host memory the device reads and writes directly where the platform offers it
// (CL_MEM_ALLOC_HOST_PTR, mapped for the world's life). Contents not kept.
static bpx_status pinned_reserve(cl_state *st, pinned *p, size_t size)
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
        return cl_fail(st, err, "clCreateBuffer (pinned)");
    void *host = clEnqueueMapBuffer(st->queue, mem, CL_TRUE, CL_MAP_READ | CL_MAP_WRITE, 0, grown,
                                    0, NULL, NULL, &err);
    if (!host) {
        clReleaseMemObject(mem);
        return cl_fail(st, err, "clEnqueueMapBuffer");
    }
    *p = (pinned){mem, host, grown};
    return BPX_OK;
}

typedef struct kernel_arg {
    size_t size;
    const void *value;
} kernel_arg;

#define ARG(x) ((kernel_arg){sizeof(x), &(x)})

// Sets the arguments and enqueues kernel k over `global` work-items in work-groups of `local`
// (0: the tile width, with global rounded up; such kernels check their index). The size is
// always given: an implementation that compiles per work-group size (PoCL) then compiles each
// kernel once, not once per n. Nothing to do for global 0.
static bpx_status launch(cl_state *st, int k, size_t global, size_t local, int arg_count,
                         const kernel_arg *args)
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

static bpx_status write_buffer(cl_state *st, cl_mem mem, size_t offset, size_t size,
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

// Reads device memory into host memory, waiting for it, or (read_later) only enqueued: the
// host memory is filled once the queue has run that far (clFinish).
static bpx_status read_some(cl_state *st, cl_mem mem, size_t offset, size_t size, void *host,
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

static bpx_status read_buffer(cl_state *st, cl_mem mem, size_t offset, size_t size, void *host)
{
    return read_some(st, mem, offset, size, host, CL_TRUE);
}

static bpx_status read_later(cl_state *st, cl_mem mem, size_t offset, size_t size, void *host)
{
    return read_some(st, mem, offset, size, host, CL_FALSE);
}

// ---------------------------------------------------------------------------------------------
// State

static void state_free(cl_state *st)
{
    if (!st)
        return;
    if (st->queue) {
        clFinish(st->queue);
        events_flush(st);
    }
    pinned *pins[] = {&st->up, &st->up_centres, &st->down, &st->reg};
    for (size_t k = 0; k < sizeof pins / sizeof pins[0]; k++)
        pinned_release(st, pins[k]);
    dbuf *bufs[] = {&st->registers, &st->check,     &st->input,     &st->minima,
                    &st->lo,        &st->hi,        &st->lo_b,      &st->hi_b,
                    &st->row_count, &st->stash,     &st->group_sum, &st->group_long,
                    &st->pairs,     &st->keys[0],   &st->keys[1],   &st->values[0],
                    &st->values[1], &st->sorted_lo, &st->sorted_hi, &st->counts,
                    &st->offsets,   &st->sums,      &st->hist,      &st->hist_offsets,
                    &st->pi[0],     &st->pi[1],     &st->pj[0],     &st->pj[1]};
    for (size_t k = 0; k < sizeof bufs / sizeof bufs[0]; k++)
        dbuf_release(st, bufs[k]);
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

static bpx_status state_create(bpx_world *w, cl_state **out)
{
    const bpx_cl_device *dev;
    const char *reason;
    if (!bpx__cl_device_get(&w->def, &dev, &reason, NULL, 0)) {
        bpx__log(0, "opencl: %s", reason);
        return BPX_ERR_DEVICE;
    }
    cl_state *st = bpx__alloc(sizeof *st);
    if (!st)
        return BPX_ERR_OUT_OF_MEMORY;
    *st = (cl_state){.dev = dev, .tile = dev->tile, .source = SOURCE_HOST};
    st->first_pair_capacity =
        w->def.opencl_pair_capacity ? w->def.opencl_pair_capacity : DEFAULT_PAIR_CAPACITY;
    uint64_t half = dev->global_memory / 2;
    st->limit = w->def.opencl_memory_limit && w->def.opencl_memory_limit < dev->global_memory
                    ? w->def.opencl_memory_limit
                    : half;
    cl_int err;
    st->queue = clCreateCommandQueue(dev->context, dev->device, CL_QUEUE_PROFILING_ENABLE, &err);
    bpx_status status = BPX_OK;
    if (!st->queue)
        status = cl_fail(st, err, "clCreateCommandQueue");
    for (int k = 0; k < K_COUNT && status == BPX_OK; k++)
        if (!(st->kernels[k] = clCreateKernel(dev->program, kernel_names[k], &err)))
            status = cl_fail(st, err, kernel_names[k]);
    if (status == BPX_OK)
        status = pinned_reserve(st, &st->reg, REGISTER_SLOTS * sizeof(cl_ulong));
    if (status == BPX_OK) {
        // The registers are tiny and always needed: they do not count against the limit.
        uint64_t limit = st->limit;
        st->limit = UINT64_MAX;
        status = dbuf_reserve(st, &st->registers, REGISTER_SLOTS * sizeof(cl_ulong));
        if (status == BPX_OK)
            status = dbuf_reserve(st, &st->check, sizeof(cl_uint));
        st->limit = limit;
    }
    if (status != BPX_OK) {
        state_free(st);
        return status;
    }
    *out = st;
    return BPX_OK;
}

static bpx_status state_get(bpx_world *w, cl_state **out)
{
    if (!w->backend_state) {
        cl_state *st;
        TRY(state_create(w, &st));
        w->backend_state = st;
    }
    *out = w->backend_state;
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// Updater: boxes [first, first + count) of the world onto the device as keys, padded.

static bpx_status upload_keys(cl_state *st, const bpx_world *w, uint32_t first, uint32_t count,
                              uint32_t padded, size_t region_offset, dbuf *lo, dbuf *hi)
{
    TRY(dbuf_reserve(st, lo, (size_t)padded * 16));
    TRY(dbuf_reserve(st, hi, (size_t)padded * 16));
    cl_uint first_arg = first, count_arg = count, padded_arg = padded;
    size_t global = round_up(padded, st->tile);
    bool whole = first == 0 && count == w->n;
    if (st->source == SOURCE_BUFFER) {
        // Already on the device: the caller's bpx_box array, read in place.
        cl_uint box_stride = 6, plane = 1;
        const kernel_arg args[] = {ARG(st->user_buffer), ARG(box_stride), ARG(plane),
                                   ARG(first_arg),       ARG(count_arg),  ARG(padded_arg),
                                   ARG(lo->mem),         ARG(hi->mem)};
        return launch(st, K_CONVERT, global, 0, 8, args);
    }
    if (st->source == SOURCE_CENTRES && whole) {
        size_t plane = (size_t)count * sizeof(float);
        if (!st->minima_on_device) {
            // Initialisation phase: the minima cross once, as three planes.
            TRY(dbuf_reserve(st, &st->minima, 3 * plane));
            TRY(pinned_reserve(st, &st->up, 3 * plane));
            for (int a = 0; a < 3; a++)
                memcpy((char *)st->up.host + a * plane, w->minima[a], plane);
            TRY(write_buffer(st, st->minima.mem, 0, 3 * plane, st->up.host, true));
            st->minima_on_device = true;
        }
        TRY(dbuf_reserve(st, &st->input, 3 * plane));
        TRY(write_buffer(st, st->input.mem, 0, 3 * plane, st->up_centres.host, false));
        cl_uint stride = count;
        const kernel_arg args[] = {ARG(st->input.mem), ARG(st->minima.mem), ARG(stride),
                                   ARG(first_arg),     ARG(count_arg),      ARG(padded_arg),
                                   ARG(lo->mem),       ARG(hi->mem)};
        return launch(st, K_UPDATE, global, 0, 8, args);
    }
    // The world's boxes as six planes (x min, y min, z min, x max, y max, z max), at
    // region_offset in the pinned staging and in the device's input: while streaming, a row
    // block and a column block are in flight together, in two regions.
    size_t plane = (size_t)count * sizeof(float);
    TRY(pinned_reserve(st, &st->up, region_offset + 6 * plane));
    TRY(dbuf_reserve(st, &st->input, region_offset + 6 * plane));
    char *stage = (char *)st->up.host + region_offset;
    for (int a = 0; a < 3; a++) {
        memcpy(stage + a * plane, w->boxes.lo[a] + first, plane);
        memcpy(stage + (3 + a) * plane, w->boxes.hi[a] + first, plane);
    }
    TRY(write_buffer(st, st->input.mem, region_offset, 6 * plane, stage, false));
    // Box k's floats start at float (region_offset / 4 + k), planes `count` floats apart.
    cl_uint box_stride = 1, plane_arg = count;
    cl_uint start = (cl_uint)(region_offset / sizeof(float));
    const kernel_arg args[] = {ARG(st->input.mem), ARG(box_stride), ARG(plane_arg), ARG(start),
                               ARG(count_arg),     ARG(padded_arg), ARG(lo->mem),   ARG(hi->mem)};
    return launch(st, K_CONVERT, global, 0, 8, args);
}

// ---------------------------------------------------------------------------------------------
// Scans and radix sort

// Exclusive scan of count uints into ulong offsets; the total goes to registers[slot].
static bpx_status scan(cl_state *st, cl_mem in, uint32_t count, cl_mem out, cl_uint slot)
{
    size_t chunk = (size_t)st->dev->scan_wg * BPX_CL_SCAN_ITEMS;
    size_t groups = (count + chunk - 1) / chunk;
    TRY(dbuf_reserve(st, &st->sums, (groups ? groups : 1) * sizeof(cl_ulong)));
    cl_uint count_arg = count, groups_arg = (cl_uint)groups;
    size_t wg = st->dev->scan_wg;
    const kernel_arg reduce[] = {ARG(in), ARG(count_arg), ARG(st->sums.mem)};
    TRY(launch(st, K_SCAN_REDUCE, groups * wg, wg, 3, reduce));
    const kernel_arg sums[] = {ARG(st->sums.mem), ARG(groups_arg), ARG(st->registers.mem),
                               ARG(slot)};
    TRY(launch(st, K_SCAN_SUMS, wg, wg, 4, sums));
    const kernel_arg apply[] = {ARG(in), ARG(count_arg), ARG(st->sums.mem), ARG(out)};
    return launch(st, K_SCAN_APPLY, groups * wg, wg, 4, apply);
}

// Stable LSD radix sort of (keys[0], values[0]) by the low `bits` bits of the keys, through
// (keys[1], values[1]); *result tells which of the two holds the sorted data.
static bpx_status radix_sort(cl_state *st, dbuf *keys, dbuf *values, uint32_t count, unsigned bits,
                             int *result)
{
    *result = 0;
    if (count < 2)
        return BPX_OK;
    size_t wg = st->dev->scan_wg;
    size_t groups = (count + wg * BPX_CL_SCAN_ITEMS - 1) / (wg * BPX_CL_SCAN_ITEMS);
    uint32_t bins = 16 * (uint32_t)groups;
    TRY(dbuf_reserve(st, &st->hist, bins * sizeof(cl_uint)));
    TRY(dbuf_reserve(st, &st->hist_offsets, bins * sizeof(cl_ulong)));
    cl_uint count_arg = count;
    int cur = 0;
    for (unsigned shift = 0; shift < bits; shift += 4) {
        cl_uint shift_arg = shift;
        const kernel_arg c[] = {ARG(keys[cur].mem), ARG(count_arg), ARG(shift_arg),
                                ARG(st->hist.mem)};
        TRY(launch(st, K_RADIX_COUNT, groups * wg, wg, 4, c));
        TRY(scan(st, st->hist.mem, bins, st->hist_offsets.mem, 2));
        const kernel_arg s[] = {
            ARG(keys[cur].mem),      ARG(values[cur].mem),      ARG(count_arg),
            ARG(shift_arg),          ARG(st->hist_offsets.mem), ARG(keys[1 - cur].mem),
            ARG(values[1 - cur].mem)};
        TRY(launch(st, K_RADIX_SCATTER, groups * wg, wg, 7, s));
        cur = 1 - cur;
    }
    *result = cur;
    return BPX_OK;
}

static bpx_status read_register(cl_state *st, cl_uint slot, uint64_t *value)
{
    TRY(read_buffer(st, st->registers.mem, slot * sizeof(cl_ulong), sizeof(cl_ulong),
                    (char *)st->reg.host + slot * sizeof(cl_ulong)));
    cl_ulong v;
    memcpy(&v, (char *)st->reg.host + slot * sizeof(cl_ulong), sizeof v);
    *value = v;
    return BPX_OK;
}

// Reads count pairs from the device buffer into out (appended), through pinned memory.
static bpx_status read_pairs(cl_state *st, cl_mem pairs, size_t count, bpx_pair_list *out)
{
    if (count == 0)
        return BPX_OK;
    if (!bpx__list_reserve(out, count))
        return BPX_ERR_OUT_OF_MEMORY;
    TRY(pinned_reserve(st, &st->down, count * sizeof(bpx_pair)));
    TRY(read_buffer(st, pairs, 0, count * sizeof(bpx_pair), st->down.host));
    memcpy(out->pairs + out->count, st->down.host, count * sizeof(bpx_pair));
    out->count += count;
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// Brute force

// The first pair buffer: def.opencl_pair_capacity pairs (default 65536), or less when the
// memory limit is tight (down to 1024 pairs; pairs beyond are read out in windows).
static bpx_status reserve_pair_window(cl_state *st)
{
    size_t want = st->first_pair_capacity;
    for (;;) {
        bpx_status status = dbuf_reserve(st, &st->pairs, want * sizeof(bpx_pair));
        if (status != BPX_ERR_DEVICE_MEMORY || want <= 1024)
            return status;
        want /= 2;
    }
}

// Rows (keys lo/hi, padded_rows, numbered from ia) against columns (lo_b/hi_b, padded_cols,
// numbered from jb): every pair with j > i, appended to out in (i, j) order.
static bpx_status brute_block(cl_state *st, cl_mem lo, cl_mem hi, uint32_t padded_rows, uint32_t ia,
                              cl_mem lo_b, cl_mem hi_b, uint32_t padded_cols, uint32_t jb,
                              bpx_pair_list *out)
{
    unsigned tile = st->tile;
    size_t groups = padded_rows / tile;
    TRY(dbuf_reserve(st, &st->row_count, (size_t)padded_rows * sizeof(cl_uint)));
    TRY(dbuf_reserve(st, &st->stash, (size_t)padded_rows * BPX_CL_STASH * sizeof(cl_uint)));
    TRY(dbuf_reserve(st, &st->group_sum, groups * sizeof(cl_ulong)));
    TRY(dbuf_reserve(st, &st->group_long, groups * sizeof(cl_uint)));
    cl_uint ia_arg = ia, jb_arg = jb, cols_arg = padded_cols, groups_arg = (cl_uint)groups;
    cl_uint slot = 0;
    const kernel_arg count_args[] = {ARG(lo),
                                     ARG(hi),
                                     ARG(ia_arg),
                                     ARG(lo_b),
                                     ARG(hi_b),
                                     ARG(cols_arg),
                                     ARG(jb_arg),
                                     ARG(st->row_count.mem),
                                     ARG(st->stash.mem),
                                     ARG(st->group_sum.mem),
                                     ARG(st->group_long.mem)};
    TRY(launch(st, K_BRUTE_COUNT, padded_rows, tile, 11, count_args));
    const kernel_arg sums_args[] = {ARG(st->group_sum.mem), ARG(groups_arg), ARG(st->registers.mem),
                                    ARG(slot)};
    TRY(launch(st, K_SCAN_SUMS, st->dev->scan_wg, st->dev->scan_wg, 4, sums_args));
    // Tests made, as the kernel walks them: each group from its first tile to the end.
    for (size_t g = 0; g < groups; g++) {
        uint64_t first = (uint64_t)ia + g * tile + 1;
        uint64_t start = first <= jb ? 0 : (first - jb) / tile * tile;
        if (start < padded_cols)
            st->tests += (padded_cols - start) * (uint64_t)tile;
    }

    // Emit at once into the buffer there is (the count is not known yet), then read the
    // register: when the buffer was too small, grow it (or, past the memory limit, read the
    // pairs out in windows) and emit again. No pair is lost either way.
    if (st->pairs.size == 0)
        TRY(reserve_pair_window(st));
    cl_ulong window = 0, capacity = st->pairs.size / sizeof(bpx_pair);
    const kernel_arg emit_args[] = {ARG(lo),
                                    ARG(hi),
                                    ARG(ia_arg),
                                    ARG(lo_b),
                                    ARG(hi_b),
                                    ARG(cols_arg),
                                    ARG(jb_arg),
                                    ARG(st->row_count.mem),
                                    ARG(st->stash.mem),
                                    ARG(st->group_sum.mem),
                                    ARG(st->group_long.mem),
                                    ARG(st->pairs.mem),
                                    ARG(window),
                                    ARG(capacity)};
    TRY(launch(st, K_BRUTE_EMIT, padded_rows, tile, 14, emit_args));
    uint64_t total;
    TRY(read_register(st, slot, &total));
    if (total > capacity) {
        // Too small: grow to the exact need and emit again; past the memory limit keep the
        // buffer, which holds the first window already, and read the rest window by window.
        bpx_status grown = dbuf_reserve(st, &st->pairs, total * sizeof(bpx_pair));
        if (grown == BPX_OK) {
            st->counters.emit_reruns++;
            capacity = st->pairs.size / sizeof(bpx_pair);
            TRY(launch(st, K_BRUTE_EMIT, padded_rows, tile, 14, emit_args));
        } else if (grown != BPX_ERR_DEVICE_MEMORY) {
            return grown;
        }
    }
    for (;;) {
        size_t count = total - window < capacity ? (size_t)(total - window) : (size_t)capacity;
        TRY(read_pairs(st, st->pairs.mem, count, out));
        window += count;
        if (window >= total)
            return BPX_OK;
        st->counters.pair_windows++;
        TRY(launch(st, K_BRUTE_EMIT, padded_rows, tile, 14, emit_args));
    }
}

// Everything on the device at once.
static bpx_status brute_all(cl_state *st, bpx_world *w, bpx_block *block)
{
    uint32_t padded = (uint32_t)round_up(w->n, st->tile);
    TRY(upload_keys(st, w, 0, w->n, padded, 0, &st->lo, &st->hi));
    st->counters.brute_cycles++;
    return brute_block(st, st->lo.mem, st->hi.mem, padded, 0, st->lo.mem, st->hi.mem, padded, 0,
                       &block->hits);
}

// Small sets: one launch (bpx_brute_small), then the count and the pairs read back together,
// as many pairs as last cycle's count and a quarter more (a second read when that was short).
static bpx_status brute_small(cl_state *st, bpx_world *w, bpx_block *block)
{
    uint32_t n = w->n;
    uint32_t padded = (uint32_t)round_up(n, st->tile);
    TRY(upload_keys(st, w, 0, n, padded, 0, &st->lo, &st->hi));
    if (st->pairs.size == 0)
        TRY(reserve_pair_window(st));
    cl_ulong capacity = st->pairs.size / sizeof(bpx_pair);
    cl_uint n_arg = n, slot = 0;
    const kernel_arg args[] = {ARG(st->lo.mem),    ARG(st->hi.mem), ARG(n_arg),
                               ARG(st->pairs.mem), ARG(capacity),   ARG(st->registers.mem),
                               ARG(slot)};
    TRY(launch(st, K_BRUTE_SMALL, st->dev->small_wg, st->dev->small_wg, 7, args));
    st->tests += (uint64_t)n * (n - 1) / 2;
    st->counters.brute_cycles++;
    uint64_t guess = st->last_pairs + st->last_pairs / 4 + 64;
    size_t first = (size_t)(guess < capacity ? guess : capacity);
    TRY(pinned_reserve(st, &st->down, first * sizeof(bpx_pair)));
    TRY(read_later(st, st->registers.mem, 0, sizeof(cl_ulong), st->reg.host));
    TRY(read_later(st, st->pairs.mem, 0, first * sizeof(bpx_pair), st->down.host));
    CL_CHECK(st, clFinish(st->queue), "clFinish");
    cl_ulong total;
    memcpy(&total, st->reg.host, sizeof total);
    if (total > capacity) { // the buffer was too small: grow it to the need and run again
        bpx_status grown = dbuf_reserve(st, &st->pairs, total * sizeof(bpx_pair));
        if (grown == BPX_ERR_DEVICE_MEMORY) {
            // Past the memory limit: the tiled path reads the pairs in windows, from now on
            // (its own buffers first, then a window in the room left).
            st->small_off = true;
            dbuf_release(st, &st->pairs);
            return brute_all(st, w, block);
        }
        if (grown != BPX_OK)
            return grown;
        st->counters.emit_reruns++;
        capacity = total;
        TRY(launch(st, K_BRUTE_SMALL, st->dev->small_wg, st->dev->small_wg, 7, args));
    }
    if (total > first) // the guess was short: read them all
        return read_pairs(st, st->pairs.mem, (size_t)total, &block->hits);
    if (!bpx__list_reserve(&block->hits, (size_t)total))
        return BPX_ERR_OUT_OF_MEMORY;
    memcpy(block->hits.pairs, st->down.host, (size_t)total * sizeof(bpx_pair));
    block->hits.count = (size_t)total;
    return BPX_OK;
}

// The paper's "streaming AABBs between CPU and FPGA": blocks of `block_boxes` boxes; each row
// block stays on the device while every later column block passes through. A row block's pairs
// arrive column block by column block, and are put back in row order on the host (stable
// counting sort by row), so the stream stays ordered by (i, j).
static bpx_status brute_streamed(cl_state *st, bpx_world *w, bpx_block *block, uint32_t block_boxes)
{
    uint32_t n = w->n;
    uint32_t blocks = (n + block_boxes - 1) / block_boxes;
    size_t region = 6 * (size_t)block_boxes * sizeof(float);
    TRY(pinned_reserve(st, &st->up, 2 * region));
    // Every block-sized buffer first, then the pair window takes what is left.
    size_t keys = (size_t)block_boxes * 16, groups = block_boxes / st->tile;
    TRY(dbuf_reserve(st, &st->input, 2 * region));
    TRY(dbuf_reserve(st, &st->lo, keys));
    TRY(dbuf_reserve(st, &st->hi, keys));
    TRY(dbuf_reserve(st, &st->lo_b, keys));
    TRY(dbuf_reserve(st, &st->hi_b, keys));
    TRY(dbuf_reserve(st, &st->row_count, (size_t)block_boxes * sizeof(cl_uint)));
    TRY(dbuf_reserve(st, &st->stash, (size_t)block_boxes * BPX_CL_STASH * sizeof(cl_uint)));
    TRY(dbuf_reserve(st, &st->group_sum, groups * sizeof(cl_ulong)));
    TRY(dbuf_reserve(st, &st->group_long, groups * sizeof(cl_uint)));
    if (st->pairs.size == 0)
        TRY(reserve_pair_window(st));
    if (st->row_hist_count < (size_t)block_boxes + 1) {
        bpx__free(st->row_hist, st->row_hist_count * sizeof(uint32_t));
        st->row_hist_count = 0;
        if (!(st->row_hist = bpx__alloc(((size_t)block_boxes + 1) * sizeof(uint32_t))))
            return BPX_ERR_OUT_OF_MEMORY;
        st->row_hist_count = (size_t)block_boxes + 1;
    }
    bpx_pair_list *stage = &block->stage;
    for (uint32_t bi = 0; bi < blocks; bi++) {
        uint32_t ia = bi * block_boxes;
        uint32_t rows = n - ia < block_boxes ? n - ia : block_boxes;
        uint32_t padded_rows = (uint32_t)round_up(rows, st->tile);
        TRY(upload_keys(st, w, ia, rows, padded_rows, 0, &st->lo, &st->hi));
        st->counters.streamed_blocks++;
        stage->count = 0;
        for (uint32_t bj = bi; bj < blocks; bj++) {
            uint32_t jb = bj * block_boxes;
            uint32_t cols = n - jb < block_boxes ? n - jb : block_boxes;
            uint32_t padded_cols = (uint32_t)round_up(cols, st->tile);
            cl_mem lo_b = st->lo.mem, hi_b = st->hi.mem;
            if (bj != bi) {
                TRY(upload_keys(st, w, jb, cols, padded_cols, region, &st->lo_b, &st->hi_b));
                st->counters.streamed_blocks++;
                lo_b = st->lo_b.mem;
                hi_b = st->hi_b.mem;
            }
            TRY(brute_block(st, st->lo.mem, st->hi.mem, padded_rows, ia, lo_b, hi_b, padded_cols,
                            jb, stage));
        }
        // Stable counting sort of the row block's pairs by row.
        uint32_t *start = st->row_hist;
        memset(start, 0, ((size_t)rows + 1) * sizeof(uint32_t));
        for (size_t k = 0; k < stage->count; k++)
            start[stage->pairs[k].i - ia + 1]++;
        for (uint32_t r = 0; r < rows; r++)
            start[r + 1] += start[r];
        if (!bpx__list_reserve(&block->hits, stage->count))
            return BPX_ERR_OUT_OF_MEMORY;
        bpx_pair *dst = block->hits.pairs + block->hits.count;
        for (size_t k = 0; k < stage->count; k++)
            dst[start[stage->pairs[k].i - ia]++] = stage->pairs[k];
        block->hits.count += stage->count;
    }
    st->counters.brute_cycles++;
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// Sort and sweep

static unsigned bits_for(uint32_t max_value)
{
    unsigned bits = 1;
    while (bits < 32 && (max_value >> bits) != 0)
        bits++;
    return bits;
}

// Returns BPX_ERR_DEVICE_MEMORY, before any pair is written, when the pairs would not fit:
// the caller then runs brute force, which can read pairs out in windows.
static bpx_status sweep_all(cl_state *st, bpx_world *w, bpx_block *block)
{
    uint32_t n = w->n;
    uint32_t padded = (uint32_t)round_up(n, st->tile);
    TRY(upload_keys(st, w, 0, n, padded, 0, &st->lo, &st->hi));
    for (int k = 0; k < 2; k++) {
        TRY(dbuf_reserve(st, &st->keys[k], (size_t)n * sizeof(cl_uint)));
        TRY(dbuf_reserve(st, &st->values[k], (size_t)n * sizeof(cl_uint)));
    }
    cl_uint n_arg = n;
    const kernel_arg key_args[] = {ARG(st->lo.mem), ARG(n_arg), ARG(st->keys[0].mem),
                                   ARG(st->values[0].mem)};
    TRY(launch(st, K_SWEEP_KEYS, n, 0, 4, key_args));
    int sorted;
    TRY(radix_sort(st, st->keys, st->values, n, 32, &sorted));
    cl_mem index = st->values[sorted].mem;
    TRY(dbuf_reserve(st, &st->sorted_lo, (size_t)padded * 16));
    TRY(dbuf_reserve(st, &st->sorted_hi, (size_t)padded * 16));
    cl_uint padded_arg = padded;
    const kernel_arg gather_args[] = {
        ARG(st->lo.mem),        ARG(st->hi.mem),       ARG(index), ARG(n_arg), ARG(padded_arg),
        ARG(st->sorted_lo.mem), ARG(st->sorted_hi.mem)};
    TRY(launch(st, K_SWEEP_GATHER, padded, 0, 7, gather_args));
    TRY(dbuf_reserve(st, &st->counts, (size_t)padded * sizeof(cl_uint)));
    TRY(dbuf_reserve(st, &st->offsets, (size_t)n * sizeof(cl_ulong)));
    const kernel_arg count_args[] = {ARG(st->sorted_lo.mem), ARG(st->sorted_hi.mem),
                                     ARG(padded_arg), ARG(st->counts.mem)};
    TRY(launch(st, K_SWEEP_COUNT, padded, st->tile, 4, count_args));
    TRY(scan(st, st->counts.mem, n, st->offsets.mem, 1));
    uint64_t total;
    TRY(read_register(st, 1, &total));
    if (total == 0) {
        st->counters.sweep_cycles++;
        return BPX_OK;
    }
    // The pairs are sorted too: two sets of (i, j) planes and the packed result.
    uint64_t need = total * (4 * sizeof(cl_uint) + sizeof(bpx_pair));
    uint64_t held =
        st->pi[0].size + st->pi[1].size + st->pj[0].size + st->pj[1].size + st->pairs.size;
    if (total > UINT32_MAX || total * sizeof(bpx_pair) > st->dev->max_alloc ||
        st->used - held + need > st->limit)
        return BPX_ERR_DEVICE_MEMORY;
    for (int k = 0; k < 2; k++) {
        TRY(dbuf_reserve(st, &st->pi[k], total * sizeof(cl_uint)));
        TRY(dbuf_reserve(st, &st->pj[k], total * sizeof(cl_uint)));
    }
    TRY(dbuf_reserve(st, &st->pairs, total * sizeof(bpx_pair)));
    cl_ulong capacity = total;
    const kernel_arg write_args[] = {
        ARG(st->sorted_lo.mem), ARG(st->sorted_hi.mem), ARG(index),         ARG(n_arg),
        ARG(padded_arg),        ARG(st->offsets.mem),   ARG(st->pi[0].mem), ARG(st->pj[0].mem),
        ARG(capacity)};
    TRY(launch(st, K_SWEEP_WRITE, padded, st->tile, 9, write_args));
    // (i, j) order: stable sort by j, then by i.
    unsigned bits = bits_for(n - 1);
    int by_j;
    TRY(radix_sort(st, st->pj, st->pi, (uint32_t)total, bits, &by_j));
    dbuf keys[2] = {st->pi[by_j], st->pi[1 - by_j]};
    dbuf values[2] = {st->pj[by_j], st->pj[1 - by_j]};
    int by_i;
    TRY(radix_sort(st, keys, values, (uint32_t)total, bits, &by_i));
    const kernel_arg pack_args[] = {ARG(keys[by_i].mem), ARG(values[by_i].mem), ARG(capacity),
                                    ARG(st->pairs.mem)};
    TRY(launch(st, K_SWEEP_INTERLEAVE, (size_t)total, 0, 4, pack_args));
    TRY(read_pairs(st, st->pairs.mem, (size_t)total, &block->hits));
    st->counters.sweep_cycles++;
    return BPX_OK;
}

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

// The sort and sweep's own buffers (a whole-set cycle keeps them for the next).
static void release_sweep_buffers(cl_state *st)
{
    dbuf *sweep_set[] = {&st->keys[0],   &st->keys[1],   &st->values[0], &st->values[1],
                         &st->sorted_lo, &st->sorted_hi, &st->counts,    &st->offsets,
                         &st->pi[0],     &st->pi[1],     &st->pj[0],     &st->pj[1]};
    for (size_t k = 0; k < sizeof sweep_set / sizeof sweep_set[0]; k++)
        dbuf_release(st, sweep_set[k]);
}

static bpx_status run_cycle(cl_state *st, bpx_world *w, bpx_block *block)
{
    uint32_t n = w->n;
    if (n == 0)
        return BPX_OK;
    if (st->source == SOURCE_BUFFER && w->dead)
        return BPX_ERR_BAD_STATE; // add/remove/move_boxes on a world fed from a device buffer
    if (st->source == SOURCE_CENTRES && w->dead)
        st->source = SOURCE_HOST; // removed objects are inert in the host's boxes only
    uint32_t forced = w->def.opencl_block_boxes;
    if (forced) {
        forced = forced / st->tile * st->tile;
        if (forced < st->tile)
            forced = st->tile;
    }
    uint32_t fit_all = block_capacity(st, BYTES_PER_BOX);
    bool whole = (forced == 0 || forced >= n) && fit_all >= n;
    if (whole) {
        bool sweep = w->def.opencl_method == BPX_OPENCL_SWEEP ||
                     (w->def.opencl_method == BPX_OPENCL_AUTO && n >= SWEEP_MIN_N &&
                      st->last_pairs <= (uint64_t)DENSE_PAIRS_PER_BOX * n);
        if (sweep) {
            bpx_status status = sweep_all(st, w, block);
            if (status != BPX_ERR_DEVICE_MEMORY)
                return status;
            // Pairs beyond the limit: brute force reads them out in windows.
            block->hits.count = 0;
            st->counters.sweep_fallbacks++;
            clFinish(st->queue);
            release_sweep_buffers(st); // brute force may need the room
        }
        if (n <= st->dev->small_n && !st->small_off)
            return brute_small(st, w, block);
        return brute_all(st, w, block);
    }
    // Streaming: free what a whole-set cycle kept, then blocks as large as the limit allows.
    release_sweep_buffers(st);
    uint32_t block_boxes = block_capacity(st, BYTES_PER_STREAMED_BOX);
    if (block_boxes < st->tile && st->pairs.size) {
        // A pair buffer grown in an earlier cycle leaves no room: start again from a window.
        dbuf_release(st, &st->pairs);
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
    return brute_streamed(st, w, block, block_boxes);
}

static bpx_status opencl_compare(bpx_world *w)
{
    cl_state *st = NULL;
    TRY(state_get(w, &st));
    if (w->planned_n != w->n)
        TRY(bpx__emitter_plan(w, true));
    bpx_block *block = &w->blocks[0];
    block->hits.count = 0;
    block->tests = 0;
    block->status = BPX_OK;
    st->bytes_in = st->bytes_out = st->tests = 0;
    memset(st->ns, 0, sizeof st->ns);
    bpx_status status = run_cycle(st, w, block);
    events_flush(st);
    if (status != BPX_OK) {
        block->hits.count = 0;
        clFinish(st->queue);
    }
    block->tests = st->tests;
    st->last_pairs = block->hits.count;
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
    if (!st && state_get(w, &st) != BPX_OK)
        return;
    if (st->user_buffer)
        clReleaseMemObject(st->user_buffer);
    st->user_buffer = NULL;
    st->source = SOURCE_HOST;
    size_t size = (size_t)w->extent_count * 3 * sizeof(float);
    // Devices that flush subnormals would round the updater's add differently from the host.
    if (w->dead || !st->dev->denormals || size == 0 ||
        pinned_reserve(st, &st->up_centres, size) != BPX_OK)
        return;
    memcpy(st->up_centres.host, centres, size);
    st->source = SOURCE_CENTRES;
}

static void opencl_destroy(bpx_world *w)
{
    state_free(w->backend_state);
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

static bpx_status opencl_world_state(bpx_world *w, cl_state **st)
{
    if (w->backend != &bpx__opencl_backend)
        return bpx__error(&w->error, BPX_ERR_BACKEND_UNAVAILABLE, UINT32_MAX, -1,
                          "the world's backend is %s, not opencl", w->backend->name);
    bpx_status status = state_get(w, st);
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
    TRY(opencl_world_state(w, &st));
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
    TRY(opencl_world_state(w, &st));
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
        status = write_buffer(st, st->check.mem, 0, sizeof none, &none, true);
        const kernel_arg args[] = {ARG(mem), ARG(n_arg), ARG(st->check.mem)};
        if (status == BPX_OK)
            status = launch(st, K_VALIDATE, n, 0, 3, args);
        if (status == BPX_OK)
            status = read_buffer(st, st->check.mem, 0, sizeof bad, &bad);
        bpx_box box;
        if (status == BPX_OK && bad != UINT32_MAX)
            status = read_buffer(st, mem, (size_t)bad * sizeof box, sizeof box, &box);
        events_flush(st);
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
    w->stats.update_ns = bpx__now_ns() - start;
    return BPX_OK;
}
