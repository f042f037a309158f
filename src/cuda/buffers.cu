// The cuda backend's buffers (context.h): device memory for boxes, the tree, keys and pairs,
// pinned host memory for staging and the pairs read back; all grown geometrically, so that
// cycles at a steady n allocate nothing. SPDX-License-Identifier: MIT
#include "context.h"

extern "C" {
#include "core/log.h"
}

namespace bpx_cuda_host {

bpx_status fail(cudaError_t e, const char *what)
{
    bpx__log(0, "cuda: %s failed: %s (%s)", what, cudaGetErrorName(e), cudaGetErrorString(e));
    cudaGetLastError(); // clears a sticky-free error so the next call starts clean
    return e == cudaErrorMemoryAllocation ? BPX_ERR_DEVICE_MEMORY : BPX_ERR_DEVICE;
}

// Pinned host memory that cannot be had is the host's lack (OUT_OF_MEMORY), not the device's.
bpx_status fail_pinned(cudaError_t e, const char *what)
{
    bpx_status s = fail(e, what);
    return s == BPX_ERR_DEVICE_MEMORY ? BPX_ERR_OUT_OF_MEMORY : s;
}


size_t grown(size_t have, size_t need)
{
    size_t size = have ? have : 1024;
    while (size < need)
        size += size / 2;
    return size;
}

unsigned long long pair_bytes(unsigned long long pairs)
{
    return sizeof(bpx_cuda_head) + pairs * sizeof(bpx_pair);
}

bpx_pair *device_pairs(const bpx_cuda *cu)
{
    return reinterpret_cast<bpx_pair *>(cu->out + sizeof(bpx_cuda_head));
}

bpx_cuda_head *device_head(const bpx_cuda *cu)
{
    return reinterpret_cast<bpx_cuda_head *>(cu->out);
}

// Room for n objects' `per` floats each (6 for boxes, 3 for centres or minima) in *arrays,
// device memory or (pinned) host memory, grown geometrically; what they held is not kept.
bpx_status reserve_floats(float **arrays, uint32_t *capacity, uint32_t n, int per, bool pinned)
{
    if (n <= *capacity)
        return BPX_OK;
    uint32_t grown_to = (uint32_t)grown(*capacity, n);
    size_t bytes = sizeof(float) * (size_t)per * (size_t)grown_to;
    float *fresh = nullptr;
    cudaError_t e = pinned ? cudaMallocHost(&fresh, bytes) : cudaMalloc(&fresh, bytes);
    if (e != cudaSuccess)
        return pinned ? fail_pinned(e, "cudaMallocHost (staging)")
                      : fail(e, "cudaMalloc (boxes, centres)");
    if (pinned)
        cudaFreeHost(*arrays);
    else
        cudaFree(*arrays);
    *arrays = fresh;
    *capacity = grown_to;
    return BPX_OK;
}

size_t align_up(size_t x)
{
    return (x + 255) & ~(size_t)255;
}

// The tree's arrays in one allocation (offsets aligned for float4 loads).
bpx_status reserve_tree(bpx_cuda *cu, uint32_t n)
{
    if (n <= cu->tree_capacity)
        return BPX_OK;
    size_t cap = grown(cu->tree_capacity, n);
    size_t u32 = align_up(4 * cap), f4 = align_up(16 * cap);
    size_t bytes = align_up(6 * 4) + 4 * u32 + 2 * f4 + align_up(sizeof(bpx_cuda_node) * cap) +
                   3 * u32;
    unsigned char *m = nullptr;
    CU(cudaMalloc(&m, bytes));
    cudaFree(cu->tree_memory);
    cu->tree_memory = m;
    bpx_cuda_tree *t = &cu->tree;
    t->scene = reinterpret_cast<uint32_t *>(m), m += align_up(6 * 4);
    t->morton[0] = reinterpret_cast<uint32_t *>(m), m += u32;
    t->morton[1] = reinterpret_cast<uint32_t *>(m), m += u32;
    t->ids[0] = reinterpret_cast<uint32_t *>(m), m += u32;
    t->ids[1] = reinterpret_cast<uint32_t *>(m), m += u32;
    t->leaf_lo = reinterpret_cast<float4 *>(m), m += f4;
    t->leaf_hi = reinterpret_cast<float4 *>(m), m += f4;
    t->nodes = reinterpret_cast<bpx_cuda_node *>(m), m += align_up(sizeof(bpx_cuda_node) * cap);
    t->leaf_parent = reinterpret_cast<uint32_t *>(m), m += u32;
    t->node_parent = reinterpret_cast<uint32_t *>(m), m += u32;
    t->flags = reinterpret_cast<uint32_t *>(m);
    cu->tree_capacity = (uint32_t)cap;
    cu->sort_temp_bytes = 0; // sizes change with the item count: ask CUB again
    return BPX_OK;
}

bpx_status reserve_pairs(bpx_cuda *cu, unsigned long long pairs)
{
    if (pairs <= cu->pair_capacity && cu->out)
        return BPX_OK;
    unsigned long long cap = grown(cu->pair_capacity, pairs < 65536 ? 65536 : pairs);
    unsigned long long *k0 = nullptr, *k1 = nullptr;
    unsigned char *out = nullptr;
    cudaError_t e = cudaMalloc(&k0, 8 * cap);
    if (e == cudaSuccess)
        e = cudaMalloc(&k1, 8 * cap);
    if (e == cudaSuccess)
        e = cudaMalloc(&out, pair_bytes(cap));
    if (e != cudaSuccess) {
        cudaFree(k0), cudaFree(k1), cudaFree(out);
        return fail(e, "cudaMalloc (pairs)");
    }
    // The fresh head says no pairs and no bad box, for a caller that reads it before a cycle;
    // landed before a cycle on any stream writes it (buffers grow rarely: the wait is cheap).
    e = cudaMemsetAsync(out, 0, sizeof(unsigned long long), cu->stream);
    if (e == cudaSuccess)
        e = cudaMemsetAsync(out + offsetof(bpx_cuda_head, bad), 0xff, 8, cu->stream);
    if (e == cudaSuccess)
        e = cudaStreamSynchronize(cu->stream);
    if (e != cudaSuccess) {
        cudaFree(k0), cudaFree(k1), cudaFree(out);
        return fail(e, "cudaMemsetAsync (head)");
    }
    cudaFree(cu->keys[0]), cudaFree(cu->keys[1]), cudaFree(cu->out);
    cu->keys[0] = k0, cu->keys[1] = k1, cu->out = out;
    cu->pair_capacity = cap;
    cu->sort_temp_bytes = 0;
    return BPX_OK;
}

bpx_status reserve_host_pairs(bpx_cuda *cu, unsigned long long pairs)
{
    if (pairs <= cu->host_pairs_capacity && cu->host_head)
        return BPX_OK;
    unsigned long long cap = grown(cu->host_pairs_capacity, pairs);
    void *host = nullptr;
    if (cudaError_t e = cudaMallocHost(&host, pair_bytes(cap)); e != cudaSuccess)
        return fail_pinned(e, "cudaMallocHost (pairs)");
    cudaFreeHost(cu->host_head);
    cu->host_head = static_cast<bpx_cuda_head *>(host);
    cu->host_pairs_capacity = cap;
    return BPX_OK;
}

// The small comparator's scratch, once; its block counter starts at zero (each cycle's last block
// leaves it so). The zero has landed before any stream's kernel reads it: a cudaMemset on the
// legacy stream may still be pending when it returns, and the world's non-blocking stream (or the
// caller's) does not wait for it.
bpx_status reserve_small(bpx_cuda *cu)
{
    if (cu->small)
        return BPX_OK;
    bpx_cuda_small_scratch *scratch = nullptr;
    CU(cudaMalloc(&scratch, sizeof *scratch));
    cudaError_t e = cudaMemsetAsync(&scratch->done, 0, sizeof scratch->done, cu->stream);
    if (e == cudaSuccess)
        e = cudaStreamSynchronize(cu->stream);
    if (e != cudaSuccess) {
        cudaFree(scratch);
        return fail(e, "cudaMemset (small comparator)");
    }
    cu->small = scratch;
    return BPX_OK;
}

// Temporary storage for both sorts at the current capacities.
bpx_status reserve_sort(bpx_cuda *cu)
{
    if (cu->sort_temp_bytes)
        return BPX_OK;
    size_t bytes = 0;
    CU(bpx__cuda_sort_temp_bytes(cu->tree_capacity, cu->pair_capacity, &bytes));
    void *temp = nullptr;
    CU(cudaMalloc(&temp, bytes));
    cudaFree(cu->sort_temp);
    cu->sort_temp = temp;
    cu->sort_temp_bytes = bytes;
    return BPX_OK;
}

} // namespace bpx_cuda_host
