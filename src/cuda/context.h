// The cuda backend's host side, shared by its two files: the context of a world (struct
// bpx_cuda) and its buffers (buffers.cu: device, pinned and staging memory, grown
// geometrically), used by the cycle (cycle.cu). Host code only: the fake device
// (test/fake_cuda/) runs it as it is. SPDX-License-Identifier: MIT
#pragma once

#include <cuda_runtime_api.h>

#include <cstddef>

#include "cuda_api.h"
#include "kernels.cuh"
#include "tree.cuh"

namespace bpx_cuda_host {


// event_handoff: recorded on the stream of the world's last work when the next work starts on
// another stream, which waits for it (follow_last); it times nothing.
enum { event_start, event_in, event_device, event_out, event_handoff, event_count };

// Where a cycle's boxes come from: the host's boxes (sent), the caller's device boxes (read in
// place), or boxes the device's updater makes from centres and the stored minima: the host's
// centres (sent, 12 bytes an object) or the caller's device centres (read in place).
enum class source { host_boxes, device_boxes, host_centres, device_centres };

} // namespace bpx_cuda_host

struct bpx_cuda {
    int device;
    cudaStream_t stream;
    cudaEvent_t events[bpx_cuda_host::event_count];

    uint32_t box_capacity; // boxes the SoA arrays hold
    float *boxes;          // 6 arrays of box_capacity floats: lo x, y, z, hi x, y, z
    float *staging;        // pinned, same layout, for staged uploads
    uint32_t staging_capacity;

    uint32_t tree_capacity; // boxes the tree's arrays hold
    bpx_cuda_tree tree;
    void *tree_memory;

    unsigned long long pair_capacity; // pairs the keys and the pair buffer hold
    unsigned long long room;          // of them, the pairs the last cycle kept room for
    unsigned long long *keys[2];
    unsigned char *out; // bpx_cuda_head, then pair_capacity pairs
    bpx_cuda_head *host_head; // pinned: head, then host_pairs_capacity pairs
    unsigned long long host_pairs_capacity;

    void *sort_temp;
    size_t sort_temp_bytes;

    uint32_t n;       // boxes of the last cycle
    int bits;         // bits of a pair key's j
    int key_buffer;   // which keys buffer the last sort left sorted
    uint64_t last_count;
    bpx_cuda_host::source input;
    const bpx_box *user_boxes; // device boxes read in place each cycle (device_boxes)
    const float *user_centres; // device centres read in place each cycle (device_centres)
    float *centres;            // the host's centres on the device (host_centres)
    uint32_t centres_capacity; // objects it holds
    float *centres_staging;    // pinned: the host's centres, copied when they are given
    uint32_t centres_staging_capacity;
    float *minima; // 3 planes of minima_capacity: the loaded extents' minima
    uint32_t minima_capacity;
    bool minima_current; // they are the world's (until the next load_extents)
    bpx_cuda_small_scratch *small; // the small comparator's rows (allocated at its first cycle)
    unsigned long long host_have; // pairs of the last host cycle already in host_head
    bool tree_path;
    bool pending_head; // a device-resident cycle's head is on its way to host_head
    // The stream the world last enqueued work on (nullptr: none yet). After a device-resident
    // cycle it is the caller's stream, where the caller's kernels read the pairs behind it.
    cudaStream_t last_stream;
    uint64_t version;  // the world's boxes_version when its input was last given
    bpx_cuda_timing timing;
};

namespace bpx_cuda_host {

// A failed CUDA call: logged, the sticky error cleared, DEVICE_MEMORY or DEVICE returned.
bpx_status fail(cudaError_t e, const char *what);
// Pinned host memory that cannot be had is the host's lack (OUT_OF_MEMORY), not the device's.
bpx_status fail_pinned(cudaError_t e, const char *what);

#define CU(call)                                                                                   \
    do {                                                                                           \
        cudaError_t e_ = (call);                                                                   \
        if (e_ != cudaSuccess)                                                                     \
            return fail(e_, #call);                                                                \
    } while (0)

size_t grown(size_t have, size_t need); // the next capacity: 1.5x steps from 1024
unsigned long long pair_bytes(unsigned long long pairs); // the head and `pairs` pairs
bpx_pair *device_pairs(const bpx_cuda *cu);
bpx_cuda_head *device_head(const bpx_cuda *cu);

// Room for n objects' `per` floats each (6 for boxes, 3 for centres or minima) in *arrays,
// device memory or (pinned) host memory, grown geometrically; what they held is not kept.
bpx_status reserve_floats(float **arrays, uint32_t *capacity, uint32_t n, int per, bool pinned);
// Each below grows one of the context's buffers to hold at least what it is asked for (what
// it held is not kept), and leaves it as it was on failure.
bpx_status reserve_tree(bpx_cuda *cu, uint32_t n);
bpx_status reserve_pairs(bpx_cuda *cu, unsigned long long pairs);
bpx_status reserve_host_pairs(bpx_cuda *cu, unsigned long long pairs);
bpx_status reserve_small(bpx_cuda *cu);
bpx_status reserve_sort(bpx_cuda *cu);

} // namespace bpx_cuda_host
