// bpx OpenCL kernels: the updater (boxes onto the device as keys). SPDX-License-Identifier: MIT
//
// The program is twin.h followed by the .cl files, in the order src/opencl/opencl.cmake lists
// them. Build options define BPX_TILE (the comparator's tile width, this backend's m).
#pragma OPENCL FP_CONTRACT OFF

#ifdef BPX_FORCE_BUILD_ERROR
#error "build failure requested by BPX_FORCE_BUILD_ERROR (test of the error path)"
#endif

/// The paper's updater: stored origin-centred minima + this cycle's centres (3 floats per object,
/// the only per-cycle upload) -> keys of boxes [first, first + count) into lo/hi at 0..count-1.
/// Work-items from count to padded write padding boxes.
__kernel void bpx_update(__global const float *centres, __global const float *minima,
                         uint stride, uint first, uint count, uint padded,
                         __global uint4 *lo, __global uint4 *hi)
{
    uint k = get_global_id(0);
    if (k >= padded)
        return;
    if (k < count) {
        bpx_update_keys(centres, minima, stride, first + k, (__global uint *)(lo + k),
                        (__global uint *)(hi + k));
    } else {
        lo[k] = (uint4)(BPX_KEY_PAD_LO, BPX_KEY_PAD_LO, BPX_KEY_PAD_LO, 0u);
        hi[k] = (uint4)(BPX_KEY_PAD_HI, BPX_KEY_PAD_HI, BPX_KEY_PAD_HI, 0u);
    }
}

/// General mode: boxes [first, first + count) -> keys at 0..count-1. Box k's six floats start
/// at boxes[k * box_stride] and lie `plane` apart: (6, 1) for an array of bpx_box (a caller's
/// device buffer), (1, plane length) for the six planes the host uploads.
__kernel void bpx_convert(__global const float *boxes, uint box_stride, uint plane, uint first,
                          uint count, uint padded, __global uint4 *lo, __global uint4 *hi)
{
    uint k = get_global_id(0);
    if (k >= padded)
        return;
    if (k < count) {
        bpx_box_keys(boxes + ((ulong)first + k) * box_stride, plane, (__global uint *)(lo + k),
                     (__global uint *)(hi + k));
    } else {
        lo[k] = (uint4)(BPX_KEY_PAD_LO, BPX_KEY_PAD_LO, BPX_KEY_PAD_LO, 0u);
        hi[k] = (uint4)(BPX_KEY_PAD_HI, BPX_KEY_PAD_HI, BPX_KEY_PAD_HI, 0u);
    }
}

/// Checks n boxes in a caller's buffer: result[0] becomes the smallest index of an invalid box
/// (it must start at 0xFFFFFFFF); result[1] / result[2] are filled by the host afterwards.
__kernel void bpx_validate(__global const float *boxes, uint n, __global volatile uint *result)
{
    uint k = get_global_id(0);
    if (k >= n)
        return;
    int axis = 0;
    if (bpx_box_problem(boxes + 6 * (ulong)k, &axis))
        atomic_min(&result[0], k);
}

/// Checks the boxes that n centres of a caller's buffer make with the stored minima (three
/// planes of `stride` floats): result[0] becomes the smallest object whose box is not finite
/// (it must start at 0xFFFFFFFF).
__kernel void bpx_validate_centres(__global const float *centres, __global const float *minima,
                                   uint stride, uint n, __global volatile uint *result)
{
    uint k = get_global_id(0);
    if (k < n && bpx_centre_problem(centres, minima, stride, k) >= 0)
        atomic_min(&result[0], k);
}
