// The device calls of include/bpx/opencl.h and include/bpx/cuda.h: the world's half. Both
// families are one set of calls over the backend's bpx_device_ops (core/backend.h): this file
// checks the world's own state (objects by id, filters, events, loaded extents) and keeps its
// books (the boxes now on the device, the host's pairs no longer the last cycle's, stats); the
// backend checks, keeps and runs the device's half.
#include "bpx/cuda.h"
#include "bpx/opencl.h"

#include "boxes.h"
#include "clock.h"
#include "objects.h"
#include "validate.h"
#include "world.h"

// The world's device ops when its backend is `backend`; else NULL_ARGUMENT (no world) or
// BACKEND_UNAVAILABLE (named in the world's error).
static bpx_status device_ops(bpx_world *w, bpx_backend backend, const bpx_device_ops **ops)
{
    bpx_status entered = bpx__world_enter(w, "device call");
    if (entered != BPX_OK)
        return entered;
    if (w->backend->id != backend || !w->backend->device)
        return bpx__error(&w->error, BPX_ERR_BACKEND_UNAVAILABLE, UINT32_MAX, -1,
                          "the world's backend is %s, not %s", w->backend->name,
                          bpx_backend_name(backend));
    if (w->boxes64_set)
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "device-resident calls on a world of float64 boxes: use "
                          "bpx_world_set_boxes first, or bpx_world_collide");
    if (bpx__world_periodic(w)) // the images are made on the host
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "device-resident calls on a periodic world: use bpx_world_collide");
    *ops = w->backend->device;
    return BPX_OK;
}

// Boxes (n bpx_box) or centres (n x 3 floats) already in the device's memory, read in place at
// every cycle until the next input.
static bpx_status set_input(bpx_world *w, bpx_backend backend, const char *call, const void *in,
                            uint32_t n, bool centres)
{
    const bpx_device_ops *ops = NULL;
    bpx_status status = device_ops(w, backend, &ops);
    if (status != BPX_OK)
        return status;
    if (!centres && n > BPX_MAX_BOXES)
        return bpx__error(&w->error, BPX_ERR_TOO_MANY_BOXES, UINT32_MAX, -1,
                          "%u boxes exceed BPX_MAX_BOXES (%u)", n, BPX_MAX_BOXES);
    if (!in && n > 0)
        return bpx__error(&w->error, BPX_ERR_NULL_ARGUMENT, UINT32_MAX, -1, "%s is NULL",
                          centres ? "centres" : "boxes");
    if (w->dead)
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "%s: the world's objects are added and removed by id", call);
    if (centres && !w->extents_loaded)
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1, "%s before load_extents",
                          call);
    if (centres && n != w->extent_count)
        return bpx__error(&w->error, BPX_ERR_INVALID_ARGUMENT, UINT32_MAX, -1,
                          "%u centres for %u loaded extents", n, w->extent_count);
    uint64_t start = bpx__now_ns();
    void *input = (void *)(uintptr_t)in; // a cl_mem is retained, a device pointer only read
    bpx_cycle cycle = bpx__world_cycle(w);
    if ((status = ops->check_input(&w->backend_state, &cycle, input, n, centres)) != BPX_OK)
        return status;
    if (!centres) {
        // The host's arrays hold n inert boxes, so that nothing sized by n reads past them.
        uint32_t old_n = w->n;
        w->n = 0;
        if (!bpx__boxes_resize(w, n)) {
            w->n = old_n;
            return bpx__error(&w->error, BPX_ERR_OUT_OF_MEMORY, UINT32_MAX, -1,
                              "no memory for %u boxes", n);
        }
        // As bpx_world_set_boxes: the boxes no longer come from the loaded extents.
        w->extents_loaded = false;
    }
    cycle = bpx__world_cycle(w);
    if ((status = ops->use_input(&w->backend_state, &cycle, input, n, centres)) != BPX_OK)
        return status;
    // With centres, the host's boxes are the last host centres': no queries either way.
    w->boxes_on_device = true;
    w->stats.update_ns = bpx__now_ns() - start;
    return BPX_OK;
}

static bpx_status collide(bpx_world *w, bpx_backend backend, void *stream)
{
    const bpx_device_ops *ops = NULL;
    bpx_status status = device_ops(w, backend, &ops);
    if (status != BPX_OK)
        return status;
    if (bpx__objects_filtering(w) || w->def.track_events)
        return bpx__error(&w->error, BPX_ERR_BAD_STATE, UINT32_MAX, -1,
                          "collide_device: filters and events need the host's pairs "
                          "(bpx_world_collide applies them)");
    bpx_cycle cycle = bpx__world_cycle(w);
    if ((status = ops->collide(&w->backend_state, &cycle, stream)) != BPX_OK)
        return status; // a refused cycle leaves the host's last result as it was
    // The world's host pairs are no longer the last cycle's.
    w->result_valid = false;
    w->merged = false;
    w->events_valid = false;
    w->stats.cycle_count++;
    // Ids removed before this cycle were inert in it: they may be reused (no events to report).
    bpx__objects_after_collide(w, NULL, 0);
    return BPX_OK;
}

static bpx_status device_pairs(bpx_world *w, bpx_backend backend, void **pairs, void **count,
                               size_t *capacity)
{
    const bpx_device_ops *ops = NULL;
    bpx_status status = device_ops(w, backend, &ops);
    if (status != BPX_OK)
        return status;
    bpx_cycle cycle = bpx__world_cycle(w);
    return ops->pairs(&w->backend_state, &cycle, pairs, count, capacity);
}

static bpx_status finish(bpx_world *w, bpx_backend backend, size_t *count)
{
    const bpx_device_ops *ops = NULL;
    if (count)
        *count = 0;
    bpx_status status = device_ops(w, backend, &ops);
    if (status != BPX_OK)
        return status;
    bpx_cycle cycle = bpx__world_cycle(w);
    uint64_t found = 0;
    status = ops->finish(&w->backend_state, &cycle, &found);
    if (count)
        *count = (size_t)found;
    // The stats show a device-resident cycle once finish has waited for it; a refused finish
    // (no such cycle) leaves them as they were.
    const bpx_backend_report *r = &cycle.report;
    if (r->resident)
        w->stats.pair_count = status == BPX_OK ? found : 0;
    if (r->timed) {
        w->stats.pair_tests = r->tests;
        w->stats.transfer_in_ns = r->transfer_in_ns;
        w->stats.transfer_out_ns = r->transfer_out_ns;
        w->stats.device_ns = r->device_ns;
        w->stats.bytes_in = r->bytes_in;
        w->stats.bytes_out = r->bytes_out;
    }
    return status;
}

static bpx_status handles(bpx_world *w, bpx_backend backend, void **context, void **queue,
                          void **device)
{
    const bpx_device_ops *ops = NULL;
    bpx_status status = device_ops(w, backend, &ops);
    if (status != BPX_OK)
        return status;
    bpx_cycle cycle = bpx__world_cycle(w);
    return ops->handles(&w->backend_state, &cycle, context, queue, device);
}

// ---------------------------------------------------------------------------------------------
// include/bpx/opencl.h

bpx_status bpx_opencl_set_boxes_device(bpx_world *w, const void *buffer, uint32_t n)
{
    return set_input(w, BPX_BACKEND_OPENCL, "set_boxes_device", buffer, n, false);
}

bpx_status bpx_opencl_set_centres_device(bpx_world *w, const void *buffer, uint32_t n)
{
    return set_input(w, BPX_BACKEND_OPENCL, "set_centres_device", buffer, n, true);
}

bpx_status bpx_opencl_set_boxes_buffer(bpx_world *w, void *buffer, uint32_t n)
{
    return bpx_opencl_set_boxes_device(w, buffer, n);
}

bpx_status bpx_opencl_set_centres_buffer(bpx_world *w, void *buffer, uint32_t n)
{
    return bpx_opencl_set_centres_device(w, buffer, n);
}

bpx_status bpx_opencl_collide_device(bpx_world *w)
{
    return collide(w, BPX_BACKEND_OPENCL, NULL);
}

bpx_status bpx_opencl_device_pairs(bpx_world *w, void **pairs, void **count, size_t *capacity)
{
    return device_pairs(w, BPX_BACKEND_OPENCL, pairs, count, capacity);
}

bpx_status bpx_opencl_finish(bpx_world *w, size_t *count)
{
    return finish(w, BPX_BACKEND_OPENCL, count);
}

bpx_status bpx_opencl_world_handles(bpx_world *w, void **context, void **queue, void **device)
{
    return handles(w, BPX_BACKEND_OPENCL, context, queue, device);
}

// ---------------------------------------------------------------------------------------------
// include/bpx/cuda.h

bpx_status bpx_cuda_set_boxes_device(bpx_world *w, const void *boxes, uint32_t n)
{
    return set_input(w, BPX_BACKEND_CUDA, "set_boxes_device", boxes, n, false);
}

bpx_status bpx_cuda_set_centres_device(bpx_world *w, const void *centres, uint32_t n)
{
    return set_input(w, BPX_BACKEND_CUDA, "set_centres_device", centres, n, true);
}

bpx_status bpx_cuda_collide_device(bpx_world *w, void *stream)
{
    return collide(w, BPX_BACKEND_CUDA, stream);
}

bpx_status bpx_cuda_device_pairs(bpx_world *w, void **pairs, void **count, size_t *capacity)
{
    return device_pairs(w, BPX_BACKEND_CUDA, pairs, count, capacity);
}

bpx_status bpx_cuda_finish(bpx_world *w, size_t *count)
{
    return finish(w, BPX_BACKEND_CUDA, count);
}

bpx_status bpx_cuda_world_stream(bpx_world *w, void **stream)
{
    if (!stream)
        return BPX_ERR_NULL_ARGUMENT;
    return handles(w, BPX_BACKEND_CUDA, NULL, stream, NULL);
}
