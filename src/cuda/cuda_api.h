// The cuda backend's device side (src/cuda/*.cu) as seen from C (src/cuda/backend.c): one
// context per world, holding its stream, its device buffers and its pinned staging memory.
// Every call returns a bpx_status; messages go to the logger (device errors name the CUDA call).
#pragma once

#include "bpx/bpx.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct bpx_cuda bpx_cuda;

/// Device-clock times and bytes of the last cycle, as bpx_cycle_stats reports them.
typedef struct bpx_cuda_timing {
    uint64_t in_ns, device_ns, out_ns;
    uint64_t bytes_in, bytes_out;
    uint64_t tests; ///< box-pair tests: brute n(n-1)/2, the tree path's leaf tests
    bool tree;      ///< the last cycle ran the tree path (else the small brute force)
} bpx_cuda_timing;

/// Whether a CUDA device can run this build's kernels. On false *reason says why (static text);
/// detail receives the device's name and compute capability. Probes once per process.
bool bpx__cuda_probe(const char **reason, char *detail, size_t size);

/// Makes a context on the default device (0): a non-blocking stream and no buffers yet.
bpx_status bpx__cuda_open(bpx_cuda **out);
void bpx__cuda_close(bpx_cuda *cu);

/// Host-in, host-out: sends the n boxes (SoA, one array per axis and side; ignored when the
/// context reads device boxes), finds the pairs on the device in (i, j) order, and returns their
/// count; the pairs wait for bpx__cuda_read_pairs. Cycles of the same n allocate nothing after
/// the first ones. With device boxes that turned invalid: NOT_FINITE (see bpx__cuda_bad_box).
bpx_status bpx__cuda_find(bpx_cuda *cu, const float *const lo[3], const float *const hi[3],
                          uint32_t n, uint64_t *count);
/// Copies the count pairs of the last bpx__cuda_find into out and completes its timing.
bpx_status bpx__cuda_read_pairs(bpx_cuda *cu, bpx_pair *out, uint64_t count);

/// Boxes in device memory (include/bpx/cuda.h): checks n boxes at once (*bad: one is invalid;
/// bpx__cuda_bad_box says which), without keeping them.
bpx_status bpx__cuda_check_device_boxes(bpx_cuda *cu, const bpx_box *boxes, uint32_t n, bool *bad);
/// From now on each cycle reads these boxes in place (NULL: the host's boxes again, and the
/// minima are sent again before the next centres: load_extents may have changed them).
void bpx__cuda_use_device_boxes(bpx_cuda *cu, const bpx_box *boxes, uint32_t n);
/// The paper's two-phase mode: from now on each cycle's boxes are made on the device from n
/// centres (x, y, z each) and the loaded minima (three arrays, sent once per load_extents). Host
/// centres (on_device false) are copied now, into pinned memory, and cross the link at each
/// cycle: 12 bytes an object instead of a box's 24. Device centres are read in place at every
/// cycle. On error the context reads what it read before.
bpx_status bpx__cuda_use_centres(bpx_cuda *cu, const float *centres, bool on_device,
                                 const float *const minima[3], uint32_t n);
/// Centres in device memory: checks the boxes that n of them make with the minima at once (*bad:
/// one is not finite; bpx__cuda_bad_box says which object), without keeping them.
bpx_status bpx__cuda_check_device_centres(bpx_cuda *cu, const float *centres,
                                          const float *const minima[3], uint32_t n, bool *bad);
/// The first invalid box (or object, for centres) of the last check or cycle that read the
/// caller's device data, if any.
bool bpx__cuda_bad_box(const bpx_cuda *cu, uint32_t *index, bool *min_greater);

/// One cycle whose pairs and count stay in device memory, enqueued on stream (NULL: the
/// context's own); host boxes (lo, hi, n) are sent first unless device boxes are in use. No
/// host round trip: the count follows into pinned memory, read by the next call.
bpx_status bpx__cuda_collide_device(bpx_cuda *cu, void *stream, const float *const lo[3],
                                    const float *const hi[3], uint32_t n);
/// Waits for the last device cycle: OK, CAPACITY (count > the buffer; the next cycle grows it)
/// or NOT_FINITE (a device box turned invalid). *count (may be NULL) gets the pairs found.
bpx_status bpx__cuda_finish(bpx_cuda *cu, uint64_t *count);
/// The device buffers of the last cycle's pairs and count.
void bpx__cuda_device_result(const bpx_cuda *cu, const bpx_pair **pairs,
                             const unsigned long long **count, size_t *capacity);

/// A few bytes from device memory (one box or centre, to name a bad one); the device boxes and
/// the device centres in use (or NULL).
bpx_status bpx__cuda_copy_in(void *out, const void *device, size_t bytes);
const bpx_box *bpx__cuda_device_boxes(const bpx_cuda *cu);
const float *bpx__cuda_device_centres(const bpx_cuda *cu);

bpx_cuda_timing bpx__cuda_timing(const bpx_cuda *cu);
/// The stream the context works on (a cudaStream_t).
void *bpx__cuda_stream(const bpx_cuda *cu);
/// The world's boxes_version when the context's input (boxes, centres) was last given: a later
/// one means ids were added, removed or moved since (the host's boxes alone changed).
uint64_t bpx__cuda_input_version(const bpx_cuda *cu);
void bpx__cuda_set_input_version(bpx_cuda *cu, uint64_t version);

#ifdef __cplusplus
}
#endif
