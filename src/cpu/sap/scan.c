// sap's scan mend, for warm cycles of few boxes of even extents.
//
// The scan mend, instead of the warm cycle's step 2 (mend.c), for up to SCAN_MAX_BOXES boxes of
// even extents on the swept axis: the last rebuild's sweep order is kept as a list of fat boxes in
// SoA, sorted by min on that axis, and each changed box moves its one entry there (a shift of the
// entries between) and tests, a vector at a time (scan_kernel.h), the boxes whose min lies within
// reach of its old or new fat box against both: one pass over a few hundred contiguous boxes
// instead of ~110 endpoint moves across three lists, each a likely cache miss (resting scene, 10k
// boxes: 180-230 us a cycle against 350-440 for the lists, `bpx bench --backend sap --scene resting
// --sizes 10000`). The endpoint lists are then left as they are; the next full rebuild makes them
// again. Uneven extents (a few wide boxes widen every box's reach) and larger scenes keep the
// lists.

#include <math.h>
#include <string.h>

#include "cpu/cpu_features.h"
#include "sap_internal.h"

// The scan mend: the fat boxes in SoA (a->lo, a->hi, slot 0 the swept axis; a->sorted_ids),
// sorted by min on the swept axis, inert ones last, padded. Each changed box in turn takes its
// new fat box: its entry moves to its new place (binary searches, one shift of the entries
// between), and the entries whose min lies within reach of its old or its new fat box (reach:
// the widest extent listed) are tested against both, a vector of them at a time; a box whose
// overlap differs is noted. Sequentially correct: each box's change is judged against the
// others as they are at its turn, as the few-boxes mend of the lists does.

// First index in [k0, k1) whose min (slot 0) is >= v (or, with `after`, > v).
static inline uint32_t scan_bound(const float *lo, uint32_t k0, uint32_t k1, float v, bool after)
{
    while (k0 < k1) {
        uint32_t mid = k0 + (k1 - k0) / 2;
        if (after ? lo[mid] <= v : lo[mid] < v)
            k0 = mid + 1;
        else
            k1 = mid;
    }
    return k0;
}

// Moves the entries [from, to) to [from + by, to + by) (by is -1 or +1).
static inline void scan_shift(bpx_sap_arrays *a, uint32_t from, uint32_t to, int by)
{
    size_t count = to - from;
    for (int s = 0; s < 3; s++) {
        memmove(a->lo[s] + from + by, a->lo[s] + from, count * sizeof(float));
        memmove(a->hi[s] + from + by, a->hi[s] + from, count * sizeof(float));
    }
    memmove(a->sorted_ids + from + by, a->sorted_ids + from, count * sizeof(uint32_t));
}

// Inert boxes after the n entries of the scan list: a scan reads up to a vector past its end.
void bpx__sap_scan_pad(bpx_sap_arrays *a, uint32_t n, const int order[3])
{
    const float inf = 1.0f / 0.0f;
    const bpx_box inert = {{inf, inf, inf}, {-inf, -inf, -inf}};
    for (uint32_t k = n; k < n + PAD; k++)
        scan_put(a, k, &inert, order, 0);
}

// The scan list after a full rebuild's sweep (its first `live` entries): the inert boxes after
// them, and the padding.
void bpx__sap_scan_list(bpx_sap_state *st, uint32_t n, uint32_t live)
{
    bpx_sap_arrays *a = &st->a;
    int order[3];
    scan_order(st->sweep_axis, order);
    uint32_t k = live;
    for (uint32_t i = 0; i < n && k < n; i++)
        if (!(a->fat[i].min[order[0]] <= a->fat[i].max[order[0]]))
            scan_put(a, k++, &a->fat[i], order, i);
    bpx__sap_scan_pad(a, n, order);
}

bpx_sap_mend_result bpx__sap_mend_scan(const bpx_cycle *cycle, bpx_sap_state *st, uint32_t n,
                                       uint32_t changed)
{
    bpx_sap_arrays *a = &st->a;
    int order[3];
    scan_order(st->sweep_axis, order);
    const float *lo0 = a->lo[0];
    const bpx_sorted list = {{a->lo[0], a->lo[1], a->lo[2]}, {a->hi[0], a->hi[1], a->hi[2]},
                             a->sorted_ids, n};
    bpx_scan_differs_fn *differs = bpx__scan_differs_for(cycle->simd);
    uint32_t *found = (uint32_t *)a->words[0]; // free in a warm cycle
    uint64_t work = 0, budget = (uint64_t)SCAN_WORK_PER_BOX * n + MOVES_BASE;
    for (uint32_t c = 0; c < changed; c++) {
        uint32_t b = a->changed[c];
        const bpx_box old = a->fat[b];
        const bpx_box now = fatten(&a->cur[b], st->margin);
        a->fat[b] = now;
        // b's entry (by its old min, then its id), and its new place.
        float was = old.min[order[0]], v = now.min[order[0]];
        uint32_t at = scan_bound(lo0, 0, n, was, false);
        while (at < n && lo0[at] == was && a->sorted_ids[at] != b)
            at++;
        if (at >= n || lo0[at] != was)
            return MEND_GAVE_UP; // never, unless this file has a bug: rebuild
        uint32_t to = at;
        if (v > was) {
            to = scan_bound(lo0, at + 1, n, v, false) - 1;
            scan_shift(a, at + 1, to + 1, -1);
        } else if (v < was) {
            to = scan_bound(lo0, 0, at, v, false);
            scan_shift(a, to, at, +1);
        }
        scan_put(a, to, &now, order, b);
        if (now.min[order[0]] <= now.max[order[0]]) {
            float extent = float_above((double)now.max[order[0]] - (double)now.min[order[0]]);
            st->scan_width = extent > st->scan_width ? extent : st->scan_width;
        }
        // Every box whose overlap with b may differ between its old and new fat box.
        float reach_lo = float_below((double)(was < v ? was : v) - (double)st->scan_width);
        float reach_hi = old.max[order[0]] > now.max[order[0]] ? old.max[order[0]]
                                                               : now.max[order[0]];
        uint32_t k0 = scan_bound(lo0, 0, n, reach_lo, false);
        uint32_t k1 = scan_bound(lo0, k0, n, reach_hi, true);
        work += (to > at ? to - at : at - to) + (k1 - k0);
        if (work > budget)
            return MEND_GAVE_UP;
        float was_box[6], now_box[6];
        for (int k = 0; k < 3; k++) {
            was_box[k] = old.min[order[k]];
            was_box[3 + k] = old.max[order[k]];
            now_box[k] = now.min[order[k]];
            now_box[3 + k] = now.max[order[k]];
        }
        uint32_t count = differs(&list, k0, k1, was_box, now_box, found);
        for (uint32_t k = 0; k < count; k++) {
            uint32_t other = a->sorted_ids[found[k]];
            if (other != b && !push(&st->changes, ordered(b, other)))
                return MEND_NO_MEMORY;
        }
    }
    return MEND_DONE;
}
