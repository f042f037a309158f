// The OpenCL calls in a build without OpenCL: they exist, and say so. (The world's device calls
// are core/device.c's: on a world of another backend they say BACKEND_UNAVAILABLE.)
#include "bpx/opencl.h"

bpx_status bpx_opencl_devices(bpx_opencl_device *out, int capacity, int *count)
{
    if (!count || (!out && capacity > 0))
        return BPX_ERR_NULL_ARGUMENT;
    *count = 0;
    return BPX_ERR_BACKEND_UNAVAILABLE;
}
