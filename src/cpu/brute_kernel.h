// The brute-force comparator, written once over the wide-float layer (src/simd/wide_*.h).
// A per-ISA file includes its wide header, names the function with BPX_BRUTE_ROWS, then this.
//
// Row i is box i against boxes i+1 .. n-1, W boxes per step (the paper's 2m - 1 comparison
// units, W wide). The x test runs first, on four steps at once, and the other four comparisons
// run only for steps where some lane passed: in a sparse scene that skips most of the work.
// Arrays are padded to a multiple of 16 with boxes that never overlap, so steps read whole vectors.
#include "core/world.h"

#ifndef BPX_BRUTE_ROWS
#error "define BPX_BRUTE_ROWS before including brute_kernel.h"
#endif

typedef struct brute_row {
    bpx_wf lx, hx, ly, hy, lz, hz; // box i in every lane
    uint32_t i;
} brute_row;

// The x test of one step: lanes where box j's x interval meets box i's.
static inline bpx_wm x_test(const bpx_soa *s, const brute_row *r, uint32_t j)
{
    bpx_wm m = bpx_wm_le(bpx_wf_load(s->lo[0] + j), r->hx);
    return bpx_wm_le_and(m, r->lx, bpx_wf_load(s->hi[0] + j));
}

// Finishes a step whose x test gave m (lanes outside `keep` are dropped) and emits its hits.
static inline bool finish_step(const bpx_soa *s, const brute_row *r, uint32_t j, bpx_wm m,
                               uint32_t keep, bpx_block *out)
{
    m = bpx_wm_le_and(m, bpx_wf_load(s->lo[1] + j), r->hy);
    m = bpx_wm_le_and(m, r->ly, bpx_wf_load(s->hi[1] + j));
    m = bpx_wm_le_and(m, bpx_wf_load(s->lo[2] + j), r->hz);
    m = bpx_wm_le_and(m, r->lz, bpx_wf_load(s->hi[2] + j));
    uint32_t bits = bpx_wm_bits(m) & keep;
    if (!bits)
        return true;
    // Emitter: at most W hits per step; room is made for a whole step at once.
    if (out->capacity - out->count < BPX_W && !bpx__block_reserve(out, BPX_W))
        return false;
    bpx_pair *p = out->pairs + out->count;
    while (bits) {
        p->i = r->i;
        p->j = j + (uint32_t)__builtin_ctz(bits);
        p++;
        bits &= bits - 1;
    }
    out->count = (size_t)(p - out->pairs);
    return true;
}

void BPX_BRUTE_ROWS(const bpx_soa *s, uint32_t row_begin, uint32_t row_end, bpx_block *out)
{
    const uint32_t end = (s->n + BPX_W - 1) / BPX_W * BPX_W;
    const uint32_t all = (uint32_t)((1ull << BPX_W) - 1);
    uint64_t tests = 0;

    for (uint32_t i = row_begin; i < row_end; i++) {
        const brute_row r = {
            bpx_wf_set1(s->lo[0][i]), bpx_wf_set1(s->hi[0][i]), bpx_wf_set1(s->lo[1][i]),
            bpx_wf_set1(s->hi[1][i]), bpx_wf_set1(s->lo[2][i]), bpx_wf_set1(s->hi[2][i]), i};
        // The first step holds i + 1 somewhere; its lanes up to i are not pairs of row i.
        uint32_t j = (i + 1) / BPX_W * BPX_W;
        tests += end - j;
        const uint32_t first_keep = (uint32_t)((uint64_t)all << (i + 1 - j)) & all;
        bool ok = true;
        if (j < end) {
            bpx_wm m = x_test(s, &r, j);
            if (bpx_wm_any(m))
                ok = finish_step(s, &r, j, m, first_keep, out);
            j += BPX_W;
        }
        for (; ok && j + 4 * BPX_W <= end; j += 4 * BPX_W) {
            bpx_wm m0 = x_test(s, &r, j), m1 = x_test(s, &r, j + BPX_W);
            bpx_wm m2 = x_test(s, &r, j + 2 * BPX_W), m3 = x_test(s, &r, j + 3 * BPX_W);
            if (!bpx_wm_any(bpx_wm_or(bpx_wm_or(m0, m1), bpx_wm_or(m2, m3))))
                continue;
            ok = (!bpx_wm_any(m0) || finish_step(s, &r, j, m0, all, out)) &&
                 (!bpx_wm_any(m1) || finish_step(s, &r, j + BPX_W, m1, all, out)) &&
                 (!bpx_wm_any(m2) || finish_step(s, &r, j + 2 * BPX_W, m2, all, out)) &&
                 (!bpx_wm_any(m3) || finish_step(s, &r, j + 3 * BPX_W, m3, all, out));
        }
        for (; ok && j < end; j += BPX_W) {
            bpx_wm m = x_test(s, &r, j);
            if (bpx_wm_any(m))
                ok = finish_step(s, &r, j, m, all, out);
        }
        if (!ok) {
            out->status = BPX_ERR_OUT_OF_MEMORY;
            return;
        }
    }
    out->tests += tests;
}
