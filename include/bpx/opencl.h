// bpx: broad-phase collision detection. SPDX-License-Identifier: MIT
//
// The OpenCL backend's own calls: listing devices, and handing the world boxes or centres that
// are already on the device. The backend itself is chosen like any other (bpx_world_def.backend =
// BPX_BACKEND_OPENCL) and configured with the opencl_* fields of bpx_world_def. Every function
// here exists in every build; without OpenCL support they return BPX_ERR_BACKEND_UNAVAILABLE.
// OpenCL handles cross this header as void pointers, so including it needs no OpenCL headers.
#pragma once

#include "bpx.h"

#ifdef __cplusplus
extern "C" {
#endif

/// One OpenCL device, as bpx_opencl_devices lists it.
typedef struct bpx_opencl_device {
    int platform;           ///< 0-based platform number (clGetPlatformIDs order)
    int device;             ///< 0-based device number within the platform
    int type;               ///< BPX_OPENCL_GPU, BPX_OPENCL_CPU or BPX_OPENCL_ACCELERATOR (0: other)
    int compute_units;      ///< CL_DEVICE_MAX_COMPUTE_UNITS
    uint64_t global_memory; ///< bytes of global memory
    char platform_name[64];
    char name[96];
    char version[64]; ///< CL_DEVICE_VERSION, e.g. "OpenCL 3.0 PoCL ..."
} bpx_opencl_device;

/// Lists every OpenCL device of every platform into out[0 .. capacity) and the total in *count
/// (which may exceed capacity: call with capacity 0 to size the array).
/// Errors: NULL_ARGUMENT (count NULL, or out NULL with capacity > 0), BACKEND_UNAVAILABLE (no
/// OpenCL in this build, or no platform: *count is 0), DEVICE (the platform layer failed).
BPX_API bpx_status bpx_opencl_devices(bpx_opencl_device *out, int capacity, int *count);

/// The OpenCL objects of a world using the opencl backend: its cl_context, cl_command_queue
/// (in order) and cl_device_id, for a caller that makes boxes on the device. The world owns them;
/// they are valid until bpx_world_destroy. Any pointer may be NULL.
/// Errors: NULL_ARGUMENT (world NULL), BACKEND_UNAVAILABLE (the world's backend is not opencl),
/// DEVICE or OUT_OF_MEMORY (the world's device state could not be made).
BPX_API bpx_status bpx_opencl_world_handles(bpx_world *world, void **context, void **queue,
                                            void **device);

/// General mode with the boxes already on the device: `buffer` is a cl_mem in the world's
/// context holding n bpx_box (24 bytes each, same layout as on the host). Nothing crosses the
/// link but a validity check's answer: the boxes are checked on the device, and an invalid box
/// is reported like bpx_world_set_boxes does (NOT_FINITE or MIN_GREATER_THAN_MAX, naming the
/// first bad box; the axis is that box's first bad one). The world retains the buffer and reads
/// it at each bpx_world_collide* until the next set_boxes / load_extents / update_centres /
/// set_boxes_buffer; the caller may change its contents between cycles (on the world's queue, or
/// finished before the collide call) but must not make the boxes invalid. Until then queries
/// (include/bpx/query.h) are refused with BAD_STATE: the host has no copy of these boxes.
/// Errors: NULL_ARGUMENT, TOO_MANY_BOXES, BACKEND_UNAVAILABLE (not an opencl world),
/// INVALID_ARGUMENT (buffer smaller than n boxes or from another context), NOT_FINITE,
/// MIN_GREATER_THAN_MAX, DEVICE, DEVICE_MEMORY, OUT_OF_MEMORY. On error the world is unchanged.
BPX_API bpx_status bpx_opencl_set_boxes_buffer(bpx_world *world, void *buffer, uint32_t n);

/// The paper's two-phase mode with the centres already on the device: `buffer` is a cl_mem in
/// the world's context holding n centres (x, y, z floats, 12 bytes each, the layout
/// bpx_world_update_centres takes), n the count given to bpx_world_load_extents. Each cycle the
/// device's updater makes the boxes from them and the minima it keeps (min = centre + minimum,
/// max = centre - minimum, single precision, the host's arithmetic): nothing crosses the link
/// for the boxes. They are checked now, on the device: a centre whose box is not finite is
/// reported as bpx_world_update_centres reports it (NOT_FINITE, naming the first such object
/// and its axis), and only that centre crosses the link.
/// Ownership and queues: the world retains the buffer (the caller may release its own
/// reference) and reads it in place at each bpx_world_collide* until the next set_boxes /
/// load_extents / update_centres / set_boxes_buffer / set_centres_buffer. The caller may change
/// the centres between cycles: with commands on the world's queue (bpx_opencl_world_handles;
/// in order, so the next collide sees them), or on another queue finished before the collide
/// call. Centres changed later are not checked again: they must keep every box finite. Until
/// then queries (include/bpx/query.h) are refused with BAD_STATE, as with set_boxes_buffer.
/// Errors: NULL_ARGUMENT, BACKEND_UNAVAILABLE (not an opencl world, or a device without
/// single-precision subnormals, whose updater would round differently from the host's),
/// BAD_STATE (no extents loaded, or objects removed by id), INVALID_ARGUMENT (n other than the
/// loaded count, a buffer smaller than n centres or from another context), NOT_FINITE, DEVICE,
/// DEVICE_MEMORY, OUT_OF_MEMORY. On error the world is unchanged.
BPX_API bpx_status bpx_opencl_set_centres_buffer(bpx_world *world, void *buffer, uint32_t n);

#ifdef __cplusplus
}
#endif
