// The brute-force comparator, written once over the wide-float layer (src/simd/wide_*.h).
// A per-ISA file includes its wide header, names the function with BPX_BRUTE_ROWS, then this.
//
// Row i is box i against boxes i+1 .. n-1, W boxes per step (the paper's 2m - 1 comparison
// units, W wide). The x test runs first, on four steps at once, and the other four comparisons
// run only when some lane of the four passed: in a sparse scene that skips most of the work.
// Arrays are padded to a multiple of 64 with boxes that never overlap, so groups read whole vectors.
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

// The y and z tests of one step, on the lanes m left standing.
static inline bpx_wm yz_test(const bpx_soa *s, const brute_row *r, uint32_t j, bpx_wm m)
{
    m = bpx_wm_le_and(m, bpx_wf_load(s->lo[1] + j), r->hy);
    m = bpx_wm_le_and(m, r->ly, bpx_wf_load(s->hi[1] + j));
    m = bpx_wm_le_and(m, bpx_wf_load(s->lo[2] + j), r->hz);
    return bpx_wm_le_and(m, r->lz, bpx_wf_load(s->hi[2] + j));
}

// Emitter: writes (i, j + lane) for each set bit, in lane order. Room is made for a whole step
// at once (at most W hits). Returns false when memory ran out.
static inline bool emit(bpx_block *out, uint32_t i, uint32_t j, uint32_t bits)
{
    if (!bits)
        return true;
    if (out->capacity - out->count < BPX_W && !bpx__block_reserve(out, BPX_W))
        return false;
    bpx_pair *p = out->pairs + out->count;
    while (bits) {
        p->i = i;
        p->j = j + (uint32_t)__builtin_ctz(bits);
        p++;
        bits &= bits - 1;
    }
    out->count = (size_t)(p - out->pairs);
    return true;
}

// Branches are taken per group of four steps, not per step: whether one step's x test passes
// is a coin toss in a typical scene (a mispredict costs more than the four compares it saves),
// but whether a whole group is empty, or holds a hit, is predictable.
void BPX_BRUTE_ROWS(const bpx_soa *s, uint32_t row_begin, uint32_t row_end, bpx_block *out)
{
    // Groups of four steps run to the end of the padding (a multiple of 4 W; see world.h).
    enum { GROUP = 4 * BPX_W };
    _Static_assert(BPX_PAD_LANES % GROUP == 0, "padding must hold whole groups");
    const uint32_t end = (s->n + GROUP - 1) / GROUP * GROUP;
    const uint32_t all = (uint32_t)((1ull << BPX_W) - 1);
    uint64_t tests = 0;

    for (uint32_t i = row_begin; i < row_end; i++) {
        const brute_row r = {
            bpx_wf_set1(s->lo[0][i]), bpx_wf_set1(s->hi[0][i]), bpx_wf_set1(s->lo[1][i]),
            bpx_wf_set1(s->hi[1][i]), bpx_wf_set1(s->lo[2][i]), bpx_wf_set1(s->hi[2][i]), i};
        // The first step holds i + 1 somewhere; its lanes up to i are not pairs of row i and are
        // dropped when emitting (lane i, box i against itself, always passes).
        uint32_t j = (i + 1) / BPX_W * BPX_W;
        uint32_t keep = (uint32_t)((uint64_t)all << (i + 1 - j)) & all;
        tests += (end - j + GROUP - 1) / GROUP * GROUP;
        bool ok = true;
        for (; ok && j < end; j += GROUP) {
            bpx_wm m0 = x_test(s, &r, j), m1 = x_test(s, &r, j + BPX_W);
            bpx_wm m2 = x_test(s, &r, j + 2 * BPX_W), m3 = x_test(s, &r, j + 3 * BPX_W);
            if (bpx_wm_any(bpx_wm_or(bpx_wm_or(m0, m1), bpx_wm_or(m2, m3)))) {
                m0 = yz_test(s, &r, j, m0);
                m1 = yz_test(s, &r, j + BPX_W, m1);
                m2 = yz_test(s, &r, j + 2 * BPX_W, m2);
                m3 = yz_test(s, &r, j + 3 * BPX_W, m3);
                if (bpx_wm_any(bpx_wm_or(bpx_wm_or(m0, m1), bpx_wm_or(m2, m3))))
                    ok = emit(out, i, j, bpx_wm_bits(m0) & keep) &&
                         emit(out, i, j + BPX_W, bpx_wm_bits(m1)) &&
                         emit(out, i, j + 2 * BPX_W, bpx_wm_bits(m2)) &&
                         emit(out, i, j + 3 * BPX_W, bpx_wm_bits(m3));
            }
            keep = all;
        }
        if (!ok) {
            out->status = BPX_ERR_OUT_OF_MEMORY;
            return;
        }
    }
    out->tests += tests;
}
