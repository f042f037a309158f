#include "sort.h"

void bpx__radix_sort(uint32_t *keys, uint32_t *ids, uint32_t *scratch_keys,
                     uint32_t *scratch_ids, uint32_t n)
{
    enum { BITS = 11, BUCKETS = 1 << BITS };
    uint32_t *src_k = keys, *src_i = ids, *dst_k = scratch_keys, *dst_i = scratch_ids;
    for (int shift = 0; shift < 32; shift += BITS) {
        uint32_t counts[BUCKETS + 1] = {0};
        for (uint32_t k = 0; k < n; k++)
            counts[((src_k[k] >> shift) & (BUCKETS - 1)) + 1]++;
        for (int b = 0; b < BUCKETS; b++)
            counts[b + 1] += counts[b];
        for (uint32_t k = 0; k < n; k++) {
            uint32_t slot = counts[(src_k[k] >> shift) & (BUCKETS - 1)]++;
            dst_k[slot] = src_k[k];
            dst_i[slot] = src_i[k];
        }
        uint32_t *t = src_k;
        src_k = dst_k;
        dst_k = t;
        t = src_i;
        src_i = dst_i;
        dst_i = t;
    }
    // Three passes (0, 11, 22) leave the result in the scratch arrays: copy it home.
    if (src_k != keys) {
        memcpy(keys, src_k, sizeof(uint32_t) * n);
        memcpy(ids, src_i, sizeof(uint32_t) * n);
    }
}

bool bpx__insertion_sort(uint32_t *keys, uint32_t *ids, uint32_t n, uint64_t max_moves)
{
    uint64_t moves = 0;
    for (uint32_t k = 1; k < n; k++) {
        uint32_t key = keys[k], id = ids[k];
        uint32_t at = k;
        while (at > 0 && keys[at - 1] > key) {
            keys[at] = keys[at - 1];
            ids[at] = ids[at - 1];
            at--;
        }
        keys[at] = key;
        ids[at] = id;
        moves += k - at;
        if (moves > max_moves)
            return false;
    }
    return true;
}
