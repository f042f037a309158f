// The neighbour-list tests' reference pairs (test_neighbors, test_neighbors_triclinic): what a
// brute force writes for each (i <= j, shift) within the cutoff, and the order bpx reports them.
#pragma once

#include <stdint.h>

typedef struct ref_pair {
    uint32_t i, j;
    int32_t shift[3];
    double distance;
} ref_pair;

// By (i, j, shift), as bpx_find_neighbors sorts its list; for qsort.
static inline int compare_ref(const void *pa, const void *pb)
{
    const ref_pair *a = pa, *b = pb;
    if (a->i != b->i)
        return a->i < b->i ? -1 : 1;
    if (a->j != b->j)
        return a->j < b->j ? -1 : 1;
    for (int x = 0; x < 3; x++)
        if (a->shift[x] != b->shift[x])
            return a->shift[x] < b->shift[x] ? -1 : 1;
    return 0;
}
