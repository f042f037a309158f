// The OpenCL calls in a build without OpenCL: they exist, and say so.
#include "bpx/opencl.h"

bpx_status bpx_opencl_devices(bpx_opencl_device *out, int capacity, int *count)
{
    if (!count || (!out && capacity > 0))
        return BPX_ERR_NULL_ARGUMENT;
    *count = 0;
    return BPX_ERR_BACKEND_UNAVAILABLE;
}

bpx_status bpx_opencl_world_handles(bpx_world *world, void **context, void **queue, void **device)
{
    (void)context, (void)queue, (void)device;
    return world ? BPX_ERR_BACKEND_UNAVAILABLE : BPX_ERR_NULL_ARGUMENT;
}

bpx_status bpx_opencl_set_boxes_buffer(bpx_world *world, void *buffer, uint32_t n)
{
    (void)buffer, (void)n;
    return world ? BPX_ERR_BACKEND_UNAVAILABLE : BPX_ERR_NULL_ARGUMENT;
}

bpx_status bpx_opencl_set_centres_buffer(bpx_world *world, void *buffer, uint32_t n)
{
    (void)buffer, (void)n;
    return world ? BPX_ERR_BACKEND_UNAVAILABLE : BPX_ERR_NULL_ARGUMENT;
}

bpx_status bpx_opencl_collide_device(bpx_world *world)
{
    return world ? BPX_ERR_BACKEND_UNAVAILABLE : BPX_ERR_NULL_ARGUMENT;
}

bpx_status bpx_opencl_device_pairs(bpx_world *world, void **pairs_buffer, void **count_buffer,
                                   size_t *capacity)
{
    (void)pairs_buffer, (void)count_buffer, (void)capacity;
    return world ? BPX_ERR_BACKEND_UNAVAILABLE : BPX_ERR_NULL_ARGUMENT;
}

bpx_status bpx_opencl_finish(bpx_world *world, size_t *count)
{
    if (count)
        *count = 0;
    return world ? BPX_ERR_BACKEND_UNAVAILABLE : BPX_ERR_NULL_ARGUMENT;
}
