// The cuda backend as the world sees it (compare, query, destroy) and the calls of
// include/bpx/cuda.h. The device side is cycle.cu and kernels.cu, behind cuda_api.h.
#include "bpx/cuda.h"

#include <stdio.h>

#include "core/boxes.h"
#include "core/clock.h"
#include "core/validate.h"
#include "core/world.h"
#include "cuda_api.h"

static bool cuda_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    (void)def;
    return bpx__cuda_probe(reason, detail, size);
}

static bpx_status cuda_state(bpx_world *w, bpx_cuda **out)
{
    if (!w->backend_state) {
        bpx_cuda *cu = NULL;
        bpx_status s = bpx__cuda_open(&cu);
        if (s != BPX_OK)
            return bpx__error(&w->error, s, UINT32_MAX, -1, "cuda: the device could not be set up");
        w->backend_state = cu;
    }
    *out = w->backend_state;
    return BPX_OK;
}

// Names a bad device box the way bpx_world_set_boxes names a bad host box: that one box comes
// back and goes through the host's own check.
static bpx_status report_bad_box(bpx_world *w, const bpx_box *device_boxes, uint32_t index)
{
    bpx_box box;
    if (bpx__cuda_copy_in(&box, device_boxes + index, sizeof box) != BPX_OK)
        return bpx__error(&w->error, BPX_ERR_DEVICE, index, -1, "cuda: device box %u is invalid",
                          index);
    bpx_error detail;
    bpx_status why = bpx__check_boxes(&box, 1, &detail);
    if (why == BPX_OK) // changed since the check ran
        why = BPX_ERR_NOT_FINITE;
    return bpx__error(&w->error, why, index, detail.axis, "device box %u, axis %d: %s", index,
                      detail.axis, bpx_status_string(why));
}

// Names the object whose device centre makes a box that is not finite, as
// bpx_world_update_centres names it: that centre comes back and goes through the host's check.
static bpx_status report_bad_centre(bpx_world *w, const float *device_centres, uint32_t index)
{
    float centre[3];
    if (bpx__cuda_copy_in(centre, device_centres + 3 * (size_t)index, sizeof centre) != BPX_OK)
        return bpx__error(&w->error, BPX_ERR_DEVICE, index, -1, "cuda: device centre %u is invalid",
                          index);
    const float *const minima[3] = {w->minima[0] + index, w->minima[1] + index,
                                    w->minima[2] + index};
    bpx_error detail = {0};
    bpx_status why = bpx__check_centres(centre, minima, 1, &detail);
    if (why == BPX_OK) // changed since the check ran
        why = BPX_ERR_NOT_FINITE;
    return bpx__error(&w->error, why, index, detail.axis, "device centres, object %u, axis %d: %s",
                      index, detail.axis, bpx_status_string(why));
}

// The first bad object of the last cycle that read the caller's device boxes or centres.
static bpx_status report_bad_input(bpx_world *w, bpx_cuda *cu)
{
    uint32_t index = 0;
    bool min_greater = false;
    if (!bpx__cuda_bad_box(cu, &index, &min_greater))
        return bpx__error(&w->error, BPX_ERR_DEVICE, UINT32_MAX, -1,
                          "cuda: the device reported an invalid box it cannot name");
    if (bpx__cuda_device_centres(cu))
        return report_bad_centre(w, bpx__cuda_device_centres(cu), index);
    if (bpx__cuda_device_boxes(cu))
        return report_bad_box(w, bpx__cuda_device_boxes(cu), index);
    // The host's own boxes or centres, checked before they were sent: never seen.
    return bpx__error(&w->error, BPX_ERR_DEVICE, index, -1,
                      "cuda: the device made an invalid box %u of valid host data", index);
}

// Ids added, removed or moved (add/remove/move_boxes) since the input was given change the
// host's boxes alone (and their version): host centres give way to those boxes; the caller's
// device boxes or centres cannot follow (BAD_STATE).
static bpx_status cuda_check_source(bpx_world *w, bpx_cuda *cu)
{
    if (bpx__cuda_input_version(cu) == w->boxes_version)
        return BPX_OK;
    if (bpx__cuda_device_boxes(cu) || bpx__cuda_device_centres(cu))
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "cuda: boxes added, removed or moved by id since the device data was "
                          "set");
    bpx__cuda_use_device_boxes(cu, NULL, 0);
    bpx__cuda_set_input_version(cu, w->boxes_version);
    return BPX_OK;
}

static bpx_status cuda_compare(bpx_world *w)
{
    bpx_cuda *cu = NULL;
    bpx_status s = cuda_state(w, &cu);
    if (s != BPX_OK)
        return s;
    bpx_block *block;
    if ((s = bpx__emitter_one_block(w, &block)) != BPX_OK)
        return s;
    bpx_soa soa = bpx__world_soa(w);
    uint64_t count = 0;
    s = bpx__cuda_finish(cu, NULL); // a device cycle still in flight
    if (s == BPX_OK || s == BPX_ERR_CAPACITY || s == BPX_ERR_NOT_FINITE) {
        if ((s = cuda_check_source(w, cu)) != BPX_OK)
            return s;
        s = bpx__cuda_find(cu, soa.lo, soa.hi, soa.n, &count);
    }
    if (s == BPX_ERR_NOT_FINITE)
        return report_bad_input(w, cu);
    if (s == BPX_OK && !bpx__list_reserve(&block->hits, count))
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %llu pairs", (unsigned long long)count);
    if (s == BPX_OK)
        s = bpx__cuda_read_pairs(cu, block->hits.pairs, count);
    if (s != BPX_OK)
        return bpx__error(&w->error, s, UINT32_MAX, -1, "cuda: the cycle failed on the device");
    block->hits.count = count;
    bpx_cuda_timing t = bpx__cuda_timing(cu);
    block->tests = t.tests;
    w->stats.transfer_in_ns = t.in_ns;
    w->stats.transfer_out_ns = t.out_ns;
    w->stats.device_ns = t.device_ns;
    w->stats.bytes_in = t.bytes_in;
    w->stats.bytes_out = t.bytes_out;
    return BPX_OK;
}

static void cuda_destroy(bpx_world *w)
{
    bpx__cuda_close(w->backend_state);
    w->backend_state = NULL;
}

// New host boxes or centres: the device boxes or centres, if any, are no longer the world's.
// The cycle's centres go to the device's updater (12 bytes an object over the link, not 24),
// unless objects were removed by id (inert in the host's boxes alone) or the device could not
// take them: then the host's boxes, which the world made from the same centres.
static void cuda_boxes_set(bpx_world *w, const float *centres)
{
    bpx_cuda *cu = w->backend_state;
    bool updater = centres && !w->dead;
    if (!cu) {
        if (!updater || bpx__cuda_open(&cu) != BPX_OK)
            return;
        w->backend_state = cu;
    }
    bpx__cuda_set_input_version(cu, w->boxes_version);
    if (updater) {
        const float *const minima[3] = {w->minima[0], w->minima[1], w->minima[2]};
        if (bpx__cuda_use_centres(cu, centres, false, minima, w->extent_count) == BPX_OK)
            return;
    }
    bpx__cuda_use_device_boxes(cu, NULL, 0);
}

const bpx_backend_impl bpx__cuda_backend = {
    .id = BPX_BACKEND_CUDA,
    .name = "cuda",
    .query = cuda_query,
    .compare = cuda_compare,
    .destroy = cuda_destroy,
    .boxes_set = cuda_boxes_set,
};

// ---------------------------------------------------------------------------------------------
// include/bpx/cuda.h

static bpx_status cuda_world(bpx_world *w, bpx_cuda **cu)
{
    if (!w)
        return BPX_ERR_NULL_ARGUMENT;
    bpx__error_clear(&w->error);
    if (w->backend->id != BPX_BACKEND_CUDA)
        return bpx__error(&w->error, BPX_ERR_BACKEND_UNAVAILABLE, UINT32_MAX, -1,
                          "the world's backend is %s, not cuda", w->backend->name);
    return cuda_state(w, cu);
}

bpx_status bpx_cuda_set_boxes_device(bpx_world *w, const bpx_box *boxes, uint32_t n)
{
    bpx_cuda *cu = NULL;
    bpx_status s = cuda_world(w, &cu);
    if (s != BPX_OK)
        return s;
    if (n > BPX_MAX_BOXES)
        return bpx__error(&w->error, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "%u boxes exceed BPX_MAX_BOXES (%u)", n, BPX_MAX_BOXES);
    if (!boxes && n > 0)
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "boxes is NULL");
    if (w->dead)
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "set_boxes_device: the world's boxes are managed by add/remove");
    uint64_t start = bpx__now_ns();
    if ((s = bpx__cuda_finish(cu, NULL)) == BPX_ERR_DEVICE)
        return bpx__error(&w->error, s, UINT32_MAX, -1, "cuda: the last device cycle failed");
    bool bad = false;
    if ((s = bpx__cuda_check_device_boxes(cu, boxes, n, &bad)) != BPX_OK)
        return bpx__error(&w->error, s, UINT32_MAX, -1, "cuda: checking the device boxes failed");
    uint32_t index = 0;
    bool min_greater = false;
    if (bad && bpx__cuda_bad_box(cu, &index, &min_greater))
        return report_bad_box(w, boxes, index);
    // The host's arrays hold n inert boxes, so that nothing sized by n reads past them.
    uint32_t old_n = w->n;
    w->n = 0;
    if (!bpx__boxes_resize(w, n)) {
        w->n = old_n;
        return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                          "no memory for %u boxes", n);
    }
    bpx__cuda_use_device_boxes(cu, boxes, n);
    bpx__cuda_set_input_version(cu, w->boxes_version);
    w->boxes_on_device = true;
    w->stats.update_ns = bpx__now_ns() - start;
    return BPX_OK;
}

bpx_status bpx_cuda_set_centres_device(bpx_world *w, const float *centres, uint32_t n)
{
    bpx_cuda *cu = NULL;
    bpx_status s = cuda_world(w, &cu);
    if (s != BPX_OK)
        return s;
    if (!centres && n > 0)
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "centres is NULL");
    if (!w->extents_loaded || w->dead)
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          w->dead ? "set_centres_device: objects were removed by id"
                                  : "set_centres_device before load_extents");
    if (n != w->extent_count)
        return bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "%u centres for %u loaded extents", n, w->extent_count);
    uint64_t start = bpx__now_ns();
    if ((s = bpx__cuda_finish(cu, NULL)) == BPX_ERR_DEVICE)
        return bpx__error(&w->error, s, UINT32_MAX, -1, "cuda: the last device cycle failed");
    const float *const minima[3] = {w->minima[0], w->minima[1], w->minima[2]};
    bool bad = false;
    if ((s = bpx__cuda_check_device_centres(cu, centres, minima, n, &bad)) != BPX_OK)
        return bpx__error(&w->error, s, UINT32_MAX, -1, "cuda: checking the device centres failed");
    uint32_t index = 0;
    bool min_greater = false;
    if (bad && bpx__cuda_bad_box(cu, &index, &min_greater))
        return report_bad_centre(w, centres, index);
    if ((s = bpx__cuda_use_centres(cu, centres, true, minima, n)) != BPX_OK)
        return bpx__error(&w->error, s, UINT32_MAX, -1, "cuda: the device centres not taken");
    bpx__cuda_set_input_version(cu, w->boxes_version);
    w->boxes_on_device = true; // the host's boxes are the last host centres': no queries
    w->stats.update_ns = bpx__now_ns() - start;
    return BPX_OK;
}

bpx_status bpx_cuda_collide_device(bpx_world *w, void *stream)
{
    bpx_cuda *cu = NULL;
    bpx_status s = cuda_world(w, &cu);
    if (s != BPX_OK)
        return s;
    if (w->category || w->def.track_events)
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "collide_device: filters and events need the host's pairs");
    if ((s = cuda_check_source(w, cu)) != BPX_OK)
        return s;
    bpx_soa soa = bpx__world_soa(w);
    s = bpx__cuda_collide_device(cu, stream, soa.lo, soa.hi, soa.n);
    if (s != BPX_OK)
        return bpx__error(&w->error, s, UINT32_MAX, -1, "cuda: enqueueing the cycle failed");
    w->stats.cycle_count++;
    return BPX_OK;
}

bpx_status bpx_cuda_device_pairs(bpx_world *w, const bpx_pair **pairs,
                                 const unsigned long long **count, size_t *capacity)
{
    bpx_cuda *cu = NULL;
    bpx_status s = cuda_world(w, &cu);
    if (s != BPX_OK)
        return s;
    const bpx_pair *p = NULL;
    const unsigned long long *c = NULL;
    size_t cap = 0;
    bpx__cuda_device_result(cu, &p, &c, &cap);
    if (pairs)
        *pairs = p;
    if (count)
        *count = c;
    if (capacity)
        *capacity = cap;
    return BPX_OK;
}

bpx_status bpx_cuda_finish(bpx_world *w, size_t *count)
{
    bpx_cuda *cu = NULL;
    bpx_status s = cuda_world(w, &cu);
    if (s != BPX_OK)
        return s;
    uint64_t found = 0;
    s = bpx__cuda_finish(cu, &found);
    if (count)
        *count = (size_t)found;
    if (s == BPX_ERR_NOT_FINITE)
        return report_bad_input(w, cu);
    if (s == BPX_ERR_CAPACITY)
        return bpx__error(&w->error, s, UINT32_MAX, -1,
                          "cuda: %llu pairs found, the device buffer held fewer; the next cycle "
                          "has room",
                          (unsigned long long)found);
    if (s != BPX_OK)
        return bpx__error(&w->error, s, UINT32_MAX, -1, "cuda: the device cycle failed");
    w->stats.pair_count = found;
    return BPX_OK;
}

bpx_status bpx_cuda_world_stream(bpx_world *w, void **stream)
{
    bpx_cuda *cu = NULL;
    bpx_status s = stream ? cuda_world(w, &cu) : BPX_ERR_NULL_ARGUMENT;
    if (s != BPX_OK)
        return s;
    *stream = bpx__cuda_stream(cu);
    return BPX_OK;
}
