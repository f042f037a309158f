// bpx: broad-phase collision detection. SPDX-License-Identifier: MIT
//
// THE overlap predicate: the contract of every backend, and the body of the reference.
#pragma once

#include <stdbool.h>

#include "types.h"

#ifdef __cplusplus
extern "C" {
#endif

/// Algorithm 1 of Woulfe et al. 2007: a and b overlap iff on each axis
/// min_a <= max_b and min_b <= max_a. Closed intervals: touching boxes overlap; -0.0 == 0.0.
/// Defined only for valid boxes (finite, min <= max).
static inline bool bpx_overlap(const bpx_box *a, const bpx_box *b)
{
    return a->min[0] <= b->max[0] && b->min[0] <= a->max[0] &&
           a->min[1] <= b->max[1] && b->min[1] <= a->max[1] &&
           a->min[2] <= b->max[2] && b->min[2] <= a->max[2];
}

#ifdef __cplusplus
}
#endif
