// bpx: broad-phase collision detection. SPDX-License-Identifier: MIT
//
// The cuda backend's own calls: cycles whose boxes and pairs stay in GPU memory. The backend is
// chosen like any other (bpx_world_def.backend = BPX_BACKEND_CUDA) and runs on CUDA device 0;
// bpx_world_collide* work as on every backend (boxes in from the host, pairs out to the host).
// Every function here exists in every build; without CUDA they return BACKEND_UNAVAILABLE.
// CUDA types cross this header as void pointers (a cudaStream_t, device memory), so it needs no
// CUDA headers. The device calls are named, typed and ordered as include/bpx/opencl.h's.
//
// Ownership and synchronisation:
// - The world owns a non-blocking stream (bpx_cuda_world_stream) and its device buffers; they
//   live until bpx_world_destroy. Pointers it hands out stay valid until the next call that
//   changes the world.
// - bpx_cuda_collide_device enqueues the whole cycle on the stream you pass (or the world's) and
//   returns without waiting: kernels you enqueue after it on that stream see the pairs and their
//   count. Work on other streams must wait for it (an event) before reading them.
// - The pairs, the count and the world's other buffers stay yours to read, on that stream, until
//   the world's next call that enqueues device work (bpx_cuda_collide_device on any stream,
//   bpx_world_collide*, bpx_cuda_set_boxes_device / _set_centres_device,
//   bpx_world_update_centres): that call makes its own stream wait, on the device (an event
//   recorded on the cycle's stream when the call is made; no host wait), for everything enqueued
//   on the cycle's stream by then, so your kernels and copies queued behind the cycle finish
//   reading before anything is rewritten. Hence: (1) keep that stream alive until then (or until
//   bpx_world_destroy); (2) work on a third stream that reads the pairs is not waited for: make
//   the cycle's stream wait for it (an event) before the world's next call; (3) work you enqueue
//   after the next call reads that call's buffers, not this cycle's.
// - Device boxes are read in place at each cycle: change them between cycles on the stream the
//   cycle runs on, or finish that work before the call. The world's stream is non-blocking: it
//   does not wait for the legacy default stream, where a plain cudaMemcpy from pageable memory
//   may still be copying when it returns (synchronise the device or that stream first).
// - A world is used by one host thread at a time, like every world.
#pragma once

#include "bpx.h"

#ifdef __cplusplus
extern "C" {
#endif

/// General mode with the boxes already in device memory: `boxes` points to n bpx_box (24 bytes
/// each, as on the host) in memory of CUDA device 0. They are checked now (one small read comes
/// back) and an invalid box is reported as bpx_world_set_boxes reports it (NOT_FINITE or
/// MIN_GREATER_THAN_MAX, naming the first bad box and its axis). The world then reads them in
/// place at every collide until the next set_boxes / load_extents / update_centres /
/// bpx_cuda_set_boxes_device; a box that turns invalid later is reported by the cycle that
/// reads it (bpx_world_collide, or bpx_cuda_finish after bpx_cuda_collide_device). Until then
/// queries (include/bpx/query.h) are refused with BAD_STATE: the host has no copy of the boxes.
/// Errors: NULL_ARGUMENT, TOO_MANY_BOXES, BACKEND_UNAVAILABLE (not a cuda world), BAD_STATE
/// (boxes added and removed one by one), NOT_FINITE, MIN_GREATER_THAN_MAX, DEVICE,
/// DEVICE_MEMORY, OUT_OF_MEMORY. On error the world is unchanged.
BPX_API bpx_status bpx_cuda_set_boxes_device(bpx_world *world, const void *boxes, uint32_t n);

/// The paper's two-phase mode with the centres already in device memory: `centres` points to n
/// centres (x, y, z floats, 12 bytes each, the layout bpx_world_update_centres takes) in memory
/// of CUDA device 0, n the count given to bpx_world_load_extents. Each cycle the device's updater
/// makes the boxes from them and the loaded extents (min = centre + minimum, max = centre -
/// minimum, single precision: the host's arithmetic, bit for bit), reading the centres in place:
/// nothing crosses the link for the boxes. They are checked now: a centre whose box is not
/// finite is reported as bpx_world_update_centres reports it (NOT_FINITE, naming the first such
/// object and its axis). The world reads them at every collide until the next set_boxes /
/// load_extents / update_centres / bpx_cuda_set_boxes_device / bpx_cuda_set_centres_device;
/// change them between cycles as for device boxes (above). A centre that makes a box not finite
/// later is reported by the cycle that reads it. Queries are refused (BAD_STATE) meanwhile.
/// (bpx_world_update_centres on a cuda world sends the host's centres, 12 bytes an object, to
/// the same updater, unless objects were removed by id.)
/// Errors: NULL_ARGUMENT, BACKEND_UNAVAILABLE (not a cuda world), BAD_STATE (no extents loaded,
/// or objects removed by id), INVALID_ARGUMENT (n other than the loaded count), NOT_FINITE,
/// DEVICE, DEVICE_MEMORY. On error the world is unchanged.
BPX_API bpx_status bpx_cuda_set_centres_device(bpx_world *world, const void *centres, uint32_t n);
/// One cycle that never leaves the device: enqueued on `stream` (a cudaStream_t; NULL for the
/// world's own) and returned from at once. The pairs, sorted by (i, j), and their count stay in
/// device memory (bpx_cuda_device_pairs). The boxes are the device boxes, or those the device's
/// updater makes from the device centres, else the world's current host boxes (or host centres),
/// sent first. No host round trip happens inside the cycle: the count
/// follows the pairs into pinned host memory, and the next call reads it to size the buffer.
/// Errors (of the enqueueing; the cycle's own outcome is bpx_cuda_finish's): NULL_ARGUMENT,
/// BACKEND_UNAVAILABLE, DEVICE, DEVICE_MEMORY, OUT_OF_MEMORY (pinned host memory). Filters
/// (bpx_world_set_filters) and events are not applied to device-resident pairs: BAD_STATE when
/// either is in use.
BPX_API bpx_status bpx_cuda_collide_device(bpx_world *world, void *stream);

/// The last device cycle's pairs and count, in device memory: *pairs (bpx_pair, two uint32 each)
/// holds *capacity pairs, of which the first count (the unsigned long long at *count) are the
/// cycle's when count <= capacity. The capacity is that cycle's room (its last count and half
/// more), so it changes from cycle to cycle: ask again after each bpx_cuda_collide_device. When
/// count > capacity the buffer was too small, its content is not the pair set, bpx_cuda_finish
/// says CAPACITY with the count, and the next cycle has room for it. The world's host pairs
/// (bpx_world_pairs) are no longer the last cycle's after bpx_cuda_collide_device.
/// Any pointer may be NULL. Errors: NULL_ARGUMENT, BACKEND_UNAVAILABLE.
BPX_API bpx_status bpx_cuda_device_pairs(bpx_world *world, void **pairs, void **count,
                                         size_t *capacity);

/// Waits for the last bpx_cuda_collide_device and tells how it went: OK with *count (may be
/// NULL) pairs; CAPACITY with *count the pairs found (the buffer was too small; run the cycle
/// again); NOT_FINITE or MIN_GREATER_THAN_MAX when a device box was invalid (the world's error
/// names it); DEVICE when the device failed. OK at once when no device cycle is pending. Sets
/// bpx_world_stats' pair_count (0 unless OK).
BPX_API bpx_status bpx_cuda_finish(bpx_world *world, size_t *count);

/// The world's CUDA stream (a cudaStream_t), for the caller's kernels that feed or read it.
/// Errors: NULL_ARGUMENT, BACKEND_UNAVAILABLE, DEVICE.
BPX_API bpx_status bpx_cuda_world_stream(bpx_world *world, void **stream);

#ifdef __cplusplus
}
#endif
