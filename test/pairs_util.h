// bpx tests: pair-list helpers shared by the tests. SPDX-License-Identifier: MIT
#pragma once

#include "check.h"

/// A growable pair array owned by the test.
typedef struct pair_list {
    bpx_pair *pairs;
    size_t count;
    size_t capacity;
} pair_list;

static inline void pair_list_reserve(pair_list *l, size_t capacity)
{
    if (capacity > l->capacity) {
        free(l->pairs);
        l->pairs = check_alloc(sizeof(bpx_pair) * capacity);
        l->capacity = capacity;
    }
}

static inline void pair_list_set(pair_list *l, const bpx_pair *pairs, size_t count)
{
    pair_list_reserve(l, count);
    if (count) {
        memcpy(l->pairs, pairs, sizeof(bpx_pair) * count);
    }
    l->count = count;
}

static inline void pair_list_free(pair_list *l)
{
    free(l->pairs);
    l->pairs = NULL;
    l->count = l->capacity = 0;
}

/// The independent oracle: a double loop over bpx_overlap, in (i, j) order.
static inline void pair_list_brute(pair_list *l, const bpx_box *boxes, uint32_t n)
{
    size_t count = 0;
    for (uint32_t i = 0; i < n; i++) {
        for (uint32_t j = i + 1; j < n; j++) {
            count += bpx_overlap(&boxes[i], &boxes[j]);
        }
    }
    pair_list_reserve(l, count);
    l->count = 0;
    for (uint32_t i = 0; i < n; i++) {
        for (uint32_t j = i + 1; j < n; j++) {
            if (bpx_overlap(&boxes[i], &boxes[j])) {
                l->pairs[l->count].i = i;
                l->pairs[l->count].j = j;
                l->count++;
            }
        }
    }
}

/// Index of the first difference of two pair arrays (min of the counts when one is a prefix).
static inline size_t pairs_first_diff(const bpx_pair *a, size_t na, const bpx_pair *b, size_t nb)
{
    size_t n = na < nb ? na : nb;
    for (size_t k = 0; k < n; k++) {
        if (a[k].i != b[k].i || a[k].j != b[k].j) {
            return k;
        }
    }
    return n;
}

/// Checks got == want byte for byte; on failure names the first differing pair.
#define CHECK_PAIRS_EQ(want, nwant, got, ngot)                                                     \
    do {                                                                                           \
        const bpx_pair *check_w_ = (want);                                                         \
        const bpx_pair *check_g_ = (got);                                                          \
        size_t check_nw_ = (nwant);                                                                \
        size_t check_ng_ = (ngot);                                                                 \
        bool check_same_ = check_nw_ == check_ng_ &&                                               \
                           (check_nw_ == 0 ||                                                      \
                            (check_g_ && memcmp(check_w_, check_g_,                                \
                                                sizeof(bpx_pair) * check_nw_) == 0));              \
        size_t check_k_ = check_same_ || !check_g_                                                 \
                              ? 0                                                                  \
                              : pairs_first_diff(check_w_, check_nw_, check_g_, check_ng_);        \
        CHECK_MSG(check_same_,                                                                     \
                  "want %zu pairs, got %zu; first difference at %zu: want (%u,%u) got (%u,%u)",   \
                  check_nw_, check_ng_, check_k_,                                                  \
                  check_k_ < check_nw_ ? check_w_[check_k_].i : 0u,                                \
                  check_k_ < check_nw_ ? check_w_[check_k_].j : 0u,                                \
                  check_g_ && check_k_ < check_ng_ ? check_g_[check_k_].i : 0u,                    \
                  check_g_ && check_k_ < check_ng_ ? check_g_[check_k_].j : 0u);                   \
    } while (0)

/// Strictly ascending (i, j) with i < j < n.
static inline bool pairs_well_formed(const bpx_pair *p, size_t count, uint32_t n)
{
    for (size_t k = 0; k < count; k++) {
        if (!(p[k].i < p[k].j && p[k].j < n)) {
            return false;
        }
        if (k > 0 && !(p[k - 1].i < p[k].i || (p[k - 1].i == p[k].i && p[k - 1].j < p[k].j))) {
            return false;
        }
    }
    return true;
}
