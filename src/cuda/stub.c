// The CUDA calls in a build without CUDA: they exist, and say so.
#include "bpx/cuda.h"

bpx_status bpx_cuda_set_boxes_device(bpx_world *world, const bpx_box *boxes, uint32_t n)
{
    (void)boxes, (void)n;
    return world ? BPX_ERR_BACKEND_UNAVAILABLE : BPX_ERR_NULL_ARGUMENT;
}

bpx_status bpx_cuda_set_centres_device(bpx_world *world, const float *centres, uint32_t n)
{
    (void)centres, (void)n;
    return world ? BPX_ERR_BACKEND_UNAVAILABLE : BPX_ERR_NULL_ARGUMENT;
}

bpx_status bpx_cuda_collide_device(bpx_world *world, void *stream)
{
    (void)stream;
    return world ? BPX_ERR_BACKEND_UNAVAILABLE : BPX_ERR_NULL_ARGUMENT;
}

bpx_status bpx_cuda_device_pairs(bpx_world *world, const bpx_pair **pairs,
                                 const unsigned long long **count, size_t *capacity)
{
    (void)pairs, (void)count, (void)capacity;
    return world ? BPX_ERR_BACKEND_UNAVAILABLE : BPX_ERR_NULL_ARGUMENT;
}

bpx_status bpx_cuda_finish(bpx_world *world, size_t *count)
{
    (void)count;
    return world ? BPX_ERR_BACKEND_UNAVAILABLE : BPX_ERR_NULL_ARGUMENT;
}

bpx_status bpx_cuda_world_stream(bpx_world *world, void **stream)
{
    (void)stream;
    return world ? BPX_ERR_BACKEND_UNAVAILABLE : BPX_ERR_NULL_ARGUMENT;
}
