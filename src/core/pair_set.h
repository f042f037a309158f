// A set of unordered id pairs (the world's excluded pairs): open addressing with linear probing,
// at most half full, deletion by shifting the cluster back (no tombstones), so a lookup in the
// hot loop is one hash and, nearly always, one cache line.
#pragma once

#include <stdbool.h>
#include <stdint.h>

typedef struct bpx_pair_set {
    uint64_t *keys;    // capacity slots; BPX_PAIR_SET_EMPTY marks a free one
    uint32_t capacity; // a power of two, or 0
    uint32_t count;
} bpx_pair_set;

#define BPX_PAIR_SET_EMPTY UINT64_MAX

/// The key of {i, j}: the smaller id in the high half. i != j.
static inline uint64_t bpx__pair_key(uint32_t i, uint32_t j)
{
    return i < j ? (uint64_t)i << 32 | j : (uint64_t)j << 32 | i;
}

static inline uint32_t bpx__pair_slot(uint64_t key, uint32_t capacity)
{
    return (uint32_t)((key * 0x9E3779B97F4A7C15ull) >> 32) & (capacity - 1);
}

static inline bool bpx__pair_set_has(const bpx_pair_set *s, uint64_t key)
{
    if (!s->count)
        return false;
    for (uint32_t slot = bpx__pair_slot(key, s->capacity);; slot = (slot + 1) & (s->capacity - 1)) {
        if (s->keys[slot] == key)
            return true;
        if (s->keys[slot] == BPX_PAIR_SET_EMPTY)
            return false;
    }
}

/// Room for `extra` more keys without a rehash. False (the set unchanged) when out of memory.
bool bpx__pair_set_reserve(bpx_pair_set *s, uint32_t extra);
/// Adds a key (room must have been reserved). True when it was not there.
bool bpx__pair_set_add(bpx_pair_set *s, uint64_t key);
/// Removes a key. True when it was there.
bool bpx__pair_set_remove(bpx_pair_set *s, uint64_t key);
/// Removes every key for which drop(key, context) is true.
void bpx__pair_set_remove_if(bpx_pair_set *s, bool (*drop)(uint64_t key, const void *context),
                             const void *context);
void bpx__pair_set_free(bpx_pair_set *s);
