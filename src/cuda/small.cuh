// The small comparator's per-lane steps (n <= BPX_CUDA_SMALL_MAX boxes): __host__ __device__, so
// the kernel (kernels.cu) and test_cuda_twin, which runs its lanes in loops, index the same way.
// SPDX-License-Identifier: MIT
//
// Row i (box i) is one warp's: lane l tests box j = i + 1 + 32k + l at step k, and the warp's
// ballot is the row's k-th hit word. A row's count is the sum of its words' bits; the rows'
// exclusive scan is where each row's pairs start; a hit's place in its row is the number of hits
// before it in its word plus the words before. So the pairs come out in (i, j) order.
#pragma once

#include <cstdint>

#include "bpx/types.h"
#include "update.cuh"

namespace bpx_small {

/// Hit words of row i among n boxes: one per 32 later boxes.
__host__ __device__ inline uint32_t words(uint32_t i, uint32_t n)
{
    return (n - i - 1 + 31) / 32;
}

/// The box lane `lane` tests at step k of row i.
__host__ __device__ inline uint32_t other(uint32_t i, uint32_t k, uint32_t lane)
{
    return i + 1 + 32 * k + lane;
}

/// The hits before lane `lane` in a hit word.
__host__ __device__ inline uint32_t before(uint32_t word, uint32_t lane)
{
#ifdef __CUDA_ARCH__
    return __popc(word & ((1u << lane) - 1u));
#else
    return (uint32_t)__builtin_popcount(word & ((1u << lane) - 1u));
#endif
}

/// Where the boxes come from: SoA arrays, or centres and minima (the paper's updater, fused in).
struct input {
    const float *lo[3], *hi[3];
    const float *centres, *minima; // centres non-NULL: boxes made from them
    uint32_t stride;               // of the minima's planes
};

/// Box j of the input; the first axis whose box is not finite (centres only), else -1.
__host__ __device__ inline int box(const input &in, uint32_t j, float lo[3], float hi[3])
{
    if (in.centres)
        return bpx_update::box_of(in.centres, in.minima, in.minima + in.stride,
                                  in.minima + 2 * (size_t)in.stride, j, lo, hi);
    for (int a = 0; a < 3; a++)
        lo[a] = in.lo[a][j], hi[a] = in.hi[a][j];
    return -1;
}

/// Algorithm 1: closed intervals on every axis (touching boxes overlap, -0.0 equals 0.0).
__host__ __device__ inline bool overlap(const float alo[3], const float ahi[3], const float blo[3],
                                        const float bhi[3])
{
    return alo[0] <= bhi[0] && blo[0] <= ahi[0] && alo[1] <= bhi[1] && blo[1] <= ahi[1] &&
           alo[2] <= bhi[2] && blo[2] <= ahi[2];
}

// ---- the kernel's work on the host, lanes and warps in loops (test_cuda_twin, the fake device) --

/// Each row's hit words (a ballot: bit l for lane l; row i's at masks + i * row_words) and its
/// count; bad(row, axis) for each box the updater finds not finite. Returns the pairs.
template <class Bad>
inline uint32_t rows_on_host(const input &in, uint32_t n, uint32_t *masks, uint32_t row_words,
                             uint32_t *counts, Bad bad)
{
    uint32_t total = 0;
    for (uint32_t row = 0; row < n; row++) {
        float alo[3], ahi[3];
        if (int axis = box(in, row, alo, ahi); axis >= 0)
            bad(row, axis);
        uint32_t count = 0;
        for (uint32_t k = 0; k < words(row, n); k++) {
            uint32_t word = 0;
            for (uint32_t lane = 0; lane < 32; lane++) {
                uint32_t j = other(row, k, lane);
                float blo[3], bhi[3];
                if (j < n && (box(in, j, blo, bhi), overlap(alo, ahi, blo, bhi)))
                    word |= 1u << lane;
            }
            masks[(size_t)row * row_words + k] = word;
            count += (uint32_t)__builtin_popcount(word);
        }
        counts[row] = count;
        total += count;
    }
    return total;
}

/// The rows' counts scanned, and put(place, pair) for each hit: the pairs in (i, j) order.
template <class Put>
inline void pairs_on_host(uint32_t n, const uint32_t *masks, uint32_t row_words, Put put)
{
    uint32_t at = 0;
    for (uint32_t i = 0; i < n; i++)
        for (uint32_t k = 0; k < words(i, n); k++) {
            uint32_t word = masks[(size_t)i * row_words + k];
            for (uint32_t lane = 0; lane < 32; lane++)
                if ((word >> lane) & 1u)
                    put(at + before(word, lane), bpx_pair{i, other(i, k, lane)});
            at += (uint32_t)__builtin_popcount(word);
        }
}

} // namespace bpx_small
