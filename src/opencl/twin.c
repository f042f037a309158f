// The plain-C twin of the device's sort and sweep: the same functions (kernels/twin.h) compiled
// for the host, with a host sort in place of the radix-sort kernels.
#include <stdlib.h>

#include "core/alloc.h"
#include "kernels/twin.h"
#include "opencl_internal.h"

typedef struct keyed {
    uint32_t key;
    uint32_t index;
} keyed;

static int by_key_then_index(const void *a, const void *b)
{
    const keyed *x = a, *y = b;
    if (x->key != y->key)
        return x->key < y->key ? -1 : 1;
    return (x->index > y->index) - (x->index < y->index);
}

static int by_pair(const void *a, const void *b)
{
    const bpx_pair *x = a, *y = b;
    if (x->i != y->i)
        return x->i < y->i ? -1 : 1;
    return (x->j > y->j) - (x->j < y->j);
}

bpx_status bpx__opencl_twin_pairs(const bpx_box *boxes, uint32_t n, bpx_pair *out, size_t capacity,
                                  size_t *count)
{
    *count = 0;
    if (n < 2)
        return BPX_OK;
    size_t keys_size = (size_t)n * BPX_KEY_LANES * sizeof(uint32_t);
    uint32_t *lo = bpx__alloc(keys_size), *hi = bpx__alloc(keys_size);
    uint32_t *slo = bpx__alloc(keys_size), *shi = bpx__alloc(keys_size);
    uint32_t *index = bpx__alloc(n * sizeof(uint32_t));
    keyed *order = bpx__alloc(n * sizeof(keyed));
    bpx_status status = BPX_ERR_OUT_OF_MEMORY;
    uint32_t *pi = NULL, *pj = NULL;
    size_t total = 0;
    if (!lo || !hi || !slo || !shi || !index || !order)
        goto done;
    for (uint32_t i = 0; i < n; i++) {
        bpx_box_keys((const float *)&boxes[i], 1, lo + (size_t)i * BPX_KEY_LANES,
                     hi + (size_t)i * BPX_KEY_LANES);
        order[i] = (keyed){lo[(size_t)i * BPX_KEY_LANES], i};
    }
    qsort(order, n, sizeof *order, by_key_then_index); // = the stable radix sort by key
    for (uint32_t p = 0; p < n; p++) {
        index[p] = order[p].index;
        for (int a = 0; a < BPX_KEY_LANES; a++) {
            slo[(size_t)p * BPX_KEY_LANES + a] = lo[(size_t)index[p] * BPX_KEY_LANES + a];
            shi[(size_t)p * BPX_KEY_LANES + a] = hi[(size_t)index[p] * BPX_KEY_LANES + a];
        }
    }
    for (uint32_t p = 0; p < n; p++)
        total += bpx_sweep_position(slo, shi, index, n, p, NULL, NULL, 0, 0);
    *count = total;
    status = BPX_ERR_CAPACITY;
    if (total > capacity)
        goto done;
    status = BPX_ERR_OUT_OF_MEMORY;
    if (total && (!(pi = bpx__alloc(total * sizeof(uint32_t))) ||
                  !(pj = bpx__alloc(total * sizeof(uint32_t)))))
        goto done;
    uint64_t offset = 0;
    for (uint32_t p = 0; p < n; p++)
        offset += bpx_sweep_position(slo, shi, index, n, p, pi, pj, offset, total);
    for (size_t k = 0; k < total; k++)
        out[k] = (bpx_pair){pi[k], pj[k]};
    qsort(out, total, sizeof *out, by_pair); // = the two radix sorts (by j, then by i)
    status = BPX_OK;
done:
    bpx__free(pi, total * sizeof(uint32_t));
    bpx__free(pj, total * sizeof(uint32_t));
    bpx__free(lo, keys_size);
    bpx__free(hi, keys_size);
    bpx__free(slo, keys_size);
    bpx__free(shi, keys_size);
    bpx__free(index, n * sizeof(uint32_t));
    bpx__free(order, n * sizeof(keyed));
    return status;
}
