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

/// Insertion sort of (keys, ids) by key that gives up after max_moves element moves, for
/// nearly sorted input. Returns true when sorted; false leaves a permutation of the input.
bool bpx__insertion_sort(uint32_t *keys, uint32_t *ids, uint32_t n, uint64_t max_moves);
