// Sorting helpers for the sweep backends.
#pragma once

#include <stdbool.h>
#include <stdint.h>
#include <string.h>

/// A float's bits mapped so that unsigned order is float order (-0.0 just below +0.0).
static inline uint32_t bpx__float_key(float x)
{
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    return u ^ ((uint32_t)((int32_t)u >> 31) | 0x80000000u);
}

/// Stable LSD radix sort of (keys, ids) by key, three passes of 11 bits.
void bpx__radix_sort(uint32_t *keys, uint32_t *ids, uint32_t *scratch_keys,
                     uint32_t *scratch_ids, uint32_t n);

enum {
    BPX_RADIX_BITS = 11,
    BPX_RADIX_BUCKETS = 1 << BPX_RADIX_BITS,
    BPX_RADIX_PASSES = (32 + BPX_RADIX_BITS - 1) / BPX_RADIX_BITS,
    BPX_RADIX_LINE = 8,               // words in a 64-byte cache line
    BPX_RADIX_STREAM_WORDS = 1 << 17, // 1 MiB of words: from here on, passes stream (lines)
};

/// A cache line per bucket, where words gather before they are written (128 KiB).
typedef uint64_t bpx_radix_lines[BPX_RADIX_BUCKETS][BPX_RADIX_LINE];

/// Work memory of bpx__radix_sort_words: each pass's bucket counts (24 KiB), and the lines
/// (64-byte aligned), wanted only from BPX_RADIX_STREAM_WORDS words on (NULL: plain stores).
typedef struct bpx_radix_work {
    uint32_t counts[BPX_RADIX_PASSES][BPX_RADIX_BUCKETS];
    bpx_radix_lines *lines;
} bpx_radix_work;

/// Stable LSD radix sort of n 64-bit words by their high 32 bits, from src into dst (src is
/// left in any order; both 64-byte aligned when work->lines is set). Passes whose digit is the
/// same in every word are skipped.
void bpx__radix_sort_words(uint64_t *src, uint64_t *dst, uint32_t n, bpx_radix_work *work);

/// Insertion sort of (keys, ids) by key that gives up after max_moves element moves, for
/// nearly sorted input. Returns true when sorted; false leaves a permutation of the input.
bool bpx__insertion_sort(uint32_t *keys, uint32_t *ids, uint32_t n, uint64_t max_moves);
