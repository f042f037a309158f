// The cuda backend through the backend contract (core/backend.h): the host's cycle (compare),
// the boxes' changes, and the device calls of include/bpx/cuda.h (through core/device.c). The
// device side is cycle.cu and kernels.cu, behind cuda_api.h. Paper modules: the updater, the
// comparator and the emitter on a CUDA GPU; the interface is the link and its counted transfers.
#include <stdio.h>

#include "core/backend.h"
#include "core/validate.h"
#include "cuda_api.h"

static bool cuda_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    (void)def;
    return bpx__cuda_probe(reason, detail, size);
}

static bpx_status cuda_state(void **state, bpx_cycle *cycle, bpx_cuda **out)
{
    if (!*state) {
        bpx_cuda *cu = NULL;
        bpx_status s = bpx__cuda_open(&cu);
        if (s != BPX_OK)
            return bpx__error(cycle->error, s, UINT32_MAX, -1,
                              "cuda: the device could not be set up");
        *state = cu;
    }
    *out = *state;
    return BPX_OK;
}

// Names a bad device box the way bpx_world_set_boxes names a bad host box: that one box comes
// back and goes through the host's own check.
static bpx_status report_bad_box(bpx_cycle *cycle, const bpx_box *device_boxes, uint32_t index)
{
    bpx_box box;
    if (bpx__cuda_copy_in(&box, device_boxes + index, sizeof box) != BPX_OK)
        return bpx__error(cycle->error, BPX_ERR_DEVICE, index, -1, "cuda: device box %u is invalid",
                          index);
    bpx_error detail;
    bpx_status why = bpx__check_boxes(&box, 1, &detail);
    if (why == BPX_OK) // changed since the check ran
        why = BPX_ERR_NOT_FINITE;
    return bpx__error(cycle->error, why, index, detail.axis, "device box %u, axis %d: %s", index,
                      detail.axis, bpx_status_string(why));
}

// Names the object whose device centre makes a box that is not finite, as
// bpx_world_update_centres names it: that centre comes back and goes through the host's check.
static bpx_status report_bad_centre(bpx_cycle *cycle, const float *device_centres, uint32_t index)
{
    float centre[3];
    if (bpx__cuda_copy_in(centre, device_centres + 3 * (size_t)index, sizeof centre) != BPX_OK)
        return bpx__error(cycle->error, BPX_ERR_DEVICE, index, -1,
                          "cuda: device centre %u is invalid", index);
    const float *const *m = cycle->extents.minima;
    const float *const minima[3] = {m[0] + index, m[1] + index, m[2] + index};
    bpx_error detail = {0};
    bpx_status why = bpx__check_centres(centre, minima, 1, &detail);
    if (why == BPX_OK) // changed since the check ran
        why = BPX_ERR_NOT_FINITE;
    return bpx__error(cycle->error, why, index, detail.axis,
                      "device centres, object %u, axis %d: %s", index, detail.axis,
                      bpx_status_string(why));
}

// The first bad object of the last cycle that read the caller's device boxes or centres.
static bpx_status report_bad_input(bpx_cycle *cycle, bpx_cuda *cu)
{
    uint32_t index = 0;
    bool min_greater = false;
    if (!bpx__cuda_bad_box(cu, &index, &min_greater))
        return bpx__error(cycle->error, BPX_ERR_DEVICE, UINT32_MAX, -1,
                          "cuda: the device reported an invalid box it cannot name");
    if (bpx__cuda_device_centres(cu))
        return report_bad_centre(cycle, bpx__cuda_device_centres(cu), index);
    if (bpx__cuda_device_boxes(cu))
        return report_bad_box(cycle, bpx__cuda_device_boxes(cu), index);
    // The host's own boxes or centres, checked before they were sent: never seen.
    return bpx__error(cycle->error, BPX_ERR_DEVICE, index, -1,
                      "cuda: the device made an invalid box %u of valid host data", index);
}

// Ids added, removed or moved (add/remove/move_boxes) since the input was given change the
// host's boxes alone (and their version): host centres give way to those boxes; the caller's
// device boxes or centres cannot follow (BAD_STATE).
static bpx_status cuda_check_source(bpx_cycle *cycle, bpx_cuda *cu)
{
    if (bpx__cuda_input_version(cu) == cycle->boxes_version)
        return BPX_OK;
    if (bpx__cuda_device_boxes(cu) || bpx__cuda_device_centres(cu))
        return bpx__error(cycle->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "cuda: boxes added, removed or moved by id since the device data was "
                          "set");
    bpx__cuda_use_device_boxes(cu, NULL, 0);
    bpx__cuda_set_input_version(cu, cycle->boxes_version);
    return BPX_OK;
}

static bpx_status cuda_compare(void **state, bpx_cycle *cycle)
{
    bpx_cuda *cu = NULL;
    bpx_status s = cuda_state(state, cycle, &cu);
    if (s != BPX_OK)
        return s;
    bpx_block *block;
    if ((s = bpx__emitter_one_block(cycle->sink, cycle->n, &block)) != BPX_OK)
        return s;
    bpx_soa soa = cycle->boxes;
    uint64_t count = 0;
    s = bpx__cuda_finish(cu, NULL); // a device cycle still in flight
    if (s == BPX_OK || s == BPX_ERR_CAPACITY || s == BPX_ERR_NOT_FINITE) {
        if ((s = cuda_check_source(cycle, cu)) != BPX_OK)
            return s;
        s = bpx__cuda_find(cu, soa.lo, soa.hi, soa.n, &count);
    }
    if (s == BPX_ERR_NOT_FINITE)
        return report_bad_input(cycle, cu);
    if (s == BPX_OK && !bpx__list_reserve(&block->hits, count))
        return bpx__error(cycle->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %llu pairs", (unsigned long long)count);
    if (s == BPX_OK)
        s = bpx__cuda_read_pairs(cu, block->hits.pairs, count);
    if (s != BPX_OK)
        return bpx__error(cycle->error, s, UINT32_MAX, -1, "cuda: the cycle failed on the device");
    block->hits.count = count;
    bpx_cuda_timing t = bpx__cuda_timing(cu);
    block->tests = t.tests;
    cycle->report.transfer_in_ns = t.in_ns;
    cycle->report.transfer_out_ns = t.out_ns;
    cycle->report.device_ns = t.device_ns;
    cycle->report.bytes_in = t.bytes_in;
    cycle->report.bytes_out = t.bytes_out;
    return BPX_OK;
}

static void cuda_destroy(void *state)
{
    bpx__cuda_close(state);
}

// New host boxes or centres: the device boxes or centres, if any, are no longer the world's.
// The cycle's centres go to the device's updater (12 bytes an object over the link, not 24),
// unless objects were removed by id (inert in the host's boxes alone) or the device could not
// take them: then the host's boxes, which the world made from the same centres.
static void cuda_boxes_set(void **state, const bpx_world_def *def, const bpx_boxes_change *change)
{
    (void)def;
    bpx_cuda *cu = *state;
    bool updater = change->centres && !change->inert_ids;
    if (!cu) {
        if (!updater || bpx__cuda_open(&cu) != BPX_OK)
            return;
        *state = cu;
    }
    bpx__cuda_set_input_version(cu, change->boxes_version);
    if (updater) {
        const bpx_extents *e = &change->extents;
        if (bpx__cuda_use_centres(cu, change->centres, false, e->minima, e->count) == BPX_OK)
            return;
    }
    bpx__cuda_use_device_boxes(cu, NULL, 0);
}

// ---------------------------------------------------------------------------------------------
// The device calls (include/bpx/cuda.h through core/device.c)

static bpx_status cuda_check_input(void **state, bpx_cycle *cycle, void *input, uint32_t n,
                                   bool centres)
{
    bpx_cuda *cu = NULL;
    bpx_status s = cuda_state(state, cycle, &cu);
    if (s != BPX_OK)
        return s;
    if ((s = bpx__cuda_finish(cu, NULL)) == BPX_ERR_DEVICE)
        return bpx__error(cycle->error, s, UINT32_MAX, -1, "cuda: the last device cycle failed");
    bool bad = false;
    s = centres ? bpx__cuda_check_device_centres(cu, input, cycle->extents.minima, n, &bad)
                : bpx__cuda_check_device_boxes(cu, input, n, &bad);
    if (s != BPX_OK)
        return bpx__error(cycle->error, s, UINT32_MAX, -1, "cuda: checking the device %s failed",
                          centres ? "centres" : "boxes");
    uint32_t index = 0;
    bool min_greater = false;
    if (bad && bpx__cuda_bad_box(cu, &index, &min_greater))
        return centres ? report_bad_centre(cycle, input, index)
                       : report_bad_box(cycle, input, index);
    return BPX_OK;
}

static bpx_status cuda_use_input(void **state, bpx_cycle *cycle, void *input, uint32_t n,
                                 bool centres)
{
    bpx_cuda *cu = *state; // made by check_input
    if (!centres) {
        bpx__cuda_use_device_boxes(cu, input, n);
    } else {
        bpx_status s = bpx__cuda_use_centres(cu, input, true, cycle->extents.minima, n);
        if (s != BPX_OK)
            return bpx__error(cycle->error, s, UINT32_MAX, -1,
                              "cuda: the device centres not taken");
    }
    bpx__cuda_set_input_version(cu, cycle->boxes_version);
    return BPX_OK;
}

static bpx_status cuda_collide(void **state, bpx_cycle *cycle, void *stream)
{
    bpx_cuda *cu = NULL;
    bpx_status s = cuda_state(state, cycle, &cu);
    if (s != BPX_OK)
        return s;
    if ((s = cuda_check_source(cycle, cu)) != BPX_OK)
        return s;
    s = bpx__cuda_collide_device(cu, stream, cycle->boxes.lo, cycle->boxes.hi, cycle->n);
    if (s != BPX_OK)
        return bpx__error(cycle->error, s, UINT32_MAX, -1, "cuda: enqueueing the cycle failed");
    return BPX_OK;
}

static bpx_status cuda_pairs(void **state, bpx_cycle *cycle, void **pairs, void **count,
                             size_t *capacity)
{
    bpx_cuda *cu = NULL;
    bpx_status s = cuda_state(state, cycle, &cu);
    if (s != BPX_OK)
        return s;
    const bpx_pair *p = NULL;
    const unsigned long long *c = NULL;
    size_t cap = 0;
    bpx__cuda_device_result(cu, &p, &c, &cap);
    if (pairs)
        *pairs = (void *)p;
    if (count)
        *count = (void *)c;
    if (capacity)
        *capacity = cap;
    return BPX_OK;
}

static bpx_status cuda_finish(void **state, bpx_cycle *cycle, uint64_t *found)
{
    bpx_cuda *cu = NULL;
    bpx_status s = cuda_state(state, cycle, &cu);
    if (s != BPX_OK)
        return s;
    s = bpx__cuda_finish(cu, found);
    cycle->report.resident = true; // its count; the device-resident cycle's times are not kept
    if (s == BPX_ERR_NOT_FINITE)
        return report_bad_input(cycle, cu);
    if (s == BPX_ERR_CAPACITY)
        return bpx__error(cycle->error, s, UINT32_MAX, -1,
                          "cuda: %llu pairs found, the device buffer held fewer; the next cycle "
                          "has room",
                          (unsigned long long)*found);
    if (s != BPX_OK)
        return bpx__error(cycle->error, s, UINT32_MAX, -1, "cuda: the device cycle failed");
    return BPX_OK;
}

static bpx_status cuda_handles(void **state, bpx_cycle *cycle, void **context, void **queue,
                               void **device)
{
    bpx_cuda *cu = NULL;
    bpx_status s = cuda_state(state, cycle, &cu);
    if (s != BPX_OK)
        return s;
    if (context)
        *context = NULL;
    if (queue)
        *queue = bpx__cuda_stream(cu);
    if (device)
        *device = NULL;
    return BPX_OK;
}

static const bpx_device_ops cuda_device_ops = {
    .check_input = cuda_check_input,
    .use_input = cuda_use_input,
    .collide = cuda_collide,
    .pairs = cuda_pairs,
    .finish = cuda_finish,
    .handles = cuda_handles,
};

const bpx_backend_impl bpx__cuda_backend = {
    .id = BPX_BACKEND_CUDA,
    .name = "cuda",
    .query = cuda_query,
    .compare = cuda_compare,
    .destroy = cuda_destroy,
    .boxes_set = cuda_boxes_set,
    .device = &cuda_device_ops,
};
