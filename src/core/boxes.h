// The world's box storage: the current boxes and the spare set the updater writes, both in
// structure-of-arrays form, padded with inert boxes (boxes.c). The world's updater, the object
// layer and the device backends that hold the boxes themselves all go through it.
#pragma once

#include "world.h"

// (The box arrays themselves, bpx_box_arrays and bpx__box_arrays_*, are in backend.h: backends
// that hold boxes of their own use them too.)

/// Resizes the current boxes to n, keeping boxes below min(n, old n); new slots are inert.
bool bpx__boxes_resize(bpx_world *w, uint32_t n);
/// The spare set (written by the updater) becomes the current boxes, n of them.
void bpx__boxes_swap_in_spare(bpx_world *w, uint32_t n);
/// Makes box id inert (never overlaps anything).
void bpx__box_make_inert(bpx_world *w, uint32_t id);
/// Box id becomes `box` (already validated).
static inline void bpx__box_set(bpx_world *w, uint32_t id, const bpx_box *box)
{
    for (int a = 0; a < 3; a++) {
        w->boxes.lo[a][id] = box->min[a];
        w->boxes.hi[a][id] = box->max[a];
    }
    w->boxes_version++;
}
