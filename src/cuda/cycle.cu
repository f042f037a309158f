// The cuda backend's cycle: a context per world (stream, events, its buffers: context.h and
// buffers.cu) and the order of copies, kernels and sorts (kernels.cu). SPDX-License-Identifier: MIT
//
// Buffers only grow, geometrically, so cycles at a steady n allocate nothing. Sorting is CUB's
// (the toolkit's CCCL), behind kernels.cu like every launch: the Morton keys with the box ids,
// then the pair keys. This file itself holds no device code: the fake device
// (test/fake_cuda/) runs it as it is, with host loops for the kernels and sorts.
#include <cuda_runtime_api.h>

#include <cstddef>
#include <cstdio>
#include <cstring>
#include <pthread.h>

#include "context.h"

extern "C" {
#include "core/alloc.h"
#include "core/log.h"
}

using namespace bpx_cuda_host;

namespace {

// Boxes up to this many go through pinned staging in one copy (cheap to pack on the host);
// beyond it each SoA array is copied straight from the world's memory.
constexpr uint32_t staged_max = 65536;

// Work about to be enqueued on `s` runs after everything on the stream of the world's last work,
// as it stands now: after a device-resident cycle that is the caller's stream, with the caller's
// kernels and copies that read the pairs, the count and the keys enqueued behind the cycle (not
// just the cycle, which event_out ends). A next cycle on another stream, or a host cycle on the
// world's, would otherwise rewrite them under those readers. One event record and one wait, on
// the device, and only when the stream changes; on the same stream, stream order does it.
bpx_status follow_last(bpx_cuda *cu, cudaStream_t s)
{
    if (cu->last_stream && cu->last_stream != s) {
        CU(cudaEventRecord(cu->events[event_handoff], cu->last_stream));
        CU(cudaStreamWaitEvent(s, cu->events[event_handoff], 0));
    }
    cu->last_stream = s;
    return BPX_OK;
}

bpx_status upload(bpx_cuda *cu, cudaStream_t s, const float *const lo[3], const float *const hi[3],
                  uint32_t n)
{
    const float *src[6] = {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]};
    cu->timing.bytes_in = 24ull * n;
    if (n == 0) // no arrays yet: no 2D copy of null pointers with pitch 0 (may be refused)
        return BPX_OK;
    if (n <= staged_max) {
        if (bpx_status st = reserve_floats(&cu->staging, &cu->staging_capacity, n, 6, true);
            st != BPX_OK)
            return st;
        for (int a = 0; a < 6; a++)
            memcpy(cu->staging + (size_t)a * n, src[a], sizeof(float) * n);
        // Packed as 6 arrays of n, then spread to the device's arrays of box_capacity: one 2D
        // copy while that pitch is one CUDA takes (at most 2^31 - 1 bytes: the arrays only
        // grow, and a world that once held 2^29 boxes may hold few now), else 6 copies.
        size_t pitch = sizeof(float) * cu->box_capacity;
        if (pitch <= 0x7fffffff)
            CU(cudaMemcpy2DAsync(cu->boxes, pitch, cu->staging, sizeof(float) * n,
                                 sizeof(float) * n, 6, cudaMemcpyHostToDevice, s));
        else
            for (int a = 0; a < 6; a++)
                CU(cudaMemcpyAsync(cu->boxes + (size_t)a * cu->box_capacity,
                                   cu->staging + (size_t)a * n, sizeof(float) * n,
                                   cudaMemcpyHostToDevice, s));
    } else {
        for (int a = 0; a < 6; a++)
            CU(cudaMemcpyAsync(cu->boxes + (size_t)a * cu->box_capacity, src[a],
                               sizeof(float) * n, cudaMemcpyHostToDevice, s));
    }
    return BPX_OK;
}

void point_tree_at_boxes(bpx_cuda *cu, uint32_t n)
{
    for (int a = 0; a < 3; a++) {
        cu->tree.lo[a] = cu->boxes + (size_t)a * cu->box_capacity;
        cu->tree.hi[a] = cu->boxes + (size_t)(3 + a) * cu->box_capacity;
    }
    cu->tree.n = n;
}

// Bounds, Morton keys, their sort, the hierarchy: everything up to the walk.
bpx_status enqueue_tree(bpx_cuda *cu, cudaStream_t s)
{
    bpx_cuda_tree *t = &cu->tree;
    uint32_t n = t->n;
    CU(cudaMemsetAsync(t->scene, 0xff, 12, s));
    CU(cudaMemsetAsync(t->scene + 3, 0, 12, s));
    CU(cudaMemsetAsync(t->flags, 0, 4 * (size_t)n, s));
    CU(bpx__cuda_launch_bounds(s, t));
    CU(bpx__cuda_launch_morton(s, t));
    CU(bpx__cuda_sort_morton(s, cu->sort_temp, cu->sort_temp_bytes, t));
    CU(bpx__cuda_launch_build(s, t));
    return BPX_OK;
}

// The walk into keys[0], below cu->room (on the device path, keys above the count stay all
// ones and sort last).
bpx_status enqueue_walk(bpx_cuda *cu, cudaStream_t s)
{
    CU(cudaMemsetAsync(device_head(cu), 0, sizeof(unsigned long long), s));
    CU(bpx__cuda_launch_traverse(s, &cu->tree, cu->bits, cu->keys[0], cu->room,
                                 device_head(cu)));
    return BPX_OK;
}

// The sort of `items` keys and their unpacking into the pair buffer.
bpx_status enqueue_sort(bpx_cuda *cu, cudaStream_t s, unsigned long long items)
{
    CU(bpx__cuda_sort_pair_keys(s, cu->sort_temp, cu->sort_temp_bytes, cu->keys, items,
                                2 * cu->bits, &cu->key_buffer));
    CU(bpx__cuda_launch_unpack(s, cu->keys[cu->key_buffer], cu->bits, items, device_head(cu),
                               device_pairs(cu)));
    return BPX_OK;
}

uint64_t elapsed_ns(cudaEvent_t a, cudaEvent_t b)
{
    float ms = 0.0f;
    if (cudaEventElapsedTime(&ms, a, b) != cudaSuccess) {
        cudaGetLastError();
        return 0;
    }
    return (uint64_t)((double)ms * 1e6);
}

pthread_once_t probe_once = PTHREAD_ONCE_INIT;
const char *probe_reason = "";
char probe_detail[96];
char probe_old_driver[96];
bool probe_ok;

void probe_device()
{
    int count = 0;
    cudaError_t e = cudaGetDeviceCount(&count);
    if (e != cudaSuccess || count == 0) {
        probe_reason = e == cudaErrorInsufficientDriver ? "no CUDA driver"
                       : e == cudaErrorNoDevice || count == 0 ? "no CUDA device"
                                                              : "CUDA runtime failed to start";
        // The same error when the driver is there but older than the runtime linked in: a GPU
        // machine that would skip every CUDA test says why.
        int driver = 0;
        if (e == cudaErrorInsufficientDriver && cudaDriverGetVersion(&driver) == cudaSuccess &&
            driver > 0) {
            snprintf(probe_old_driver, sizeof probe_old_driver,
                     "the CUDA driver (%d.%d) is older than this build's runtime (%d.%d)",
                     driver / 1000, driver % 1000 / 10, CUDART_VERSION / 1000,
                     CUDART_VERSION % 1000 / 10);
            probe_reason = probe_old_driver;
        }
        cudaGetLastError();
        return;
    }
    cudaDeviceProp prop;
    int *d = nullptr, h = 0;
    if (cudaGetDeviceProperties(&prop, 0) != cudaSuccess || cudaMalloc(&d, sizeof(int)) != cudaSuccess) {
        probe_reason = "CUDA device 0 unusable";
        cudaGetLastError();
        return;
    }
    e = bpx__cuda_launch_probe(d);
    if (e == cudaSuccess)
        e = cudaMemcpy(&h, d, sizeof h, cudaMemcpyDeviceToHost);
    cudaFree(d);
    if (e != cudaSuccess || h != 42) {
        probe_reason = "this build has no kernels for the device (CMAKE_CUDA_ARCHITECTURES)";
        cudaGetLastError();
        return;
    }
    snprintf(probe_detail, sizeof probe_detail, "%s, sm_%d%d", prop.name, prop.major, prop.minor);
    probe_ok = true;
}

// A check of the caller's device boxes or centres: the head's verdict reset, the checking
// kernel enqueued by `enqueue`, the verdict read back.
template <class Enqueue> bpx_status check_on_device(bpx_cuda *cu, bool *bad, Enqueue enqueue)
{
    *bad = false;
    CU(cudaSetDevice(cu->device));
    if (bpx_status st = follow_last(cu, cu->stream); st != BPX_OK)
        return st;
    if (bpx_status st = reserve_pairs(cu, 0); st != BPX_OK)
        return st;
    if (bpx_status st = reserve_host_pairs(cu, 0); st != BPX_OK)
        return st;
    CU(cudaMemsetAsync(&device_head(cu)->bad, 0xff, 8, cu->stream));
    CU(enqueue());
    CU(cudaMemcpyAsync(cu->host_head, device_head(cu), sizeof(bpx_cuda_head),
                       cudaMemcpyDeviceToHost, cu->stream));
    CU(cudaStreamSynchronize(cu->stream));
    *bad = cu->host_head->bad != ~0ull;
    return BPX_OK;
}

// The loaded extents' minima onto the device, once per load_extents (no cycle may be in flight
// on another stream). On the context's stream, which the kernels that read them follow: a
// cudaMemcpy from pageable memory may return before its DMA ends, and the legacy stream it runs
// on does not order the context's non-blocking stream.
bpx_status upload_minima(bpx_cuda *cu, const float *const minima[3], uint32_t n)
{
    if (cu->minima_current)
        return BPX_OK;
    if (bpx_status st = follow_last(cu, cu->stream); st != BPX_OK)
        return st;
    if (bpx_status st = reserve_floats(&cu->minima, &cu->minima_capacity, n, 3, false);
        st != BPX_OK)
        return st;
    for (int a = 0; a < 3 && n; a++)
        CU(cudaMemcpyAsync(cu->minima + (size_t)a * cu->minima_capacity, minima[a],
                           sizeof(float) * n, cudaMemcpyHostToDevice, cu->stream));
    cu->minima_current = true;
    return BPX_OK;
}

} // namespace

extern "C" {

bool bpx__cuda_probe(const char **reason, char *detail, size_t size)
{
    pthread_once(&probe_once, probe_device);
    if (reason)
        *reason = probe_reason;
    if (detail && size)
        snprintf(detail, size, "%s", probe_ok ? probe_detail : "");
    return probe_ok;
}

bpx_status bpx__cuda_open(bpx_cuda **out)
{
    *out = nullptr;
    if (!bpx__cuda_probe(nullptr, nullptr, 0))
        return BPX_ERR_BACKEND_UNAVAILABLE;
    auto *cu = static_cast<bpx_cuda *>(bpx__alloc(sizeof(bpx_cuda)));
    if (!cu)
        return BPX_ERR_OUT_OF_MEMORY;
    memset(cu, 0, sizeof *cu);
    cudaError_t e = cudaSetDevice(0);
    if (e == cudaSuccess)
        e = cudaStreamCreateWithFlags(&cu->stream, cudaStreamNonBlocking);
    for (int k = 0; k < event_count && e == cudaSuccess; k++)
        e = k == event_handoff ? cudaEventCreateWithFlags(&cu->events[k], cudaEventDisableTiming)
                               : cudaEventCreate(&cu->events[k]);
    if (e != cudaSuccess) {
        bpx__cuda_close(cu);
        return fail(e, "cudaStreamCreate/cudaEventCreate");
    }
    *out = cu;
    return BPX_OK;
}

void bpx__cuda_close(bpx_cuda *cu)
{
    if (!cu)
        return;
    if (cu->pending_head) // a device-resident cycle, perhaps on the caller's stream
        cudaEventSynchronize(cu->events[event_out]);
    if (cu->stream)
        cudaStreamSynchronize(cu->stream);
    cudaFree(cu->boxes);
    cudaFreeHost(cu->staging);
    cudaFree(cu->centres);
    cudaFreeHost(cu->centres_staging);
    cudaFree(cu->minima);
    cudaFree(cu->small);
    cudaFree(cu->tree_memory);
    cudaFree(cu->keys[0]);
    cudaFree(cu->keys[1]);
    cudaFree(cu->out);
    cudaFreeHost(cu->host_head);
    cudaFree(cu->sort_temp);
    for (int k = 0; k < event_count; k++)
        if (cu->events[k])
            cudaEventDestroy(cu->events[k]);
    if (cu->stream)
        cudaStreamDestroy(cu->stream);
    cudaGetLastError();
    bpx__free(cu, sizeof *cu);
}

// Boxes in: the host's SoA arrays sent, the caller's device boxes converted and checked, or
// boxes made from centres by the device's updater (and checked). With `small` (the small
// comparator follows) the updater is left to that kernel, so the cycle stays one launch:
// *small_centres says where its centres are (NULL: the boxes are in place).
static bpx_status boxes_in(bpx_cuda *cu, cudaStream_t s, const float *const lo[3],
                           const float *const hi[3], uint32_t n, bool small,
                           const float **small_centres)
{
    *small_centres = nullptr;
    if (bpx_status st = reserve_floats(&cu->boxes, &cu->box_capacity, n, 6, false); st != BPX_OK)
        return st;
    CU(cudaMemsetAsync(&device_head(cu)->bad, 0xff, 8, s));
    if (cu->input == source::host_boxes)
        return upload(cu, s, lo, hi, n);
    float *dlo[3], *dhi[3];
    for (int a = 0; a < 3; a++) {
        dlo[a] = cu->boxes + (size_t)a * cu->box_capacity;
        dhi[a] = cu->boxes + (size_t)(3 + a) * cu->box_capacity;
    }
    if (n == 0)
        return BPX_OK;
    if (cu->input == source::device_boxes) {
        CU(bpx__cuda_launch_convert(s, cu->user_boxes, n, dlo, dhi, device_head(cu)));
        return BPX_OK;
    }
    const float *centres = cu->user_centres;
    if (cu->input == source::host_centres) {
        CU(cudaMemcpyAsync(cu->centres, cu->centres_staging, sizeof(float) * 3 * (size_t)n,
                           cudaMemcpyHostToDevice, s));
        cu->timing.bytes_in = 12ull * n;
        centres = cu->centres;
    }
    if (small) {
        *small_centres = centres;
        return BPX_OK;
    }
    CU(bpx__cuda_launch_update(s, centres, cu->minima, cu->minima_capacity, n, dlo, dhi,
                               device_head(cu)));
    return BPX_OK;
}

// The caller's device boxes or centres fix the count; the host's follow the world's.
static bool input_on_device(const bpx_cuda *cu)
{
    return cu->input == source::device_boxes || cu->input == source::device_centres;
}

static unsigned long long small_pairs(uint32_t n)
{
    return (unsigned long long)n * (n ? n - 1 : 0) / 2;
}

static bpx_status find(bpx_cuda *cu, const float *const lo[3], const float *const hi[3],
                       uint32_t n, uint64_t *count)
{
    *count = 0;
    cu->timing = bpx_cuda_timing{};
    cu->host_have = 0;
    if (input_on_device(cu))
        n = cu->n;
    cu->n = n;
    cu->tree_path = n > BPX_CUDA_SMALL_MAX;
    CU(cudaSetDevice(cu->device));
    // The caller's kernels behind a device-resident cycle on its stream may still read the
    // buffers this cycle rewrites.
    if (bpx_status s = follow_last(cu, cu->stream); s != BPX_OK)
        return s;
    // Every buffer that the head lives in is sized before the boxes go in: the check of device
    // boxes writes its verdict into the head, which a later regrow would drop.
    unsigned long long expected =
        cu->tree_path ? cu->last_count + cu->last_count / 4 : small_pairs(n);
    if (bpx_status s = reserve_pairs(cu, expected); s != BPX_OK)
        return s;
    cu->room = cu->tree_path ? cu->pair_capacity : small_pairs(n); // the host path grows to fit
    // The pairs we expect come back in the same copy as the head (small sets); the tree's are
    // counted first and copied straight to the caller.
    unsigned long long guess = cu->last_count + cu->last_count / 4 + 64;
    if (guess > small_pairs(n) || cu->tree_path)
        guess = cu->tree_path ? 0 : small_pairs(n);
    if (bpx_status s = reserve_host_pairs(cu, guess); s != BPX_OK)
        return s;
    CU(cudaEventRecord(cu->events[event_start], cu->stream));
    const float *small_centres = nullptr;
    if (bpx_status s = boxes_in(cu, cu->stream, lo, hi, n, !cu->tree_path && n >= 2,
                                &small_centres);
        s != BPX_OK)
        return s;
    CU(cudaEventRecord(cu->events[event_in], cu->stream));
    point_tree_at_boxes(cu, n);
    if (n < 2) {
        CU(cudaMemsetAsync(device_head(cu), 0, 8, cu->stream));
    } else if (!cu->tree_path) {
        if (bpx_status s = reserve_small(cu); s != BPX_OK)
            return s;
        CU(bpx__cuda_launch_small(cu->stream, cu->tree.lo, cu->tree.hi, small_centres,
                                  cu->minima, cu->minima_capacity, n, cu->small, device_head(cu),
                                  device_pairs(cu)));
        cu->timing.tests = small_pairs(n);
    } else {
        cu->bits = bpx_tree::key_bits(n);
        if (bpx_status s = reserve_tree(cu, n); s != BPX_OK)
            return s;
        if (bpx_status s = reserve_sort(cu); s != BPX_OK)
            return s;
        if (bpx_status s = enqueue_tree(cu, cu->stream); s != BPX_OK)
            return s;
        if (bpx_status s = enqueue_walk(cu, cu->stream); s != BPX_OK)
            return s;
        CU(cudaMemcpyAsync(cu->host_head, device_head(cu), sizeof(bpx_cuda_head),
                           cudaMemcpyDeviceToHost, cu->stream));
        CU(cudaStreamSynchronize(cu->stream));
        // A bad device box is reported before anything grows: its count means nothing (an
        // infinite box can ask for n^2 / 2 pairs).
        if (cu->host_head->bad != ~0ull)
            return BPX_ERR_NOT_FINITE;
        unsigned long long found = cu->host_head->count;
        if (found > cu->pair_capacity) { // grow to the exact need and walk again
            if (bpx_status s = reserve_pairs(cu, found); s != BPX_OK)
                return s;
            if (bpx_status s = reserve_sort(cu); s != BPX_OK)
                return s;
            cu->room = cu->pair_capacity;
            // The fresh buffer's head: the boxes were checked above, the count is the walk's.
            CU(cudaMemsetAsync(&device_head(cu)->bad, 0xff, 8, cu->stream));
            if (bpx_status s = enqueue_walk(cu, cu->stream); s != BPX_OK)
                return s;
        }
        if (bpx_status s = enqueue_sort(cu, cu->stream, found); s != BPX_OK)
            return s;
    }
    CU(cudaEventRecord(cu->events[event_device], cu->stream));
    CU(cudaMemcpyAsync(cu->host_head, cu->out, pair_bytes(guess), cudaMemcpyDeviceToHost,
                       cu->stream));
    CU(cudaStreamSynchronize(cu->stream));
    if (cu->host_head->bad != ~0ull)
        return BPX_ERR_NOT_FINITE; // the caller asks bpx__cuda_bad_box which and why
    *count = cu->host_head->count;
    cu->last_count = *count;
    cu->host_have = guess < *count ? guess : *count;
    cu->timing.bytes_out = pair_bytes(guess);
    cu->timing.tree = cu->tree_path;
    return BPX_OK;
}

// A host cycle. One that fails part-way ends what it had enqueued before it returns: no copy
// from the pinned staging and no kernel over the buffers still runs when the next call rewrites
// or frees them.
bpx_status bpx__cuda_find(bpx_cuda *cu, const float *const lo[3], const float *const hi[3],
                          uint32_t n, uint64_t *count)
{
    bpx_status status = find(cu, lo, hi, n, count);
    if (status != BPX_OK && cudaStreamSynchronize(cu->stream) != cudaSuccess)
        cudaGetLastError();
    return status;
}

bpx_status bpx__cuda_read_pairs(bpx_cuda *cu, bpx_pair *out, uint64_t count)
{
    const bpx_pair *host_pairs =
        reinterpret_cast<const bpx_pair *>(reinterpret_cast<unsigned char *>(cu->host_head) +
                                           sizeof(bpx_cuda_head));
    unsigned long long have = cu->host_have < count ? cu->host_have : count;
    if (have)
        memcpy(out, host_pairs, sizeof(bpx_pair) * have);
    if (count > have) {
        CU(cudaMemcpyAsync(out + have, device_pairs(cu) + have, sizeof(bpx_pair) * (count - have),
                           cudaMemcpyDeviceToHost, cu->stream));
        cu->timing.bytes_out += sizeof(bpx_pair) * (count - have);
    }
    CU(cudaEventRecord(cu->events[event_out], cu->stream));
    CU(cudaStreamSynchronize(cu->stream));
    cu->timing.in_ns = elapsed_ns(cu->events[event_start], cu->events[event_in]);
    cu->timing.device_ns = elapsed_ns(cu->events[event_in], cu->events[event_device]);
    cu->timing.out_ns = elapsed_ns(cu->events[event_device], cu->events[event_out]);
    return BPX_OK;
}

bool bpx__cuda_bad_box(const bpx_cuda *cu, uint32_t *index, bool *min_greater)
{
    unsigned long long bad = cu->host_head ? cu->host_head->bad : ~0ull;
    if (bad == ~0ull)
        return false;
    *index = (uint32_t)(bad >> 32);
    *min_greater = (bad & 0xffffffffull) >= 8;
    return true;
}

bpx_status bpx__cuda_check_device_boxes(bpx_cuda *cu, const bpx_box *boxes, uint32_t n,
                                        bool *bad)
{
    float *none[3] = {nullptr, nullptr, nullptr};
    return check_on_device(cu, bad, [&] {
        return n ? bpx__cuda_launch_convert(cu->stream, boxes, n, none, none, device_head(cu))
                 : cudaSuccess;
    });
}

bpx_status bpx__cuda_check_device_centres(bpx_cuda *cu, const float *centres,
                                          const float *const minima[3], uint32_t n, bool *bad)
{
    *bad = false;
    CU(cudaSetDevice(cu->device));
    if (bpx_status st = upload_minima(cu, minima, n); st != BPX_OK)
        return st;
    float *none[3] = {nullptr, nullptr, nullptr};
    return check_on_device(cu, bad, [&] {
        return n ? bpx__cuda_launch_update(cu->stream, centres, cu->minima, cu->minima_capacity,
                                           n, none, none, device_head(cu))
                 : cudaSuccess;
    });
}

void bpx__cuda_use_device_boxes(bpx_cuda *cu, const bpx_box *boxes, uint32_t n)
{
    cu->input = boxes ? source::device_boxes : source::host_boxes;
    cu->user_boxes = boxes;
    cu->user_centres = nullptr;
    cu->n = n;
    if (!boxes) // set_boxes or load_extents: the minima may be others from now on
        cu->minima_current = false;
}

bpx_status bpx__cuda_use_centres(bpx_cuda *cu, const float *centres, bool on_device,
                                 const float *const minima[3], uint32_t n)
{
    CU(cudaSetDevice(cu->device));
    // A device cycle in flight may still read the staging or the minima.
    if (cu->pending_head)
        CU(cudaEventSynchronize(cu->events[event_out]));
    if (bpx_status st = upload_minima(cu, minima, n); st != BPX_OK)
        return st;
    if (!on_device) {
        if (bpx_status st = reserve_floats(&cu->centres_staging, &cu->centres_staging_capacity, n,
                                           3, true);
            st != BPX_OK)
            return st;
        if (bpx_status st = reserve_floats(&cu->centres, &cu->centres_capacity, n, 3, false);
            st != BPX_OK)
            return st;
        memcpy(cu->centres_staging, centres, sizeof(float) * 3 * (size_t)n);
    }
    cu->input = on_device ? source::device_centres : source::host_centres;
    cu->user_boxes = nullptr;
    cu->user_centres = on_device ? centres : nullptr;
    cu->n = n;
    return BPX_OK;
}

bpx_status bpx__cuda_collide_device(bpx_cuda *cu, void *stream, const float *const lo[3],
                                    const float *const hi[3], uint32_t n)
{
    CU(cudaSetDevice(cu->device));
    cudaStream_t s = stream ? static_cast<cudaStream_t>(stream) : cu->stream;
    if (input_on_device(cu))
        n = cu->n;
    cu->n = n;
    cu->timing = bpx_cuda_timing{};
    // The world's last work, on whatever stream, ends before this cycle starts on `s`: the last
    // device-resident cycle with the caller's readers enqueued behind it, a host cycle's or a
    // check's work on the world's stream (on the device: no host wait).
    if (bpx_status st = follow_last(cu, s); st != BPX_OK)
        return st;
    // The last cycle's count, copied back behind it, sizes this cycle's buffer.
    if (bpx_status st = bpx__cuda_finish(cu, nullptr); st != BPX_OK && st != BPX_ERR_CAPACITY &&
                                                       st != BPX_ERR_NOT_FINITE)
        return st;
    // Room for the last count and half more, without one for two pairs per box (the benchmark
    // scenes have about one), never more than there can be. The walk keeps that many and the sort
    // orders that many, not the buffer's geometric slack: a count past the room is CAPACITY.
    unsigned long long seen = cu->last_count ? cu->last_count : 2ull * n;
    unsigned long long need = n <= BPX_CUDA_SMALL_MAX ? small_pairs(n) : seen + seen / 2 + 1024;
    need = need < small_pairs(n) ? need : small_pairs(n);
    if (bpx_status st = reserve_pairs(cu, need); st != BPX_OK)
        return st;
    // Before any count the whole buffer is the room: a first cycle past two pairs per box fits.
    cu->room = cu->last_count || n <= BPX_CUDA_SMALL_MAX
                   ? need
                   : (cu->pair_capacity < small_pairs(n) ? cu->pair_capacity : small_pairs(n));
    if (bpx_status st = reserve_host_pairs(cu, 0); st != BPX_OK)
        return st;
    const float *small_centres = nullptr;
    bpx_status status =
        boxes_in(cu, s, lo, hi, n, n >= 2 && n <= BPX_CUDA_SMALL_MAX, &small_centres);
    point_tree_at_boxes(cu, n);
    if (status != BPX_OK) {
    } else if (n < 2) {
        cudaError_t e = cudaMemsetAsync(device_head(cu), 0, 8, s);
        status = e == cudaSuccess ? BPX_OK : fail(e, "cudaMemsetAsync");
    } else if (n <= BPX_CUDA_SMALL_MAX) {
        status = reserve_small(cu);
        cudaError_t e = status != BPX_OK ? cudaSuccess
                                         : bpx__cuda_launch_small(
                                               s, cu->tree.lo, cu->tree.hi, small_centres,
                                               cu->minima, cu->minima_capacity, n, cu->small,
                                               device_head(cu), device_pairs(cu));
        if (e != cudaSuccess)
            status = fail(e, "small_kernel");
        cu->tree_path = false;
    } else {
        cu->tree_path = true;
        cu->bits = bpx_tree::key_bits(n);
        status = reserve_tree(cu, n);
        if (status == BPX_OK)
            status = reserve_sort(cu);
        if (status == BPX_OK)
            status = enqueue_tree(cu, s);
        if (status == BPX_OK) {
            cudaError_t e = cudaMemsetAsync(cu->keys[0], 0xff, 8 * cu->room, s);
            status = e == cudaSuccess ? BPX_OK : fail(e, "cudaMemsetAsync (keys)");
        }
        if (status == BPX_OK)
            status = enqueue_walk(cu, s);
        if (status == BPX_OK)
            status = enqueue_sort(cu, s, cu->room);
    }
    if (status == BPX_OK) {
        cudaError_t e = cudaMemcpyAsync(cu->host_head, device_head(cu), sizeof(bpx_cuda_head),
                                        cudaMemcpyDeviceToHost, s);
        if (e == cudaSuccess)
            e = cudaEventRecord(cu->events[event_out], s);
        status = e == cudaSuccess ? BPX_OK : fail(e, "cudaMemcpyAsync (head)");
        cu->pending_head = status == BPX_OK;
    }
    cu->timing.tree = cu->tree_path;
    if (status != BPX_OK && cudaStreamSynchronize(s) != cudaSuccess)
        cudaGetLastError(); // what was enqueued ends before a host cycle reuses its buffers
    return status;
}

bpx_status bpx__cuda_finish(bpx_cuda *cu, uint64_t *count)
{
    if (!cu->pending_head)
        return BPX_OK;
    CU(cudaEventSynchronize(cu->events[event_out]));
    cu->pending_head = false;
    if (count)
        *count = cu->host_head->count;
    // A bad box's count sizes nothing (an infinite box can ask for n^2 / 2 pairs).
    if (cu->host_head->bad != ~0ull)
        return BPX_ERR_NOT_FINITE;
    cu->last_count = cu->host_head->count;
    if (cu->last_count > cu->room)
        return BPX_ERR_CAPACITY;
    return BPX_OK;
}

void bpx__cuda_device_result(const bpx_cuda *cu, const bpx_pair **pairs,
                             const unsigned long long **count, size_t *capacity)
{
    *pairs = cu->out ? device_pairs(cu) : nullptr;
    *count = cu->out ? &device_head(cu)->count : nullptr;
    *capacity = (size_t)cu->room;
}

bpx_status bpx__cuda_copy_in(void *out, const void *device, size_t bytes)
{
    CU(cudaMemcpy(out, device, bytes, cudaMemcpyDeviceToHost));
    return BPX_OK;
}

const bpx_box *bpx__cuda_device_boxes(const bpx_cuda *cu)
{
    return cu->user_boxes;
}

const float *bpx__cuda_device_centres(const bpx_cuda *cu)
{
    return cu->user_centres;
}

bpx_cuda_timing bpx__cuda_timing(const bpx_cuda *cu)
{
    return cu->timing;
}

void *bpx__cuda_stream(const bpx_cuda *cu)
{
    return cu->stream;
}

uint64_t bpx__cuda_input_version(const bpx_cuda *cu)
{
    return cu->version;
}

void bpx__cuda_set_input_version(bpx_cuda *cu, uint64_t version)
{
    cu->version = version;
}

} // extern "C"
