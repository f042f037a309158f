// The plain-C twins of the device's sort and sweep and of its tree: the same functions
// (kernels/twin.h, kernels/lbvh.h) compiled for the host, each item run in a loop, with a host
// sort in place of the radix-sort kernels.
#include <stdlib.h>

#include "core/alloc.h"
#include "kernels/lbvh.h"
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

static int by_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

// The twin's arrays, one allocation each, freed together.
typedef struct tree_arrays {
    uint32_t *lo, *hi, *slo, *shi, *codes, *ids, *leaf_parent, *node_parent, *flags, *nodes;
    keyed *order;
    uint64_t *keys;
    size_t n, key_capacity;
} tree_arrays;

static void tree_arrays_free(tree_arrays *t)
{
    size_t n = t->n, nodes = n - 1, lanes = BPX_KEY_LANES * sizeof(uint32_t);
    bpx__free(t->lo, n * lanes);
    bpx__free(t->hi, n * lanes);
    bpx__free(t->slo, n * lanes);
    bpx__free(t->shi, n * lanes);
    bpx__free(t->codes, n * sizeof(uint32_t));
    bpx__free(t->ids, n * sizeof(uint32_t));
    bpx__free(t->leaf_parent, n * sizeof(uint32_t));
    bpx__free(t->node_parent, nodes * sizeof(uint32_t));
    bpx__free(t->flags, nodes * sizeof(uint32_t));
    bpx__free(t->nodes, 2 * nodes * BPX_LBVH_SLOT * sizeof(uint32_t));
    bpx__free(t->order, n * sizeof(keyed));
    bpx__free(t->keys, t->key_capacity * sizeof(uint64_t));
}

bpx_status bpx__opencl_twin_tree_pairs(const bpx_box *boxes, uint32_t n, size_t key_capacity,
                                       bpx_pair *out, size_t capacity, size_t *count,
                                       uint64_t *tests, int *rewalks)
{
    *count = 0;
    if (tests)
        *tests = 0;
    if (rewalks)
        *rewalks = 0;
    if (n < 2)
        return BPX_OK;
    size_t nodes = (size_t)n - 1, lanes = BPX_KEY_LANES * sizeof(uint32_t);
    key_capacity = key_capacity ? key_capacity : 1;
    tree_arrays t = {.n = n, .key_capacity = key_capacity};
    t.lo = bpx__alloc(n * lanes);
    t.hi = bpx__alloc(n * lanes);
    t.slo = bpx__alloc(n * lanes);
    t.shi = bpx__alloc(n * lanes);
    t.codes = bpx__alloc(n * sizeof(uint32_t));
    t.ids = bpx__alloc(n * sizeof(uint32_t));
    t.leaf_parent = bpx__alloc(n * sizeof(uint32_t));
    t.node_parent = bpx__alloc(nodes * sizeof(uint32_t));
    t.flags = bpx__alloc(nodes * sizeof(uint32_t));
    t.nodes = bpx__alloc(2 * nodes * BPX_LBVH_SLOT * sizeof(uint32_t));
    t.order = bpx__alloc(n * sizeof(keyed));
    t.keys = bpx__alloc(key_capacity * sizeof(uint64_t));
    bpx_status status = BPX_ERR_OUT_OF_MEMORY;
    if (!t.lo || !t.hi || !t.slo || !t.shi || !t.codes || !t.ids || !t.leaf_parent ||
        !t.node_parent || !t.flags || !t.nodes || !t.order || !t.keys)
        goto done;
    // bpx_tree_bounds and bpx_tree_codes.
    uint32_t scene[6] = {0xFFFFFFFFu, 0xFFFFFFFFu, 0xFFFFFFFFu, 0u, 0u, 0u};
    for (uint32_t i = 0; i < n; i++) {
        uint32_t *bl = t.lo + (size_t)i * BPX_KEY_LANES, *bh = t.hi + (size_t)i * BPX_KEY_LANES;
        bpx_box_keys((const float *)&boxes[i], 1, bl, bh);
        if (bpx_lbvh_live(bl, bh)) {
            float c[3];
            bpx_lbvh_centre(bl, bh, c);
            for (int a = 0; a < 3; a++) {
                uint32_t key = bpx_key(BPX_FLOAT_BITS(c[a]));
                scene[a] = key < scene[a] ? key : scene[a];
                scene[3 + a] = key > scene[3 + a] ? key : scene[3 + a];
            }
        }
    }
    for (uint32_t i = 0; i < n; i++) {
        uint32_t *bl = t.lo + (size_t)i * BPX_KEY_LANES, *bh = t.hi + (size_t)i * BPX_KEY_LANES;
        uint32_t code = BPX_LBVH_NO_CODE;
        if (bpx_lbvh_live(bl, bh)) {
            float c[3];
            bpx_lbvh_centre(bl, bh, c);
            code = bpx_lbvh_morton(c, scene);
        }
        t.order[i] = (keyed){code, i};
    }
    qsort(t.order, n, sizeof *t.order, by_key_then_index); // = the stable radix sort
    for (uint32_t p = 0; p < n; p++) {
        t.codes[p] = t.order[p].key;
        t.ids[p] = t.order[p].index;
        for (int a = 0; a < BPX_KEY_LANES; a++) { // = bpx_sweep_gather
            t.slo[(size_t)p * BPX_KEY_LANES + a] = t.lo[(size_t)t.ids[p] * BPX_KEY_LANES + a];
            t.shi[(size_t)p * BPX_KEY_LANES + a] = t.hi[(size_t)t.ids[p] * BPX_KEY_LANES + a];
        }
    }
    // bpx_tree_build, bpx_tree_refit, bpx_tree_walk: every item in turn.
    for (uint32_t i = 0; i < nodes; i++) {
        bpx_lbvh_build_node(t.codes, (int)n, (int)i, t.leaf_parent, t.node_parent);
        t.flags[i] = 0;
    }
    for (uint32_t p = 0; p < n; p++)
        bpx_lbvh_refit_leaf(p, t.slo, t.shi, t.leaf_parent, t.node_parent, t.nodes, t.flags);
    uint32_t bits = 1;
    while (bits < 32 && ((n - 1) >> bits) != 0)
        bits++;
    uint32_t counter[2];
    for (int pass = 0;; pass++) {
        counter[0] = counter[1] = 0;
        uint64_t walked = 0;
        for (uint32_t p = 0; p + 1 < n; p++)
            walked += bpx_lbvh_walk(p, t.slo, t.shi, t.ids, t.leaf_parent, t.node_parent, t.nodes,
                                    bits, t.keys, t.key_capacity, counter);
        if (tests)
            *tests = walked;
        if (counter[0] <= t.key_capacity || pass > 0)
            break;
        // As on the device: room for the count, and the walks again.
        uint64_t *grown = bpx__alloc(counter[0] * sizeof(uint64_t));
        if (!grown)
            goto done;
        bpx__free(t.keys, t.key_capacity * sizeof(uint64_t));
        t.keys = grown;
        t.key_capacity = counter[0];
        if (rewalks)
            (*rewalks)++;
    }
    size_t total = counter[0];
    *count = total;
    status = BPX_ERR_CAPACITY;
    if (total > capacity)
        goto done;
    qsort(t.keys, total, sizeof *t.keys, by_u64); // = the 64-bit radix sort
    for (size_t k = 0; k < total; k++)
        out[k] = (bpx_pair){(uint32_t)(t.keys[k] >> bits),
                            (uint32_t)(t.keys[k] & (((uint64_t)1 << bits) - 1))};
    status = BPX_OK;
done:
    tree_arrays_free(&t);
    return status;
}
