// The opencl backend's device-resident cycles (include/bpx/opencl.h): the whole cycle enqueued
// on the world's in-order queue and left running; the pairs, sorted by (i, j), and their count
// stay in device memory for the caller's next kernel. No host round trip happens inside the
// cycle: every path sizes its buffers from the previous cycle's count before enqueueing
// anything (the tree and the sweep sort their whole room, padded with keys that sort last),
// the count follows the pairs into pinned host memory (8 bytes), and the next call waits for
// that copy only. A count past the room is reported (CAPACITY, with the count) and the next
// cycle has room for it: nothing short is ever taken for the pair set.

#include <string.h>

#include "core/log.h"
#include "state.h"

// Pairs a device-resident cycle makes room for: the last cycle's count and a quarter more (plus
// a little), or before any count max(opencl_pair_capacity, 2 per box); never more than the
// n(n - 1) / 2 there can be.
static uint64_t room_for(const bpx_cl_state *st, uint32_t n)
{
    uint64_t most = (uint64_t)n * (n - 1) / 2;
    uint64_t need = 2 * (uint64_t)n;
    if (need < st->first_pair_capacity)
        need = st->first_pair_capacity;
    if (st->pairs_known) {
        uint64_t seen = st->last_pairs < most ? st->last_pairs : most;
        need = seen + seen / 4 + 1024;
    }
    return need < most ? need : most;
}

void bpx__cl_resident_settle(bpx_cl_state *st)
{
    if (st->resident != RESIDENT_PENDING)
        return;
    cl_int err =
        st->event_count ? clWaitForEvents((cl_uint)st->event_count, st->events) : CL_SUCCESS;
    bpx__cl_events_flush(st);
    cl_ulong found;
    memcpy(&found, st->resident_host.host, sizeof found);
    st->resident = RESIDENT_DONE;
    st->resident_found = found;
    st->resident_status = err != CL_SUCCESS               ? BPX_ERR_DEVICE
                          : found == UINT64_MAX           ? BPX_ERR_TOO_MANY_PAIRS
                          : found > st->resident_capacity ? BPX_ERR_CAPACITY
                                                          : BPX_OK;
    if (err != CL_SUCCESS)
        bpx__log(0, "opencl: the device-resident cycle failed: %s", bpx__cl_error_name(err));
    st->last_pairs = err == CL_SUCCESS ? found : 0;
    st->pairs_known = err == CL_SUCCESS;
}

// Every command of the cycle, then the count's copy to the host, enqueued and flushed.
static bpx_status enqueue_cycle(const bpx_cycle *cycle, bpx_cl_state *st)
{
    if (!st->resident_count.mem) {
        // Tiny and always needed: outside the memory limit, like the registers.
        uint64_t limit = st->limit;
        st->limit = UINT64_MAX;
        bpx_status status = bpx__cl_dbuf_reserve(st, &st->resident_count, sizeof(cl_ulong));
        st->limit = limit;
        TRY(status);
    }
    TRY(bpx__cl_pinned_reserve(st, &st->resident_host, sizeof(cl_ulong)));
    cl_mem count = st->resident_count.mem;
    uint32_t n = cycle->n;
    if (n < 2) {
        TRY(bpx__cl_dbuf_reserve(st, &st->pairs, sizeof(bpx_pair)));
        st->resident_capacity = st->pairs.size / sizeof(bpx_pair);
        TRY(bpx__cl_fill(st, count, 0, sizeof(cl_ulong)));
    } else {
        uint64_t need = room_for(st, n);
        int method = bpx__cl_method(st, cycle);
        bpx_status status = BPX_ERR_DEVICE_MEMORY;
        if (method == BPX_OPENCL_TREE)
            status = bpx__cl_tree_resident(st, cycle, need, count, &st->resident_capacity);
        else if (method == BPX_OPENCL_SWEEP)
            status = bpx__cl_sweep_resident(st, cycle, need, count, &st->resident_capacity);
        if (method != BPX_OPENCL_BRUTE && status == BPX_ERR_DEVICE_MEMORY) {
            // Their keys and planes passed the limit: brute force needs the pairs alone.
            if (method == BPX_OPENCL_TREE)
                st->counters.tree_fallbacks++;
            else
                st->counters.sweep_fallbacks++;
            bpx__cl_release_sweep_buffers(st);
        }
        if (status == BPX_ERR_DEVICE_MEMORY) {
            status = bpx__cl_brute_resident(st, cycle, need, count, &st->resident_capacity);
            if (status == BPX_ERR_DEVICE_MEMORY)
                return bpx__error(cycle->error, status, UINT32_MAX, -1,
                                  "collide_device: room for %llu pairs passes the device "
                                  "memory limit of %llu bytes",
                                  (unsigned long long)need, (unsigned long long)st->limit);
        }
        TRY(status);
    }
    TRY(bpx__cl_read_later(st, count, 0, sizeof(cl_ulong), st->resident_host.host));
    CL_CHECK(st, clFlush(st->queue), "clFlush");
    return BPX_OK;
}

// The backend's state (made by the world's first device call, handles or input), or the error.
static bpx_status resident_state(void **state, bpx_cycle *cycle, bpx_cl_state **st)
{
    bpx_status status = bpx__cl_state_get(state, cycle->def, st);
    if (status != BPX_OK)
        return bpx__error(cycle->error, status, UINT32_MAX, -1, "opencl: no device state: %s",
                          bpx_status_string(status));
    return BPX_OK;
}

bpx_status bpx__cl_collide_device(void **state, bpx_cycle *cycle, void *stream)
{
    bpx_cl_state *st = NULL;
    if (stream)
        return bpx__error(cycle->error, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "collide_device: an opencl cycle runs on the world's queue "
                          "(bpx_opencl_world_handles); stream must be NULL");
    TRY(resident_state(state, cycle, &st));
    bpx__cl_resident_settle(st); // the last cycle's count sizes this one's room
    st->resident = RESIDENT_NONE;
    if (bpx__cl_check_source(st, cycle) != BPX_OK)
        return bpx__error(cycle->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "collide_device: the boxes come from a device buffer, but objects "
                          "were added or removed by id");
    uint32_t forced;
    if (cycle->n > 0 && bpx__cl_streamed(st, cycle, &forced)) {
        if (forced)
            return bpx__error(cycle->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                              "collide_device: opencl_block_boxes (%u) streams %u boxes in "
                              "blocks; a device-resident cycle needs them all on the device",
                              forced, cycle->n);
        return bpx__error(cycle->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "collide_device: %u boxes do not fit on the device at once under the "
                          "memory limit of %llu bytes (the host's cycle streams them in blocks)",
                          cycle->n, (unsigned long long)st->limit);
    }
    st->bytes_in = st->bytes_out = st->tests = 0;
    memset(st->ns, 0, sizeof st->ns);
    bpx_status status = enqueue_cycle(cycle, st);
    if (status != BPX_OK) {
        clFinish(st->queue);
        bpx__cl_events_flush(st);
        if (cycle->error->status == status)
            return status; // named already
        return bpx__error(cycle->error, status, UINT32_MAX, -1,
                          "opencl: enqueueing the device-resident cycle failed: %s",
                          bpx_status_string(status));
    }
    st->resident = RESIDENT_PENDING;
    return BPX_OK;
}

// BAD_STATE when the world has no device-resident cycle's result.
static bpx_status resident_result(bpx_cycle *cycle, const bpx_cl_state *st, const char *call)
{
    if (st->resident != RESIDENT_NONE)
        return BPX_OK;
    return bpx__error(cycle->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                      "%s: no device-resident cycle (bpx_opencl_collide_device) since the world "
                      "was made or since its last bpx_world_collide",
                      call);
}

bpx_status bpx__cl_device_pairs(void **state, bpx_cycle *cycle, void **pairs, void **count,
                                size_t *capacity)
{
    bpx_cl_state *st = NULL;
    TRY(resident_state(state, cycle, &st));
    TRY(resident_result(cycle, st, "device_pairs"));
    if (pairs)
        *pairs = st->pairs.mem;
    if (count)
        *count = st->resident_count.mem;
    if (capacity)
        *capacity = (size_t)st->resident_capacity;
    return BPX_OK;
}

bpx_status bpx__cl_finish(void **state, bpx_cycle *cycle, uint64_t *found)
{
    bpx_cl_state *st = NULL;
    TRY(resident_state(state, cycle, &st));
    TRY(resident_result(cycle, st, "finish"));
    bpx__cl_resident_settle(st);
    *found = st->resident_found;
    cycle->report.resident = cycle->report.timed = true;
    cycle->report.tests = st->tests;
    cycle->report.transfer_in_ns = st->ns[EV_IN];
    cycle->report.transfer_out_ns = st->ns[EV_OUT];
    cycle->report.device_ns = st->ns[EV_DEVICE];
    cycle->report.bytes_in = st->bytes_in;
    cycle->report.bytes_out = st->bytes_out;
    switch (st->resident_status) {
    case BPX_OK:
        return BPX_OK;
    case BPX_ERR_CAPACITY:
        return bpx__error(cycle->error, BPX_ERR_CAPACITY, UINT32_MAX, -1,
                          "opencl: %llu pairs found, the device buffer held %llu; the next "
                          "device-resident cycle has room",
                          (unsigned long long)st->resident_found,
                          (unsigned long long)st->resident_capacity);
    case BPX_ERR_TOO_MANY_PAIRS:
        return bpx__error(cycle->error, BPX_ERR_TOO_MANY_PAIRS, UINT32_MAX, -1,
                          "opencl: 2^32 pairs or more: the tree's counter wrapped");
    default:
        return bpx__error(cycle->error, st->resident_status, UINT32_MAX, -1,
                          "opencl: the device-resident cycle failed on the device");
    }
}
