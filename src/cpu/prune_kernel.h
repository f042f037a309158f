// The sweep of the prune backend (single-axis sort and sweep, "box pruning"), written once over
// the wide-float layer like brute_kernel.h.
//
// Boxes are sorted by min x (prune.c). Box p is tested against the boxes after it in that order
// while their min x is <= its max x: those are exactly the ones whose x interval meets its own
// (their max x >= their min x >= its min x). W candidates are tested per step, y and z with the
// same compares as the brute force; the run ends at the first box out of reach, and a sentinel
// (min x = +inf) after the last box ends it there.
#include "cpu/backends.h"

#ifndef BPX_PRUNE_ROWS
#error "define BPX_PRUNE_ROWS before including prune_kernel.h"
#endif

// Hits leave in sorted-position order; prune.c puts them in (i, j) order afterwards, so here a
// pair is only normalised to i < j.
static inline bool emit_sorted(bpx_pair_list *out, uint32_t id, const uint32_t *ids, uint32_t k,
                               uint32_t bits)
{
    if (out->capacity - out->count < BPX_W && !bpx__list_reserve(out, BPX_W))
        return false;
    bpx_pair *p = out->pairs + out->count;
    while (bits) {
        uint32_t other = ids[k + (uint32_t)__builtin_ctz(bits)];
        p->i = id < other ? id : other;
        p->j = id < other ? other : id;
        p++;
        bits &= bits - 1;
    }
    out->count = (size_t)(p - out->pairs);
    return true;
}

void BPX_PRUNE_ROWS(const bpx_sorted *s, uint32_t row_begin, uint32_t row_end, bpx_block *out)
{
    const uint32_t all = (uint32_t)((1ull << BPX_W) - 1);
    const float *lx = s->lo[0], *ly = s->lo[1], *lz = s->lo[2];
    const float *ly_hi = s->hi[1], *lz_hi = s->hi[2];
    uint64_t tests = 0;
    for (uint32_t p = row_begin; p < row_end; p++) {
        const bpx_wf hx = bpx_wf_set1(s->hi[0][p]);
        const bpx_wf ly_p = bpx_wf_set1(ly[p]), hy_p = bpx_wf_set1(ly_hi[p]);
        const bpx_wf lz_p = bpx_wf_set1(lz[p]), hz_p = bpx_wf_set1(lz_hi[p]);
        for (uint32_t k = p + 1;; k += BPX_W) {
            bpx_wm reach = bpx_wm_le(bpx_wf_loadu(lx + k), hx);
            bpx_wm m = bpx_wm_le_and(reach, bpx_wf_loadu(ly + k), hy_p);
            m = bpx_wm_le_and(m, ly_p, bpx_wf_loadu(ly_hi + k));
            m = bpx_wm_le_and(m, bpx_wf_loadu(lz + k), hz_p);
            m = bpx_wm_le_and(m, lz_p, bpx_wf_loadu(lz_hi + k));
            // Only the run of lanes in reach from the first counts: a list may hold several
            // sorted runs one after another, each ended by a sentinel (the grid's columns).
            uint32_t in_reach = bpx_wm_bits(reach);
            in_reach &= ~(in_reach + 1);
            uint32_t bits = bpx_wm_bits(m) & in_reach;
            tests += BPX_W;
            if (bits && !emit_sorted(&out->hits, s->id[p], s->id, k, bits)) {
                out->status = BPX_ERR_OUT_OF_MEMORY;
                return;
            }
            if (in_reach != all)
                break;
        }
    }
    out->tests += tests;
}
