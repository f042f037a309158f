// The cuda backend's kernels (kernels.cu), launched by the cycle (cycle.cu). SPDX-License-Identifier: MIT
//
// Two comparators, both exact (float comparisons of the caller's own coordinates; node bounds
// are minima and maxima of them, so culling never rounds) and both in (i, j) order:
//   small  n <= BPX_CUDA_SMALL_MAX: a warp per box tests the later boxes 32 at a time into hit
//          words; the last block to finish scans the rows' counts and writes every pair at its
//          place: one launch per cycle.
//   tree   a linear BVH (Karras 2012) built every cycle over the boxes' centres in Morton
//          order; each box walks it for the boxes later in that order, so every pair is found
//          once; the pairs, packed as 64-bit (i, j) keys, are radix sorted into (i, j) order.
#pragma once

#include <cstdint>

#include "bpx/types.h"

enum { BPX_CUDA_SMALL_MAX = 1024 };

/// The bits the Morton sort orders by: all 32. Live codes have 30, inert boxes get ~0u; a sort
/// over 30 bits ties an inert box with a live one in the top cell (0x3FFFFFFF), leaves the codes
/// unsorted, and the node build then makes no tree (test_cuda_twin sorts by the same bits).
enum { BPX_CUDA_MORTON_SORT_BITS = 32 };

/// The small comparator's scratch in device memory: each row's (box's) hit words over the later
/// boxes and its count; `done` counts the blocks that finished (zero between cycles).
struct bpx_cuda_small_scratch {
    uint32_t done;
    uint32_t counts[BPX_CUDA_SMALL_MAX];
    uint32_t masks[BPX_CUDA_SMALL_MAX * (BPX_CUDA_SMALL_MAX / 32)];
};

/// The result block at the head of the pair buffer, read back in the same copy as the first
/// pairs: the pair count, and for device input the first bad box as (index << 32) | code, code
/// 4 + axis for a non-finite coordinate, 8 + axis for min > max (all ones: every box valid).
struct bpx_cuda_head {
    unsigned long long count;
    unsigned long long bad;
};

/// One internal node of the tree: the bounds of both children and their codes (index, with
/// BPX_CUDA_LEAF set for a leaf), as four float4 loads in one 64-byte line.
struct bpx_cuda_node {
    float4 lo[2]; // .w: child code (as int bits) in lo[side]
    float4 hi[2];
};
#define BPX_CUDA_LEAF 0x80000000u

/// Device buffers of one context (sizes in elements).
struct bpx_cuda_tree {
    uint32_t n;
    const float *lo[3], *hi[3];   // the boxes, SoA
    uint32_t *scene;              // 6 order keys: centre minima, then maxima
    uint32_t *morton[2], *ids[2]; // CUB double buffers
    int current;                  // which of the double buffers holds the sorted order
    float4 *leaf_lo, *leaf_hi;    // boxes in Morton order
    bpx_cuda_node *nodes;         // n - 1 internal nodes, root 0
    uint32_t *leaf_parent;        // (parent << 1) | side
    uint32_t *node_parent;
    uint32_t *flags;              // refit arrivals, zeroed each cycle
};

/// The probe's kernel, on the legacy stream: writes 42 to *out (a device int).
cudaError_t bpx__cuda_launch_probe(int *out);

/// Temporary storage, in bytes, for both sorts: up to `boxes` Morton codes with their ids, up to
/// `keys` pair keys.
cudaError_t bpx__cuda_sort_temp_bytes(uint32_t boxes, unsigned long long keys, size_t *bytes);
/// CUB's radix sort of the t->n Morton codes with their ids, stable, by
/// BPX_CUDA_MORTON_SORT_BITS; t->current says which of the double buffers holds the result.
cudaError_t bpx__cuda_sort_morton(cudaStream_t stream, void *temp, size_t bytes,
                                  bpx_cuda_tree *t);
/// CUB's radix sort of `items` pair keys in keys[0] by their low end_bit bits (keys[1] its other
/// buffer); *current says which buffer holds the result.
cudaError_t bpx__cuda_sort_pair_keys(cudaStream_t stream, void *temp, size_t bytes,
                                     unsigned long long *const keys[2], unsigned long long items,
                                     int end_bit, int *current);

/// The small comparator (n >= 2); with centres (not NULL) it makes the boxes itself from them
/// and the minima (three planes `stride` apart), checking each (the paper's updater, in the same
/// launch). scratch->done must be zero (it is left so).
cudaError_t bpx__cuda_launch_small(cudaStream_t stream, const float *const lo[3],
                                   const float *const hi[3], const float *centres,
                                   const float *minima, uint32_t stride, uint32_t n,
                                   bpx_cuda_small_scratch *scratch, bpx_cuda_head *head,
                                   bpx_pair *pairs);

cudaError_t bpx__cuda_launch_bounds(cudaStream_t stream, const bpx_cuda_tree *t);
cudaError_t bpx__cuda_launch_morton(cudaStream_t stream, const bpx_cuda_tree *t);
/// After the sort: gathers the boxes into Morton order, builds the hierarchy and refits it.
cudaError_t bpx__cuda_launch_build(cudaStream_t stream, const bpx_cuda_tree *t);
/// Every pair as a key (i << bits) | j, i < j, written below capacity; head->count counts all.
cudaError_t bpx__cuda_launch_traverse(cudaStream_t stream, const bpx_cuda_tree *t, int bits,
                                      unsigned long long *keys, unsigned long long capacity,
                                      bpx_cuda_head *head);
/// Sorted keys back to pairs: the first min(count, capacity).
cudaError_t bpx__cuda_launch_unpack(cudaStream_t stream, const unsigned long long *keys, int bits,
                                    unsigned long long capacity, const bpx_cuda_head *head,
                                    bpx_pair *pairs);
/// Device input: AoS boxes to the SoA arrays, checking each (first bad box into head).
cudaError_t bpx__cuda_launch_convert(cudaStream_t stream, const bpx_box *boxes, uint32_t n,
                                     float *const lo[3], float *const hi[3], bpx_cuda_head *head);
/// The paper's updater: n centres (x, y, z each) and the minima (three planes `stride` apart) to
/// the SoA arrays (lo NULL: only the check), the first object whose box is not finite into head.
cudaError_t bpx__cuda_launch_update(cudaStream_t stream, const float *centres,
                                    const float *minima, uint32_t stride, uint32_t n,
                                    float *const lo[3], float *const hi[3], bpx_cuda_head *head);
