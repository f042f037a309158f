// The brute-force comparator, written once over the wide-float layer (src/simd/wide_*.h).
// A per-ISA file includes its wide header, names the function with BPX_BRUTE_ROWS, then this.
//
// Row i is box i against boxes i+1 .. n-1, W boxes per step (the paper's 2m - 1 comparison
// units, W wide). Two rows run together, so every vector loaded serves two boxes: beyond L1
// (n of a few thousand) the comparator is bound by how fast the six arrays stream in, and this
// halves the traffic. The x test runs first; the other four comparisons run only when some
// lane of a group of steps passed, which in a sparse scene skips most of the work. Branches are
// taken per group, not per step: whether one step's x test passes is a coin toss in a typical
// scene (a mispredict costs more than the compares it saves), whether a group is empty is not.
// Arrays are padded with boxes that never overlap (core/backend.h), so groups read whole vectors.
#include "cpu/backends.h"

#ifndef BPX_BRUTE_ROWS
#error "define BPX_BRUTE_ROWS before including brute_kernel.h"
#endif

typedef struct bpx_brute_row {
    bpx_wf lx, hx, ly, hy, lz, hz; // box i in every lane
    uint32_t i;
} bpx_brute_row;

static inline bpx_brute_row load_row(const bpx_soa *s, uint32_t i)
{
    return (bpx_brute_row){bpx_wf_set1(s->lo[0][i]),
                           bpx_wf_set1(s->hi[0][i]),
                           bpx_wf_set1(s->lo[1][i]),
                           bpx_wf_set1(s->hi[1][i]),
                           bpx_wf_set1(s->lo[2][i]),
                           bpx_wf_set1(s->hi[2][i]),
                           i};
}

// The x test of one step: lanes where box j's x interval meets box i's.
static inline bpx_wm x_test(const bpx_soa *s, const bpx_brute_row *r, uint32_t j)
{
    bpx_wm m = bpx_wm_le(bpx_wf_load(s->lo[0] + j), r->hx);
    return bpx_wm_le_and(m, r->lx, bpx_wf_load(s->hi[0] + j));
}

// The y and z tests of one step, on the lanes m left standing.
static inline bpx_wm yz_test(const bpx_soa *s, const bpx_brute_row *r, uint32_t j, bpx_wm m)
{
    m = bpx_wm_le_and(m, bpx_wf_load(s->lo[1] + j), r->hy);
    m = bpx_wm_le_and(m, r->ly, bpx_wf_load(s->hi[1] + j));
    m = bpx_wm_le_and(m, bpx_wf_load(s->lo[2] + j), r->hz);
    return bpx_wm_le_and(m, r->lz, bpx_wf_load(s->hi[2] + j));
}

// Emitter: appends (i, j + lane) for each set bit, in lane order. Room is made for a whole step
// at once (at most W hits). Returns false when memory ran out.
static inline bool emit(bpx_pair_list *out, uint32_t i, uint32_t j, uint32_t bits)
{
    if (!bits)
        return true;
    if (out->capacity - out->count < BPX_W && !bpx__list_reserve(out, BPX_W))
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

static inline int any4(bpx_wm a, bpx_wm b, bpx_wm c, bpx_wm d)
{
    return bpx_wm_any(bpx_wm_or(bpx_wm_or(a, b), bpx_wm_or(c, d)));
}

// Lanes of the step starting at j (a multiple of W) that hold boxes after i.
static inline uint32_t lanes_after(uint32_t i, uint32_t j)
{
    const uint64_t all = (1ull << BPX_W) - 1;
    return i + 1 <= j ? (uint32_t)all : (uint32_t)((all << (i + 1 - j)) & all);
}

// Rows i and i+1 together, two steps per group. Row i's hits go straight to the block; row
// i+1's wait in the stage list and follow them, which keeps the block in (i, j) order. end is a
// multiple of W: a step left over after the whole groups runs alone (at n = 50 with 16 lanes,
// groups run to the end of the padding read a tenth more lanes than this).
static bool row_pair(const bpx_soa *s, uint32_t i, uint32_t end, bpx_block *out)
{
    enum { GROUP = 2 * BPX_W };
    const bpx_brute_row r0 = load_row(s, i), r1 = load_row(s, i + 1);
    uint32_t j = (i + 1) / BPX_W * BPX_W;
    uint32_t keep0 = lanes_after(i, j), keep1 = lanes_after(i + 1, j);
    out->tests += 2 * (uint64_t)(end - j);
    out->stage.count = 0;
    bool ok = true;
    for (; ok && j + GROUP <= end; j += GROUP) {
        bpx_wm a0 = x_test(s, &r0, j), a1 = x_test(s, &r0, j + BPX_W);
        bpx_wm b0 = x_test(s, &r1, j), b1 = x_test(s, &r1, j + BPX_W);
        if (any4(a0, a1, b0, b1)) {
            a0 = yz_test(s, &r0, j, a0);
            a1 = yz_test(s, &r0, j + BPX_W, a1);
            b0 = yz_test(s, &r1, j, b0);
            b1 = yz_test(s, &r1, j + BPX_W, b1);
            if (any4(a0, a1, b0, b1))
                ok = emit(&out->hits, i, j, bpx_wm_bits(a0) & keep0) &&
                     emit(&out->hits, i, j + BPX_W, bpx_wm_bits(a1)) &&
                     emit(&out->stage, i + 1, j, bpx_wm_bits(b0) & keep1) &&
                     emit(&out->stage, i + 1, j + BPX_W, bpx_wm_bits(b1));
        }
        keep0 = keep1 = lanes_after(0, 1); // all lanes after the first step
    }
    if (ok && j < end) { // one step left (end - j is 0 or W)
        bpx_wm a0 = x_test(s, &r0, j), b0 = x_test(s, &r1, j);
        if (bpx_wm_any(bpx_wm_or(a0, b0))) {
            a0 = yz_test(s, &r0, j, a0);
            b0 = yz_test(s, &r1, j, b0);
            ok = emit(&out->hits, i, j, bpx_wm_bits(a0) & keep0) &&
                 emit(&out->stage, i + 1, j, bpx_wm_bits(b0) & keep1);
        }
    }
    // (Most row pairs of a sparse scene leave the stage empty: no call for those.)
    return ok && (out->stage.count == 0 || bpx__list_append(&out->hits, &out->stage));
}

// One row alone (the last of a block with an odd row count), four steps per group.
static bool row_single(const bpx_soa *s, uint32_t i, uint32_t end, bpx_block *out)
{
    enum { GROUP = 4 * BPX_W };
    const bpx_brute_row r = load_row(s, i);
    uint32_t j = (i + 1) / BPX_W * BPX_W;
    uint32_t keep = lanes_after(i, j);
    out->tests += (end - j + GROUP - 1) / GROUP * GROUP;
    bool ok = true;
    for (; ok && j < end; j += GROUP) {
        bpx_wm m0 = x_test(s, &r, j), m1 = x_test(s, &r, j + BPX_W);
        bpx_wm m2 = x_test(s, &r, j + 2 * BPX_W), m3 = x_test(s, &r, j + 3 * BPX_W);
        if (any4(m0, m1, m2, m3)) {
            m0 = yz_test(s, &r, j, m0);
            m1 = yz_test(s, &r, j + BPX_W, m1);
            m2 = yz_test(s, &r, j + 2 * BPX_W, m2);
            m3 = yz_test(s, &r, j + 3 * BPX_W, m3);
            if (any4(m0, m1, m2, m3))
                ok = emit(&out->hits, i, j, bpx_wm_bits(m0) & keep) &&
                     emit(&out->hits, i, j + BPX_W, bpx_wm_bits(m1)) &&
                     emit(&out->hits, i, j + 2 * BPX_W, bpx_wm_bits(m2)) &&
                     emit(&out->hits, i, j + 3 * BPX_W, bpx_wm_bits(m3));
        }
        keep = lanes_after(0, 1);
    }
    return ok;
}

void BPX_BRUTE_ROWS(const bpx_soa *s, uint32_t row_begin, uint32_t row_end, bpx_block *out)
{
    // Steps run to the end of the padding's whole groups (a multiple of 4 W; see core/backend.h).
    _Static_assert(BPX_PAD_LANES % (4 * BPX_W) == 0, "padding must hold whole groups");
    const uint32_t end = (s->n + 4 * BPX_W - 1) / (4 * BPX_W) * (4 * BPX_W);
    const uint32_t end_steps = (s->n + BPX_W - 1) / BPX_W * BPX_W; // row pairs: whole steps
    uint32_t i = row_begin;
    bool ok = true;
    for (; ok && i + 1 < row_end; i += 2)
        ok = row_pair(s, i, end_steps, out);
    if (ok && i < row_end)
        ok = row_single(s, i, end, out);
    if (!ok)
        out->status = BPX_ERR_OUT_OF_MEMORY;
}
