// bpx: broad-phase collision detection. SPDX-License-Identifier: MIT
//
// The OpenCL backend's own calls: listing devices, handing the world boxes or centres that are
// already on the device, and cycles whose pairs stay there. The backend itself is chosen like any
// other (bpx_world_def.backend = BPX_BACKEND_OPENCL) and configured with the opencl_* fields of
// bpx_world_def. Every function here exists in every build; without OpenCL support they return
// BPX_ERR_BACKEND_UNAVAILABLE. OpenCL handles cross this header as void pointers, so including it
// needs no OpenCL headers. The device calls are named, typed and ordered as include/bpx/cuda.h's:
// set_boxes_device, set_centres_device, collide_device, device_pairs, finish.
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
/// set_boxes_device; the caller may change its contents between cycles (on the world's queue, or
/// finished before the collide call) but must not make the boxes invalid. Until then queries
/// (include/bpx/query.h) are refused with BAD_STATE: the host has no copy of these boxes.
/// Errors: NULL_ARGUMENT, TOO_MANY_BOXES, BACKEND_UNAVAILABLE (not an opencl world),
/// INVALID_ARGUMENT (buffer smaller than n boxes or from another context), NOT_FINITE,
/// MIN_GREATER_THAN_MAX, DEVICE, DEVICE_MEMORY, OUT_OF_MEMORY. On error the world is unchanged.
BPX_API bpx_status bpx_opencl_set_boxes_device(bpx_world *world, const void *buffer, uint32_t n);

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
/// load_extents / update_centres / set_boxes_device / set_centres_device. The caller may change
/// the centres between cycles: with commands on the world's queue (bpx_opencl_world_handles;
/// in order, so the next collide sees them), or on another queue finished before the collide
/// call. Centres changed later are not checked again: they must keep every box finite. Until
/// then queries (include/bpx/query.h) are refused with BAD_STATE, as with set_boxes_device.
/// Errors: NULL_ARGUMENT, BACKEND_UNAVAILABLE (not an opencl world, or a device without
/// single-precision subnormals, whose updater would round differently from the host's),
/// BAD_STATE (no extents loaded, or objects removed by id), INVALID_ARGUMENT (n other than the
/// loaded count, a buffer smaller than n centres or from another context), NOT_FINITE, DEVICE,
/// DEVICE_MEMORY, OUT_OF_MEMORY. On error the world is unchanged.
BPX_API bpx_status bpx_opencl_set_centres_device(bpx_world *world, const void *buffer, uint32_t n);

/// The names these calls had before they were named as cuda.h's (same calls).
BPX_API bpx_status bpx_opencl_set_boxes_buffer(bpx_world *world, void *buffer, uint32_t n);
BPX_API bpx_status bpx_opencl_set_centres_buffer(bpx_world *world, void *buffer, uint32_t n);

// ---------------------------------------------------------------------------------------------
// Cycles that never leave the device
//
// bpx_opencl_collide_device runs the cycle and leaves its pairs, sorted by (i, j), and their
// count in device memory for the caller's next kernel; with set_boxes_device or
// set_centres_device nothing crosses the link but the 8-byte count.
//
// Ownership, queues and synchronisation:
// - The world owns the pair buffer and the count buffer (cl_mem in the world's context). They
//   are handed out without a reference: valid until the next bpx_opencl_collide_device,
//   bpx_world_collide* or bpx_world_destroy, which may replace or overwrite them (retain one to
//   keep the object longer; its content is the world's to change). Call
//   bpx_opencl_device_pairs after each bpx_opencl_collide_device.
// - The cycle runs on the world's in-order command queue (bpx_opencl_world_handles): commands
//   the caller enqueues there after bpx_opencl_collide_device see the pairs and the count; the
//   next cycle, enqueued after them, overwrites the buffers only when they are done. Work on
//   another queue must wait for the cycle first (an event of a marker enqueued on the world's
//   queue), and must be done before the next cycle is enqueued.
// - No host round trip inside the cycle: buffers are sized from the previous cycle's count
//   before anything is enqueued, and the count follows the pairs to pinned host memory. The
//   next bpx_opencl_collide_device waits for that copy (the previous cycle only, not the
//   caller's commands behind it); so do bpx_opencl_finish, bpx_world_collide*,
//   bpx_world_update_centres and bpx_opencl_set_*_device. Nothing else waits.
// - Every path runs device-resident: brute force (the small-set kernel and the tiled one), the
//   tree, and the sweep when forced. The tree and the sweep sort the whole room (their pairs
//   past the count are padding); when their buffers pass the memory limit, brute force takes
//   the cycle, as on the host. Boxes streamed in blocks (opencl_block_boxes below n, or more
//   boxes than fit under the memory limit) are refused: BAD_STATE.
// - A world is used by one host thread at a time, like every world.

/// Enqueues one whole cycle on the world's queue and returns without waiting for it. The boxes
/// are the world's current ones (from the host, from centres, or from a device buffer).
/// Errors (of the enqueueing; the cycle's outcome is bpx_opencl_finish's): NULL_ARGUMENT,
/// BACKEND_UNAVAILABLE (not an opencl world), BAD_STATE (filters or events in use: they need
/// the host's pairs; boxes streamed in blocks; a device buffer in a world with objects removed
/// by id), DEVICE_MEMORY (room for the pairs passes the memory limit), DEVICE, OUT_OF_MEMORY.
/// The world's host pairs (bpx_world_pairs) are no longer the last cycle's.
BPX_API bpx_status bpx_opencl_collide_device(bpx_world *world);

/// The last device-resident cycle's buffers: *pairs (a cl_mem) holds *capacity pairs (bpx_pair,
/// two uint32 each), of which the first count are the cycle's when count <= capacity, count
/// being the cl_ulong at the start of *count (a cl_mem). When count >
/// capacity the room was short: the buffer is not the pair set, bpx_opencl_finish says
/// CAPACITY, and the next cycle has room. Does not wait. Any pointer may be NULL.
/// Errors: NULL_ARGUMENT, BACKEND_UNAVAILABLE, BAD_STATE (no bpx_opencl_collide_device since
/// the world was made or since its last bpx_world_collide*).
BPX_API bpx_status bpx_opencl_device_pairs(bpx_world *world, void **pairs, void **count,
                                           size_t *capacity);

/// Waits for the last bpx_opencl_collide_device and tells how it went, as often as asked until
/// the next cycle: OK with *count (may be NULL) pairs; CAPACITY with *count the pairs found
/// (the room was short; run the cycle again: it has room); TOO_MANY_PAIRS (2^32 pairs or more);
/// DEVICE (the device failed). Also sets bpx_world_stats (pair_count, the transfer and device
/// times, bytes in and out; pair_tests for brute force only): the stats show a device-resident
/// cycle once this call has waited for it (a refused call leaves them as they were).
/// Errors: NULL_ARGUMENT, BACKEND_UNAVAILABLE, BAD_STATE (no device-resident cycle, as above).
BPX_API bpx_status bpx_opencl_finish(bpx_world *world, size_t *count);

#ifdef __cplusplus
}
#endif
