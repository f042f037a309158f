// bpx tests: the oracle's side of checking a world, written without the library's code: which
// ids pair (Algorithm 1's test, with filters) and what a cycle's events are (the difference of
// two sorted pair lists). Shared by test_soak.c and fuzz/fuzz_api.c, each of which keeps its own
// model of the world (boxes, live ids, filters). SPDX-License-Identifier: MIT
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <bpx/bpx.h>

/// The closed intervals overlap on every axis (touching boxes do; a NaN bound never does).
static inline bool oracle_overlap(const bpx_box *a, const bpx_box *b)
{
    for (int k = 0; k < 3; k++)
        if (!(a->min[k] <= b->max[k] && b->min[k] <= a->max[k]))
            return false;
    return true;
}

/// Whether two live ids i and j make a pair: their boxes overlap and each passes the other's
/// filter, (category[i] & mask[j]) && (category[j] & mask[i]).
static inline bool oracle_pair(const bpx_box *boxes, const uint32_t *category, const uint32_t *mask,
                               uint32_t i, uint32_t j)
{
    return oracle_overlap(&boxes[i], &boxes[j]) && (category[i] & mask[j]) &&
           (category[j] & mask[i]);
}

static inline bool oracle_pair_less(bpx_pair a, bpx_pair b)
{
    return a.i < b.i || (a.i == b.i && a.j < b.j);
}

/// The pairs of a that are not in b, both sorted by (i, j), into out (room for na): began is
/// difference(now, before), ended difference(before, now). Returns how many.
static inline size_t oracle_difference(const bpx_pair *a, size_t na, const bpx_pair *b, size_t nb,
                                       bpx_pair *out)
{
    size_t x = 0, y = 0, count = 0;
    while (x < na) {
        if (y == nb || oracle_pair_less(a[x], b[y]))
            out[count++] = a[x++];
        else if (oracle_pair_less(b[y], a[x]))
            y++;
        else
            x++, y++;
    }
    return count;
}
