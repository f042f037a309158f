// The world's box storage (boxes.h): two sets of six padded arrays, the current boxes and the
// spare set the updater writes and checks before swapping it in, so bad input leaves the world
// unchanged.
#include "boxes.h"

#include <math.h>
#include <string.h>

#include "alloc.h"

void bpx__box_arrays_free(bpx_box_arrays *b)
{
    bpx__free(b->lo[0], 6 * sizeof(float) * b->capacity); // one block (bpx__box_arrays_reserve)
    *b = (bpx_box_arrays){0};
}

// Boxes plus padding: n rounded up to whole groups, plus one more group, because a row's
// first group starts at the vector holding i + 1 and may run past the rounded end.
uint32_t bpx__boxes_padded(uint32_t n)
{
    return (n + BPX_PAD_LANES - 1) / BPX_PAD_LANES * BPX_PAD_LANES + BPX_PAD_LANES;
}

bool bpx__box_arrays_reserve(bpx_box_arrays *b, uint32_t n)
{
    uint32_t capacity = bpx__boxes_padded(n);
    if (capacity <= b->capacity)
        return true;
    // One block, so that the spare set can be lent whole (bpx_cycle.scratch); capacity is a
    // multiple of BPX_PAD_LANES, so each array starts on a whole cache line like the first.
    bpx_box_arrays grown = {.capacity = capacity};
    float *block = bpx__alloc(6 * sizeof(float) * capacity);
    if (!block)
        return false;
    for (int a = 0; a < 3; a++) {
        grown.lo[a] = block + (size_t)a * capacity;
        grown.hi[a] = block + (size_t)(3 + a) * capacity;
    }
    bpx__box_arrays_free(b);
    *b = grown;
    return true;
}

static void fill(float *restrict to, uint32_t count, float value)
{
    for (uint32_t k = 0; k < count; k++)
        to[k] = value;
}

// Padding boxes can never overlap anything: min = +inf fails every `min_j <= max_i`. Array by
// array, so each fill is a run of vector stores: every update_centres / set_boxes pads the set
// it swaps in, 14 to 78 boxes of it, which box by box across six arrays was 15% of a cycle at
// n = 50 (perf, Table 2's scenario).
void bpx__box_arrays_pad(bpx_box_arrays *b, uint32_t n)
{
    uint32_t count = bpx__boxes_padded(n) - n;
    for (int a = 0; a < 3; a++) {
        fill(b->lo[a] + n, count, INFINITY);
        fill(b->hi[a] + n, count, -INFINITY);
    }
}

bool bpx__boxes_resize(bpx_world *w, uint32_t n)
{
    if (bpx__boxes_padded(n) > w->boxes.capacity) {
        // Boxes added a few at a time (an engine's proxies) grow the arrays by half again, so
        // that the copies stay linear in the boxes added.
        uint32_t room = w->n + w->n / 2 > n && w->n + w->n / 2 <= BPX_MAX_BOXES ? w->n + w->n / 2 : n;
        if (!bpx__box_arrays_reserve(&w->spare, room) && !bpx__box_arrays_reserve(&w->spare, n))
            return false;
        for (int a = 0; a < 3; a++) {
            memcpy(w->spare.lo[a], w->boxes.lo[a], sizeof(float) * w->n);
            memcpy(w->spare.hi[a], w->boxes.hi[a], sizeof(float) * w->n);
        }
        bpx_box_arrays current = w->boxes;
        w->boxes = w->spare;
        w->spare = current;
    }
    for (uint32_t i = w->n; i < n; i++)
        bpx__box_make_inert(w, i);
    w->n = n;
    bpx__box_arrays_pad(&w->boxes, n);
    w->stats.box_count = n;
    w->emitter.planned_n = UINT32_MAX;
    w->boxes_version++;
    return true;
}

void bpx__box_make_inert(bpx_world *w, uint32_t id)
{
    for (int a = 0; a < 3; a++) {
        w->boxes.lo[a][id] = INFINITY;
        w->boxes.hi[a][id] = -INFINITY;
    }
    w->boxes_version++;
}

void bpx__boxes_swap_in_spare(bpx_world *w, uint32_t n)
{
    bpx_box_arrays current = w->boxes;
    w->boxes = w->spare;
    w->spare = current;
    w->n = n;
    bpx__box_arrays_pad(&w->boxes, n);
    w->stats.box_count = n;
    w->boxes_version++;
    w->boxes_on_device = false;
}
