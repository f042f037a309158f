// The fake device's kernels: every launch and sort of src/cuda/kernels.cuh done at once on the
// host, with the same per-item code as the real kernels (tree.cuh, small.cuh, update.cuh) in
// loops, and std::stable_sort where CUB's radix sort runs (both stable, by the same bits).
// SPDX-License-Identifier: MIT
//
// With runtime.c (and its files) in place of the CUDA runtime, the cuda backend's host code
// (cycle.cu, backend.c) runs unchanged on machines without a GPU: its buffer sizes, copies,
// regrowth, device-resident protocol and error paths are tested in CI. Strict, to find the host code's
// mistakes: each array a kernel touches must lie in one device allocation (else abort), the
// scratch and flags the host must have cleared are checked, each sort leaves its result in the
// other buffer than the last one did and a pattern in its other buffer (a caller that ignored
// CUB's selector would read rubbish), each sort refuses temporary storage sized for fewer items,
// and a launch over no items is refused as the GPU refuses an empty grid.
// What it cannot show is the kernels' own concurrency (warps, atomics, fences): that is the GPU
// run's (bench/gpu/run.sh).
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <numeric>
#include <vector>

#include "cuda/kernels.cuh"
#include "cuda/small.cuh"
#include "cuda/tree.cuh"
#include "cuda/update.cuh"

#include "fake_cuda.h"

namespace {

// An access by a kernel on `stream`: in device memory, aligned, and in stream order
// (stream_order.c).
template <class T>
void need(cudaStream_t stream, const T *p, unsigned long long count, bool write, const char *what)
{
    bpx_fake_cuda_access(stream, p, sizeof(T) * (size_t)count, write, what);
    if (reinterpret_cast<uintptr_t>(p) % alignof(T) != 0) { // a misaligned address on the GPU
        fprintf(stderr, "fake cuda: %s at %p is not aligned to %zu bytes\n", what,
                static_cast<const void *>(p), alignof(T));
        abort();
    }
}

// The centre of box i of the tree's SoA boxes, as the bounds and Morton kernels take it; false
// for an inert box (no centre).
bool centre_of(const bpx_cuda_tree *t, uint32_t i, float c[3])
{
    if (!bpx_tree::live(t->lo[0][i], t->hi[0][i]))
        return false;
    const float blo[3] = {t->lo[0][i], t->lo[1][i], t->lo[2][i]};
    const float bhi[3] = {t->hi[0][i], t->hi[1][i], t->hi[2][i]};
    bpx_tree::centre(blo, bhi, c);
    return true;
}

// A launch whose grid would be empty: the GPU refuses it (the host must not make it).
cudaError_t empty_grid(uint32_t n)
{
    return n == 0 ? cudaErrorInvalidConfiguration : cudaSuccess;
}

template <class T>
void reads(cudaStream_t stream, const T *p, unsigned long long count, const char *what)
{
    need(stream, p, count, false, what);
}

template <class T>
void writes(cudaStream_t stream, const T *p, unsigned long long count, const char *what)
{
    need(stream, p, count, true, what); // a read-modify-write (an atomic) is a write
}

void reads_planes(cudaStream_t stream, const float *const planes[3], uint32_t n, const char *what)
{
    for (int a = 0; a < 3; a++)
        reads(stream, planes[a], n, what);
}

void writes_planes(cudaStream_t stream, const float *const planes[3], uint32_t n, const char *what)
{
    for (int a = 0; a < 3; a++)
        writes(stream, planes[a], n, what);
}

void bad_box(bpx_cuda_head *head, uint32_t i, uint32_t code)
{
    unsigned long long bad = ((unsigned long long)i << 32) | code;
    head->bad = bad < head->bad ? bad : head->bad;
}

// Where a sort leaves its result: each sort the other buffer than the last (CUB picks by its
// passes), so that both selectors are met whatever the sizes.
int result_buffer()
{
    static int next; // the fake runs on the calling thread: a test's worlds take turns
    next ^= 1;
    return next;
}

// The temporary storage a sort of `items` keys of `key_bytes` asks for: some, growing with the
// items as CUB's does, so that storage sized for fewer items is refused as CUB refuses it.
size_t temp_need(unsigned long long items, size_t key_bytes)
{
    return 256 + 2 * key_bytes * (size_t)items;
}

// What CUB leaves in a sort's other buffer: its passes' leftovers, here a pattern.
template <class T> void scramble(T *buffer, unsigned long long count)
{
    memset(buffer, 0xa5, sizeof(T) * (size_t)count);
}

} // namespace

cudaError_t bpx__cuda_launch_probe(int *out)
{
    writes(nullptr, out, 1, "probe");
    *out = 42;
    return cudaSuccess;
}

cudaError_t bpx__cuda_sort_temp_bytes(uint32_t boxes, unsigned long long keys, size_t *bytes)
{
    *bytes = std::max(temp_need(boxes, 8), temp_need(keys, 8));
    return cudaSuccess;
}

cudaError_t bpx__cuda_sort_morton(cudaStream_t stream, void *temp, size_t bytes, bpx_cuda_tree *t)
{
    const uint32_t n = t->n;
    if (n == 0)
        return cudaSuccess; // CUB returns at once, the selector unmoved
    if (bytes < temp_need(n, 8))
        return cudaErrorInvalidValue;
    writes(stream, static_cast<unsigned char *>(temp), temp_need(n, 8), "sort_morton temp");
    for (int b = 0; b < 2; b++) {
        writes(stream, t->morton[b], n, "sort_morton codes");
        writes(stream, t->ids[b], n, "sort_morton ids");
    }
    const uint32_t mask =
        BPX_CUDA_MORTON_SORT_BITS < 32 ? (1u << BPX_CUDA_MORTON_SORT_BITS) - 1 : ~0u;
    std::vector<uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
        return (t->morton[0][a] & mask) < (t->morton[0][b] & mask);
    });
    std::vector<uint32_t> codes(n), ids(n);
    for (uint32_t k = 0; k < n; k++)
        codes[k] = t->morton[0][order[k]], ids[k] = t->ids[0][order[k]];
    t->current = result_buffer();
    std::copy(codes.begin(), codes.end(), t->morton[t->current]);
    std::copy(ids.begin(), ids.end(), t->ids[t->current]);
    scramble(t->morton[!t->current], n);
    scramble(t->ids[!t->current], n);
    return cudaSuccess;
}

cudaError_t bpx__cuda_sort_pair_keys(cudaStream_t stream, void *temp, size_t bytes,
                                     unsigned long long *const keys[2], unsigned long long items,
                                     int end_bit, int *current)
{
    *current = 0;
    if (items <= 1)
        return cudaSuccess; // CUB is not called for fewer than two
    if (bytes < temp_need(items, 8))
        return cudaErrorInvalidValue;
    writes(stream, static_cast<unsigned char *>(temp), temp_need(items, 8), "sort_pair_keys temp");
    writes(stream, keys[0], items, "sort_pair_keys keys");
    writes(stream, keys[1], items, "sort_pair_keys keys");
    const unsigned long long mask = end_bit < 64 ? (1ull << end_bit) - 1 : ~0ull;
    std::vector<unsigned long long> sorted(keys[0], keys[0] + items);
    std::stable_sort(sorted.begin(), sorted.end(), [&](unsigned long long a, unsigned long long b) {
        return (a & mask) < (b & mask);
    });
    *current = result_buffer();
    std::copy(sorted.begin(), sorted.end(), keys[*current]);
    scramble(keys[!*current], items);
    return cudaSuccess;
}

// The small kernel's result (kernels.cu): each row's hit words and count into the scratch, the
// rows' counts scanned, each pair at its place, the count into the head, `done` left zero.
cudaError_t bpx__cuda_launch_small(cudaStream_t stream, const float *const lo[3],
                                   const float *const hi[3], const float *centres,
                                   const float *minima, uint32_t stride, uint32_t n,
                                   bpx_cuda_small_scratch *scratch, bpx_cuda_head *head,
                                   bpx_pair *pairs)
{
    constexpr uint32_t row_words = BPX_CUDA_SMALL_MAX / 32;
    if (n < 2 || n > BPX_CUDA_SMALL_MAX) {
        fprintf(stderr, "fake cuda: small comparator launched for n = %u\n", n);
        abort();
    }
    writes(stream, scratch, 1, "small scratch");
    writes(stream, head, 1, "small head");
    if (centres) {
        reads(stream, centres, 3ull * n, "small centres");
        reads(stream, minima, 2ull * stride + n, "small minima");
    } else {
        reads_planes(stream, lo, n, "small boxes");
        reads_planes(stream, hi, n, "small boxes");
    }
    if (scratch->done != 0) {
        fprintf(stderr, "fake cuda: small comparator launched with done = %u\n", scratch->done);
        abort();
    }
    bpx_small::input in = {{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}, centres, minima, stride};
    uint32_t total = bpx_small::rows_on_host(
        in, n, scratch->masks, row_words, scratch->counts,
        [head](uint32_t row, int axis) { bad_box(head, row, 4u + (uint32_t)axis); });
    writes(stream, pairs, total, "small pairs");
    bpx_small::pairs_on_host(n, scratch->masks, row_words,
                             [pairs](uint32_t at, bpx_pair p) { pairs[at] = p; });
    head->count = total;
    scratch->done = 0;
    return cudaSuccess;
}

cudaError_t bpx__cuda_launch_bounds(cudaStream_t stream, const bpx_cuda_tree *t)
{
    if (cudaError_t e = empty_grid(t->n))
        return e;
    reads_planes(stream, t->lo, t->n, "bounds boxes");
    reads_planes(stream, t->hi, t->n, "bounds boxes");
    writes(stream, t->scene, 6, "bounds scene");
    for (uint32_t i = 0; i < t->n; i++) {
        float c[3];
        if (!centre_of(t, i, c))
            continue;
        for (int a = 0; a < 3; a++) {
            uint32_t k = bpx_tree::order_key(c[a]);
            t->scene[a] = std::min(t->scene[a], k);
            t->scene[3 + a] = std::max(t->scene[3 + a], k);
        }
    }
    return cudaSuccess;
}

cudaError_t bpx__cuda_launch_morton(cudaStream_t stream, const bpx_cuda_tree *t)
{
    if (cudaError_t e = empty_grid(t->n))
        return e;
    reads_planes(stream, t->lo, t->n, "morton boxes");
    reads_planes(stream, t->hi, t->n, "morton boxes");
    writes(stream, t->morton[0], t->n, "morton codes");
    writes(stream, t->ids[0], t->n, "morton ids");
    reads(stream, t->scene, 6, "morton scene");
    for (uint32_t i = 0; i < t->n; i++) {
        t->ids[0][i] = i;
        float c[3];
        t->morton[0][i] = centre_of(t, i, c) ? bpx_tree::morton(c, t->scene) : ~0u;
    }
    return cudaSuccess;
}

cudaError_t bpx__cuda_launch_build(cudaStream_t stream, const bpx_cuda_tree *t)
{
    const uint32_t n = t->n;
    if (cudaError_t e = empty_grid(n))
        return e;
    const uint32_t *ids = t->ids[t->current], *codes = t->morton[t->current];
    reads_planes(stream, t->lo, n, "build boxes");
    reads_planes(stream, t->hi, n, "build boxes");
    reads(stream, ids, n, "build ids");
    reads(stream, codes, n, "build codes");
    writes(stream, t->leaf_lo, n, "build leaves");
    writes(stream, t->leaf_hi, n, "build leaves");
    writes(stream, t->nodes, n - 1, "build nodes");
    writes(stream, t->leaf_parent, n, "build parents");
    writes(stream, t->node_parent, n - 1, "build parents");
    writes(stream, t->flags, n - 1, "build flags");
    for (uint32_t k = 0; k + 1 < n; k++)
        if (t->flags[k] != 0) {
            fprintf(stderr, "fake cuda: the refit's arrival flags were not cleared\n");
            abort();
        }
    for (uint32_t k = 0; k < n; k++) {
        uint32_t i = ids[k];
        t->leaf_lo[k] = make_float4(t->lo[0][i], t->lo[1][i], t->lo[2][i], bpx_tree::float_of(i));
        t->leaf_hi[k] = make_float4(t->hi[0][i], t->hi[1][i], t->hi[2][i], 0.0f);
    }
    for (int k = 0; k < (int)n - 1; k++)
        bpx_tree::build_node(codes, (int)n, k, t->leaf_parent, t->node_parent);
    uint32_t *flags = t->flags;
    for (uint32_t k = 0; k < n; k++)
        bpx_tree::refit_leaf(k, t->leaf_lo, t->leaf_hi, t->leaf_parent, t->node_parent, t->nodes,
                             [flags](uint32_t p) { return flags[p]++; });
    return cudaSuccess;
}

cudaError_t bpx__cuda_launch_traverse(cudaStream_t stream, const bpx_cuda_tree *t, int bits,
                                      unsigned long long *keys, unsigned long long capacity,
                                      bpx_cuda_head *head)
{
    if (cudaError_t e = empty_grid(t->n))
        return e;
    writes(stream, head, 1, "traverse head");
    reads(stream, t->nodes, t->n - 1, "traverse nodes");
    reads(stream, t->leaf_lo, t->n, "traverse leaves");
    reads(stream, t->leaf_hi, t->n, "traverse leaves");
    reads(stream, t->leaf_parent, t->n, "traverse parents");
    reads(stream, t->node_parent, t->n - 1, "traverse parents");
    std::vector<unsigned long long> found;
    for (uint32_t k = 0; k + 1 < t->n; k++)
        bpx_tree::walk(
            k, t->nodes, t->leaf_lo, t->leaf_hi, t->leaf_parent, t->node_parent,
            [&](uint32_t i, uint32_t j) { found.push_back(bpx_tree::pair_key(i, j, bits)); });
    // Each key at the place the counter gives it; those at or past capacity are only counted.
    unsigned long long from = head->count, to = std::min(from + found.size(), capacity);
    if (to > from) {
        writes(stream, keys + from, to - from, "traverse keys");
        std::copy(found.begin(), found.begin() + (to - from), keys + from);
    }
    head->count = from + found.size();
    return cudaSuccess;
}

cudaError_t bpx__cuda_launch_unpack(cudaStream_t stream, const unsigned long long *keys, int bits,
                                    unsigned long long capacity, const bpx_cuda_head *head,
                                    bpx_pair *pairs)
{
    if (capacity == 0)
        return cudaSuccess;
    reads(stream, head, 1, "unpack head");
    unsigned long long count = std::min(head->count, capacity);
    reads(stream, keys, count, "unpack keys");
    writes(stream, pairs, count, "unpack pairs");
    for (unsigned long long k = 0; k < count; k++)
        pairs[k] = bpx_tree::key_pair(keys[k], bits);
    return cudaSuccess;
}

cudaError_t bpx__cuda_launch_convert(cudaStream_t stream, const bpx_box *boxes, uint32_t n,
                                     float *const lo[3], float *const hi[3], bpx_cuda_head *head)
{
    if (cudaError_t e = empty_grid(n))
        return e;
    reads(stream, boxes, n, "convert boxes");
    writes(stream, head, 1, "convert head");
    if (lo[0]) {
        writes_planes(stream, lo, n, "convert planes");
        writes_planes(stream, hi, n, "convert planes");
    }
    for (uint32_t i = 0; i < n; i++) {
        const bpx_box &b = boxes[i];
        if (lo[0])
            for (int a = 0; a < 3; a++)
                lo[a][i] = b.min[a], hi[a][i] = b.max[a];
        if (uint32_t code = bpx_update::box_check(b.min, b.max))
            bad_box(head, i, code);
    }
    return cudaSuccess;
}

cudaError_t bpx__cuda_launch_update(cudaStream_t stream, const float *centres, const float *minima,
                                    uint32_t stride, uint32_t n, float *const lo[3],
                                    float *const hi[3], bpx_cuda_head *head)
{
    if (cudaError_t e = empty_grid(n))
        return e;
    reads(stream, centres, 3ull * n, "update centres");
    reads(stream, minima, 2ull * stride + n, "update minima");
    writes(stream, head, 1, "update head");
    if (lo[0]) {
        writes_planes(stream, lo, n, "update planes");
        writes_planes(stream, hi, n, "update planes");
    }
    for (uint32_t i = 0; i < n; i++) {
        float blo[3], bhi[3];
        int bad = bpx_update::box_of(centres, minima, minima + stride, minima + 2 * (size_t)stride,
                                     i, blo, bhi);
        if (lo[0])
            for (int a = 0; a < 3; a++)
                lo[a][i] = blo[a], hi[a][i] = bhi[a];
        if (bad >= 0)
            bad_box(head, i, 4u + (uint32_t)bad);
    }
    return cudaSuccess;
}
