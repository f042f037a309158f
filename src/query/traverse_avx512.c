// The walks with eight lanes to a vector: compiled with -mavx512f, chosen at run time (the
// world's SIMD width). Each lane runs traverse_scalar.c's operations in the same order, eight
// doubles at a time, so the same bits: vmaxpd(a, b) is a > b ? a : b and vminpd(a, b)
// a < b ? a : b, as there.
#include <immintrin.h>
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "query_prep.h"

enum { GROUPS = BPX_BVH_WIDTH / 8 };
_Static_assert(BPX_BVH_WIDTH % 8 == 0, "lanes in groups of eight");

static inline __m512d widen(const float *lanes)
{
    return _mm512_cvtps_pd(_mm256_load_ps(lanes));
}

static inline uint32_t lanes_box(const bpx_bvh_node *n, const bpx_prepared *p)
{
    uint32_t hit = 0;
    for (int g = 0; g < GROUPS; g++) {
        __mmask16 in = 0xFF;
        for (int a = 0; a < 3; a++) {
            __m512 lo = _mm512_castps256_ps512(_mm256_load_ps(&n->lo[a][8 * g]));
            __m512 hi = _mm512_castps256_ps512(_mm256_load_ps(&n->hi[a][8 * g]));
            in = _mm512_mask_cmp_ps_mask(in, lo, _mm512_set1_ps(p->hi[a]), _CMP_LE_OQ);
            in = _mm512_mask_cmp_ps_mask(in, hi, _mm512_set1_ps(p->lo[a]), _CMP_GE_OQ);
        }
        hit |= (uint32_t)(in & 0xFF) << 8 * g;
    }
    return hit;
}

static inline uint32_t lanes_sphere(const bpx_bvh_node *n, const bpx_prepared *p)
{
    uint32_t hit = 0;
    __m512d zero = _mm512_setzero_pd(), r2 = _mm512_set1_pd(p->radius2);
    for (int g = 0; g < GROUPS; g++) {
        __m512d d2 = _mm512_setzero_pd();
        for (int a = 0; a < 3; a++) {
            __m512d c = _mm512_set1_pd(p->centre[a]);
            __m512d below = _mm512_sub_pd(widen(&n->lo[a][8 * g]), c);
            __m512d above = _mm512_sub_pd(c, widen(&n->hi[a][8 * g]));
            __m512d gap = _mm512_max_pd(_mm512_max_pd(below, above), zero);
            d2 = _mm512_add_pd(d2, _mm512_mul_pd(gap, gap));
        }
        hit |= (uint32_t)_mm512_cmp_pd_mask(d2, r2, _CMP_LE_OQ) << 8 * g;
    }
    return hit;
}

static inline uint32_t lanes_cast(const bpx_bvh_node *n, const bpx_prepared *p, float limit,
                                  float enter[BPX_BVH_WIDTH])
{
    uint32_t hit = 0;
    for (int g = 0; g < GROUPS; g++) {
        __m512d in = _mm512_setzero_pd(), out = _mm512_set1_pd(p->max_fraction);
        __mmask16 overlap = 0xFF;
        for (int a = 0; a < 3; a++) {
            if (!p->moving[a]) {
                __m512 lo = _mm512_castps256_ps512(_mm256_load_ps(&n->lo[a][8 * g]));
                __m512 hi = _mm512_castps256_ps512(_mm256_load_ps(&n->hi[a][8 * g]));
                overlap =
                    _mm512_mask_cmp_ps_mask(overlap, lo, _mm512_set1_ps(p->hi[a]), _CMP_LE_OQ);
                overlap =
                    _mm512_mask_cmp_ps_mask(overlap, hi, _mm512_set1_ps(p->lo[a]), _CMP_GE_OQ);
                continue;
            }
            const float *near = (const float *)((const char *)n + p->near_plane[a]) + 8 * g;
            const float *far = (const float *)((const char *)n + p->far_plane[a]) + 8 * g;
            __m512d inv = _mm512_set1_pd(p->inv[a]);
            __m512d t1 =
                _mm512_mul_pd(_mm512_sub_pd(widen(near), _mm512_set1_pd(p->q_near[a])), inv);
            __m512d t2 = _mm512_mul_pd(_mm512_sub_pd(widen(far), _mm512_set1_pd(p->q_far[a])), inv);
            in = _mm512_max_pd(t1, in);
            out = _mm512_min_pd(t2, out);
        }
        __m256 rounded = _mm512_cvtpd_ps(in);
        _mm256_storeu_ps(enter + 8 * g, rounded);
        __mmask8 h = _mm512_mask_cmp_pd_mask((__mmask8)overlap, in, out, _CMP_LE_OQ);
        __m512 wide = _mm512_castps256_ps512(rounded);
        h = (__mmask8)_mm512_mask_cmp_ps_mask(h, wide, _mm512_set1_ps(limit), _CMP_LE_OQ);
        hit |= (uint32_t)h << 8 * g;
    }
    return hit;
}

// Closest rays and sweeps that move on every axis (rays in a random direction: nearly all),
// the walk of traverse.h's cast_closest with the query's constants held in registers and no
// branch per axis. The lanes' fractions are the same operations in the same order as
// lanes_cast, so the same bits and the same answer.
static bool cast_closest_fast(const bpx_query_view *v, const bpx_prepared *p, bpx_hit_list *out);
#define BPX_CAST_CLOSEST_FAST cast_closest_fast

#define BPX_TRAVERSE bpx__traverse_avx512
#include "traverse.h"

// The bound the lanes' fractions x (in double) are held to while the best hit so far is f:
// x <= the float after f. Every x that rounds to f or less passes (it is at most half a float
// step above f), and so may a few that round to the float after f: a box's lane among those
// fails the exact comparison with the best below, a node among them is entered for nothing
// (a tie that close is rare). Conservative, so nothing is missed however x rounds.
static double best_bound(float f)
{
    return (double)nextafterf(f, INFINITY); // +inf stays +inf
}

static bool cast_closest_fast(const bpx_query_view *v, const bpx_prepared *p, bpx_hit_list *out)
{
    const bpx_bvh *t = v->tree;
    if (!t->node_count)
        return true;
    const __m512d inv0 = _mm512_set1_pd(p->inv[0]), inv1 = _mm512_set1_pd(p->inv[1]),
                  inv2 = _mm512_set1_pd(p->inv[2]);
    const __m512d qn0 = _mm512_set1_pd(p->q_near[0]), qn1 = _mm512_set1_pd(p->q_near[1]),
                  qn2 = _mm512_set1_pd(p->q_near[2]);
    const __m512d qf0 = _mm512_set1_pd(p->q_far[0]), qf1 = _mm512_set1_pd(p->q_far[1]),
                  qf2 = _mm512_set1_pd(p->q_far[2]);
    const __m512d reach = _mm512_set1_pd(p->max_fraction);
    // Per axis, the near plane is the lower one for a positive direction: both planes are
    // loaded and the mask picks (lanes of a mask all set or all clear), no offsets to hold.
    const __mmask8 down0 = p->near_plane[0] != offsetof(bpx_bvh_node, lo[0]) ? 0xFF : 0,
                   down1 = p->near_plane[1] != offsetof(bpx_bvh_node, lo[1]) ? 0xFF : 0,
                   down2 = p->near_plane[2] != offsetof(bpx_bvh_node, lo[2]) ? 0xFF : 0;
    // Fractions are >= +0 (a lane enters at the largest of 0 and its t1s, never NaN), so a
    // float's bits order as the float does: entries are (enter bits << 32 | node).
    uint32_t best_id = UINT32_MAX, best_bits = 0x7F800000u; // +inf
    float best = INFINITY;
    __m512d below = _mm512_set1_pd(INFINITY);
    const bool speculate = t->node_count > SPECULATE_NODES;
    uint64_t stack[STACK];
    int top = 0;
    uint32_t index = 0;
    for (;;) {
        const bpx_bvh_node *n = &t->nodes[index];
        COUNT_VISIT();
        if (speculate)
            prefetch_children(t, n);
#define AXIS(a)                                                                                \
    __m512d t1_##a, t2_##a;                                                                    \
    do {                                                                                       \
        __m512d lo = widen(n->lo[a]), hi = widen(n->hi[a]);                                    \
        __m512d near = _mm512_mask_blend_pd(down##a, lo, hi);                                  \
        __m512d far = _mm512_mask_blend_pd(down##a, hi, lo);                                   \
        t1_##a = _mm512_mul_pd(_mm512_sub_pd(near, qn##a), inv##a);                            \
        t2_##a = _mm512_mul_pd(_mm512_sub_pd(far, qf##a), inv##a);                             \
    } while (0)
        AXIS(0);
        AXIS(1);
        AXIS(2);
#undef AXIS
        // As a tree rather than a chain (lanes_cast's max(t1_z, max(t1_y, max(t1_x, 0)))):
        // the fractions are never NaN, so the same value, and never -0 (the 0 comes last in
        // its max, as there).
        __m512d in = _mm512_max_pd(_mm512_max_pd(t1_0, t1_1), _mm512_max_pd(t1_2, _mm512_setzero_pd()));
        __m512d leave = _mm512_min_pd(_mm512_min_pd(t2_0, t2_1), _mm512_min_pd(t2_2, reach));
        // float(in) <= best checked as in <= below (best_bound), in double: the float
        // conversion leaves the path from a node's load to the next node's.
        __mmask8 hit = _mm512_cmp_pd_mask(in, leave, _CMP_LE_OQ);
        hit = _mm512_mask_cmp_pd_mask(hit, in, below, _CMP_LE_OQ);
        __m256 enter = _mm512_cvtpd_ps(in);
        uint32_t leaves = n->leaves;
        uint32_t boxes = hit & leaves;
        if (boxes) {
            float at[8];
            _mm256_storeu_ps(at, enter);
            do {
                int k = __builtin_ctz(boxes);
                uint32_t id = n->child[k];
                if ((at[k] < best || (at[k] == best && id < best_id)) && bpx__query_seen(v, p, id)) {
                    best = at[k];
                    best_id = id;
                }
                boxes &= boxes - 1;
            } while (boxes);
            memcpy(&best_bits, &best, sizeof best);
            below = _mm512_set1_pd(best_bound(best));
            hit = _mm512_mask_cmp_pd_mask(hit, in, below, _CMP_LE_OQ);
        }
        uint32_t inner = hit & ~leaves;
        if (inner && !(inner & (inner - 1))) { // one child in reach: in at once
            index = n->child[__builtin_ctz(inner)];
            continue;
        }
        if (inner) {
            // Its children in reach by entry, the nearest entered at once, the others pushed
            // farthest first (their lines fetched meanwhile).
            __m512i keys = _mm512_or_si512(
                _mm512_slli_epi64(_mm512_cvtepu32_epi64(_mm256_castps_si256(enter)), 32),
                _mm512_cvtepu32_epi64(_mm256_loadu_si256((const __m256i *)(const void *)n->child)));
            // Compressed in a register, then stored (a compressing store is microcoded on
            // AMD's Zen 4: about 14% of the walk's time).
            uint64_t near[8];
            _mm512_storeu_si512(near, _mm512_maskz_compress_epi64((__mmask8)inner, keys));
            int count = __builtin_popcount(inner);
            for (int i = 1; i < count; i++) { // ascending
                uint64_t e = near[i];
                int j = i;
                for (; j > 0 && near[j - 1] > e; j--)
                    near[j] = near[j - 1];
                near[j] = e;
            }
            for (int i = count - 1; i > 0; i--) {
                prefetch_node(t, (uint32_t)near[i]);
                stack[top++] = near[i];
            }
            index = (uint32_t)near[0];
            continue;
        }
        for (;;) {
            if (!top)
                goto done;
            uint64_t e = stack[--top];
            if ((uint32_t)(e >> 32) <= best_bits) {
                index = (uint32_t)e;
                break;
            }
        }
    }
done:
    if (best_id == UINT32_MAX)
        return true;
    float limit = INFINITY;
    return take_hit(v, p, (bpx_hit){best_id, best}, &limit, out) != FAIL;
}
