// The cuda backend's kernels; see kernels.cuh for the two comparators. SPDX-License-Identifier: MIT
//
// No fast math anywhere (the build refuses it): comparisons decide every pair, and the only
// arithmetic, the centres behind the Morton order, only orders the tree, never decides a pair.
#include <cub/block/block_scan.cuh>
#include <cub/device/device_radix_sort.cuh>

#include "kernels.cuh"
#include "tree.cuh"
#include "small.cuh"
#include "update.cuh"

namespace {

constexpr int block_threads = 256;
constexpr int emit_buffer = 8;

unsigned int grid_for(uint32_t n)
{
    return (n + block_threads - 1) / block_threads;
}

using namespace bpx_tree;

// ---- small: a warp per box, the last block to finish writes the pairs in order ----------------

// Each warp takes one row (box i): its hit words over the later boxes (small.cuh) and its count
// go to the scratch. Every block then counts itself done; the last one (the others' writes are
// visible to it: each thread fenced them before its block's count) scans the rows' counts and
// writes every pair at its place, one row per warp at a time. One launch a cycle, spread over
// n / 32 SMs; with centres each lane makes its boxes from them (the updater, fused in), and the
// row's own warp checks its box.
__global__ void __launch_bounds__(BPX_CUDA_SMALL_MAX)
    small_kernel(bpx_small::input in, uint32_t n, bpx_cuda_small_scratch *scratch,
                 bpx_cuda_head *head, bpx_pair *pairs)
{
    constexpr unsigned full = 0xffffffffu;
    constexpr uint32_t warps = BPX_CUDA_SMALL_MAX / 32, row_words = BPX_CUDA_SMALL_MAX / 32;
    const uint32_t lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
    const uint32_t row = blockIdx.x * warps + warp;
    if (row < n) {
        float alo[3], ahi[3];
        int bad = bpx_small::box(in, row, alo, ahi);
        if (bad >= 0 && lane == 0)
            atomicMin(&head->bad, ((unsigned long long)row << 32) | (4u + (uint32_t)bad));
        uint32_t count = 0, steps = bpx_small::words(row, n);
        for (uint32_t k = 0; k < steps; k++) {
            uint32_t j = bpx_small::other(row, k, lane);
            bool hit = false;
            if (j < n) {
                float blo[3], bhi[3];
                bpx_small::box(in, j, blo, bhi);
                hit = bpx_small::overlap(alo, ahi, blo, bhi);
            }
            uint32_t word = __ballot_sync(full, hit);
            if (lane == 0)
                scratch->masks[row * row_words + k] = word;
            count += __popc(word);
        }
        if (lane == 0)
            scratch->counts[row] = count;
    }
    __threadfence(); // this thread's words are out before its block counts itself done
    __syncthreads();
    __shared__ bool last;
    if (threadIdx.x == 0)
        last = atomicAdd(&scratch->done, 1u) == gridDim.x - 1;
    __syncthreads();
    if (!last)
        return;
    __threadfence();
    // The rows' counts, scanned: where each row's pairs start.
    using scan_t = cub::BlockScan<uint32_t, BPX_CUDA_SMALL_MAX>;
    __shared__ typename scan_t::TempStorage scan_storage;
    __shared__ uint32_t start[BPX_CUDA_SMALL_MAX];
    uint32_t mine = threadIdx.x < n ? __ldcg(&scratch->counts[threadIdx.x]) : 0u, total = 0;
    scan_t(scan_storage).ExclusiveSum(mine, mine, total);
    start[threadIdx.x] = mine;
    if (threadIdx.x == 0) {
        head->count = total; // head->bad is the cycle's check (reset before it), not touched here
        scratch->done = 0;   // for the next cycle
    }
    __syncthreads();
    for (uint32_t i = warp; i < n; i += warps) {
        uint32_t steps = bpx_small::words(i, n), at = start[i];
        // One load per lane (a row has at most 32 words), then each word from its lane.
        uint32_t held = lane < steps ? __ldcg(&scratch->masks[i * row_words + lane]) : 0u;
        for (uint32_t k = 0; k < steps; k++) {
            uint32_t word = __shfl_sync(full, held, k);
            if ((word >> lane) & 1u)
                pairs[at + bpx_small::before(word, lane)] =
                    bpx_pair{i, bpx_small::other(i, k, lane)};
            at += __popc(word);
        }
    }
}

// ---- tree: bounds, Morton keys, build, refit, traverse --------------------------------------

// Inert boxes (removed ids: min +inf, max -inf) have no centre; they stay out of the bounds
// and sort last, and their empty bounds never widen a node.
__global__ void bounds_kernel(const float *lx, const float *ly, const float *lz, const float *hx,
                              const float *hy, const float *hz, uint32_t n, uint32_t *scene)
{
    uint32_t lo[3] = {~0u, ~0u, ~0u}, hi[3] = {0, 0, 0};
    for (uint32_t i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) {
        if (!live(lx[i], hx[i]))
            continue;
        const float blo[3] = {lx[i], ly[i], lz[i]}, bhi[3] = {hx[i], hy[i], hz[i]};
        float c[3];
        centre(blo, bhi, c);
        for (int a = 0; a < 3; a++) {
            uint32_t k = order_key(c[a]);
            lo[a] = min(lo[a], k);
            hi[a] = max(hi[a], k);
        }
    }
    for (int a = 0; a < 3; a++) {
        for (int d = 16; d > 0; d >>= 1) {
            lo[a] = min(lo[a], __shfl_xor_sync(0xffffffffu, lo[a], d));
            hi[a] = max(hi[a], __shfl_xor_sync(0xffffffffu, hi[a], d));
        }
    }
    if ((threadIdx.x & 31) == 0) {
        for (int a = 0; a < 3; a++) {
            atomicMin(&scene[a], lo[a]);
            atomicMax(&scene[3 + a], hi[a]);
        }
    }
}

__global__ void morton_kernel(const float *lx, const float *ly, const float *lz, const float *hx,
                              const float *hy, const float *hz, uint32_t n,
                              const uint32_t *scene, uint32_t *morton, uint32_t *ids)
{
    uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n)
        return;
    ids[i] = i;
    if (!live(lx[i], hx[i])) {
        morton[i] = ~0u;
        return;
    }
    const float blo[3] = {lx[i], ly[i], lz[i]}, bhi[3] = {hx[i], hy[i], hz[i]};
    float c[3];
    centre(blo, bhi, c);
    morton[i] = bpx_tree::morton(c, scene);
}

__global__ void gather_kernel(const float *lx, const float *ly, const float *lz, const float *hx,
                              const float *hy, const float *hz, uint32_t n, const uint32_t *ids,
                              float4 *leaf_lo, float4 *leaf_hi)
{
    uint32_t t = blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= n)
        return;
    uint32_t i = ids[t];
    leaf_lo[t] = make_float4(lx[i], ly[i], lz[i], __uint_as_float(i));
    leaf_hi[t] = make_float4(hx[i], hy[i], hz[i], 0.0f);
}

__global__ void build_kernel(const uint32_t *keys, int n, uint32_t *leaf_parent,
                             uint32_t *node_parent)
{
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n - 1)
        return;
    build_node(keys, n, i, leaf_parent, node_parent);
}

__global__ void refit_kernel(const float4 *leaf_lo, const float4 *leaf_hi, uint32_t n,
                             const uint32_t *leaf_parent, const uint32_t *node_parent,
                             bpx_cuda_node *nodes, uint32_t *flags)
{
    uint32_t t = blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= n)
        return;
    // Fence, atomic, fence: the sibling's release and this thread's acquire (PTX memory
    // model); without the second fence nothing orders the slot loads after the atomic.
    refit_leaf(t, leaf_lo, leaf_hi, leaf_parent, node_parent, nodes, [flags](uint32_t p) {
        __threadfence(); // this child's slot is out before its arrival is
        uint32_t before = atomicAdd(&flags[p], 1u);
        __threadfence(); // the sibling's slot is read after its arrival is seen
        return before;
    });
}

__device__ void emit_flush(unsigned long long *buffer, int count, unsigned long long *keys,
                           unsigned long long capacity, bpx_cuda_head *head)
{
    unsigned long long base = atomicAdd(&head->count, (unsigned long long)count);
    for (int k = 0; k < count; k++)
        if (base + k < capacity)
            keys[base + k] = buffer[k];
}

// Thread t walks for the box at Morton position t (tree.cuh); hits gather in a small buffer
// that goes out with one atomic per flush.
__global__ void traverse_kernel(const bpx_cuda_node *__restrict__ nodes,
                                const float4 *__restrict__ leaf_lo,
                                const float4 *__restrict__ leaf_hi,
                                const uint32_t *__restrict__ leaf_parent,
                                const uint32_t *__restrict__ node_parent, uint32_t n, int bits,
                                unsigned long long *keys, unsigned long long capacity,
                                bpx_cuda_head *head)
{
    const uint32_t t = blockIdx.x * blockDim.x + threadIdx.x;
    unsigned long long buffer[emit_buffer];
    int count = 0;
    if (t + 1 < n) {
        walk(t, nodes, leaf_lo, leaf_hi, leaf_parent, node_parent, [&](uint32_t i, uint32_t j) {
            if (count == emit_buffer) {
                emit_flush(buffer, count, keys, capacity, head);
                count = 0;
            }
            buffer[count++] = pair_key(i, j, bits);
        });
    }
    // One atomic per warp for what is left: a warp-wide scan of the counts.
    const int lane = threadIdx.x & 31;
    uint32_t before = count;
    for (int d = 1; d < 32; d <<= 1) {
        uint32_t v = __shfl_up_sync(0xffffffffu, before, d);
        if (lane >= d)
            before += v;
    }
    uint32_t warp_total = __shfl_sync(0xffffffffu, before, 31);
    before -= count;
    unsigned long long base = 0;
    if (lane == 31 && warp_total)
        base = atomicAdd(&head->count, (unsigned long long)warp_total);
    base = __shfl_sync(0xffffffffu, base, 31);
    for (int k = 0; k < count; k++)
        if (base + before + k < capacity)
            keys[base + before + k] = buffer[k];
}

__global__ void unpack_kernel(const unsigned long long *keys, int bits,
                              unsigned long long capacity, const bpx_cuda_head *head,
                              bpx_pair *pairs)
{
    unsigned long long k = blockIdx.x * (unsigned long long)blockDim.x + threadIdx.x;
    unsigned long long count = min(head->count, capacity);
    if (k >= count)
        return;
    pairs[k] = key_pair(keys[k], bits);
}

// The first bad box (update.cuh's check, the host's rule) into head.
__global__ void convert_kernel(const bpx_box *boxes, uint32_t n, float *lx, float *ly, float *lz,
                               float *hx, float *hy, float *hz, bpx_cuda_head *head)
{
    uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n)
        return;
    bpx_box b = boxes[i];
    if (lx) { // else only the check
        lx[i] = b.min[0], ly[i] = b.min[1], lz[i] = b.min[2];
        hx[i] = b.max[0], hy[i] = b.max[1], hz[i] = b.max[2];
    }
    if (uint32_t code = bpx_update::box_check(b.min, b.max))
        atomicMin(&head->bad, ((unsigned long long)i << 32) | code);
}

// The paper's updater (update.cuh): centres and stored minima to the SoA boxes, checking each
// box (the first object whose box is not finite into head, code 4 + axis: NOT_FINITE).
__global__ void update_kernel(const float *centres, const float *minima, uint32_t stride,
                              uint32_t n, float *lx, float *ly, float *lz, float *hx, float *hy,
                              float *hz, bpx_cuda_head *head)
{
    uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n)
        return;
    float lo[3], hi[3];
    int bad = bpx_update::box_of(centres, minima, minima + stride, minima + 2 * (size_t)stride, i,
                                 lo, hi);
    if (lx) { // else only the check
        lx[i] = lo[0], ly[i] = lo[1], lz[i] = lo[2];
        hx[i] = hi[0], hy[i] = hi[1], hz[i] = hi[2];
    }
    if (bad >= 0)
        atomicMin(&head->bad, ((unsigned long long)i << 32) | (4u + (uint32_t)bad));
}

__global__ void probe_kernel(int *out)
{
    *out = 42;
}

} // namespace

cudaError_t bpx__cuda_launch_probe(int *out)
{
    probe_kernel<<<1, 1>>>(out);
    return cudaGetLastError();
}

cudaError_t bpx__cuda_sort_temp_bytes(uint32_t boxes, unsigned long long keys, size_t *bytes)
{
    size_t a = 0, b = 0;
    cub::DoubleBuffer<uint32_t> mk(nullptr, nullptr), ids(nullptr, nullptr);
    cudaError_t e = cub::DeviceRadixSort::SortPairs(nullptr, a, mk, ids, (int64_t)boxes, 0,
                                                    BPX_CUDA_MORTON_SORT_BITS);
    cub::DoubleBuffer<unsigned long long> pk(nullptr, nullptr);
    if (e == cudaSuccess)
        e = cub::DeviceRadixSort::SortKeys(nullptr, b, pk, (int64_t)keys, 0, 64);
    *bytes = a > b ? a : b;
    return e;
}

cudaError_t bpx__cuda_sort_morton(cudaStream_t stream, void *temp, size_t bytes, bpx_cuda_tree *t)
{
    cub::DoubleBuffer<uint32_t> mk(t->morton[0], t->morton[1]), ids(t->ids[0], t->ids[1]);
    cudaError_t e = cub::DeviceRadixSort::SortPairs(temp, bytes, mk, ids, (int64_t)t->n, 0,
                                                    BPX_CUDA_MORTON_SORT_BITS, stream);
    t->current = mk.selector;
    if (e == cudaSuccess && ids.selector != mk.selector) // CUB keeps both in step; the tree relies on it
        e = cudaErrorUnknown;
    return e;
}

cudaError_t bpx__cuda_sort_pair_keys(cudaStream_t stream, void *temp, size_t bytes,
                                     unsigned long long *const keys[2], unsigned long long items,
                                     int end_bit, int *current)
{
    cub::DoubleBuffer<unsigned long long> k(keys[0], keys[1]);
    cudaError_t e = items > 1 ? cub::DeviceRadixSort::SortKeys(temp, bytes, k, (int64_t)items, 0,
                                                               end_bit, stream)
                              : cudaSuccess;
    *current = k.selector;
    return e;
}

cudaError_t bpx__cuda_launch_small(cudaStream_t stream, const float *const lo[3],
                                   const float *const hi[3], const float *centres,
                                   const float *minima, uint32_t stride, uint32_t n,
                                   bpx_cuda_small_scratch *scratch, bpx_cuda_head *head,
                                   bpx_pair *pairs)
{
    bpx_small::input in = {{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}, centres, minima, stride};
    unsigned int blocks = (n + 31) / 32; // a warp per row
    small_kernel<<<blocks, BPX_CUDA_SMALL_MAX, 0, stream>>>(in, n, scratch, head, pairs);
    return cudaGetLastError();
}

cudaError_t bpx__cuda_launch_bounds(cudaStream_t stream, const bpx_cuda_tree *t)
{
    unsigned int grid = min(grid_for(t->n), 1024u);
    bounds_kernel<<<grid, block_threads, 0, stream>>>(t->lo[0], t->lo[1], t->lo[2], t->hi[0],
                                                      t->hi[1], t->hi[2], t->n, t->scene);
    return cudaGetLastError();
}

cudaError_t bpx__cuda_launch_morton(cudaStream_t stream, const bpx_cuda_tree *t)
{
    morton_kernel<<<grid_for(t->n), block_threads, 0, stream>>>(t->lo[0], t->lo[1], t->lo[2],
                                                                t->hi[0], t->hi[1], t->hi[2], t->n,
                                                                t->scene, t->morton[0], t->ids[0]);
    return cudaGetLastError();
}

cudaError_t bpx__cuda_launch_build(cudaStream_t stream, const bpx_cuda_tree *t)
{
    const uint32_t *ids = t->ids[t->current];
    gather_kernel<<<grid_for(t->n), block_threads, 0, stream>>>(t->lo[0], t->lo[1], t->lo[2],
                                                                t->hi[0], t->hi[1], t->hi[2], t->n,
                                                                ids, t->leaf_lo, t->leaf_hi);
    if (cudaError_t e = cudaGetLastError(); e != cudaSuccess)
        return e;
    build_kernel<<<grid_for(t->n), block_threads, 0, stream>>>(t->morton[t->current], (int)t->n,
                                                               t->leaf_parent, t->node_parent);
    if (cudaError_t e = cudaGetLastError(); e != cudaSuccess)
        return e;
    refit_kernel<<<grid_for(t->n), block_threads, 0, stream>>>(
        t->leaf_lo, t->leaf_hi, t->n, t->leaf_parent, t->node_parent, t->nodes, t->flags);
    return cudaGetLastError();
}

cudaError_t bpx__cuda_launch_traverse(cudaStream_t stream, const bpx_cuda_tree *t, int bits,
                                      unsigned long long *keys, unsigned long long capacity,
                                      bpx_cuda_head *head)
{
    traverse_kernel<<<grid_for(t->n), block_threads, 0, stream>>>(
        t->nodes, t->leaf_lo, t->leaf_hi, t->leaf_parent, t->node_parent, t->n, bits, keys,
        capacity, head);
    return cudaGetLastError();
}

cudaError_t bpx__cuda_launch_unpack(cudaStream_t stream, const unsigned long long *keys, int bits,
                                    unsigned long long capacity, const bpx_cuda_head *head,
                                    bpx_pair *pairs)
{
    if (capacity == 0)
        return cudaSuccess;
    unsigned long long grid = (capacity + block_threads - 1) / block_threads;
    unpack_kernel<<<(unsigned int)grid, block_threads, 0, stream>>>(keys, bits, capacity, head,
                                                                    pairs);
    return cudaGetLastError();
}

cudaError_t bpx__cuda_launch_convert(cudaStream_t stream, const bpx_box *boxes, uint32_t n,
                                     float *const lo[3], float *const hi[3], bpx_cuda_head *head)
{
    convert_kernel<<<grid_for(n), block_threads, 0, stream>>>(boxes, n, lo[0], lo[1], lo[2], hi[0],
                                                              hi[1], hi[2], head);
    return cudaGetLastError();
}

cudaError_t bpx__cuda_launch_update(cudaStream_t stream, const float *centres,
                                    const float *minima, uint32_t stride, uint32_t n,
                                    float *const lo[3], float *const hi[3], bpx_cuda_head *head)
{
    update_kernel<<<grid_for(n), block_threads, 0, stream>>>(
        centres, minima, stride, n, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], head);
    return cudaGetLastError();
}
