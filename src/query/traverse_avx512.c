// The walks with eight lanes to a vector: compiled with -mavx512f, chosen at run time (the
// world's SIMD width). Each lane runs traverse_scalar.c's operations in the same order, eight
// doubles at a time, so the same bits: vmaxpd(a, b) is a > b ? a : b and vminpd(a, b)
// a < b ? a : b, as there.
#include <immintrin.h>
#include <math.h>
#include <stddef.h>

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

#define BPX_TRAVERSE bpx__traverse_avx512
#include "traverse.h"
