// The walks with four lanes to a vector (a node's lanes in groups of four): compiled with
// -mavx2, chosen at run time (the world's SIMD width). Each lane runs traverse_scalar.c's
// operations in the same order, four doubles at a time, so the same bits: vmaxpd(a, b) is
// a > b ? a : b and vminpd(a, b) a < b ? a : b, as there.
#include <immintrin.h>
#include <math.h>
#include <stddef.h>

#include "query_prep.h"

enum { GROUPS = BPX_BVH_WIDTH / 4 };
_Static_assert(BPX_BVH_WIDTH % 4 == 0, "lanes in groups of four");

static inline uint32_t lanes_box(const bpx_bvh_node *n, const bpx_prepared *p)
{
    uint32_t hit = 0;
    for (int g = 0; g < GROUPS; g++) {
        __m128 in = _mm_castsi128_ps(_mm_set1_epi32(-1));
        for (int a = 0; a < 3; a++) {
            in = _mm_and_ps(in, _mm_cmple_ps(_mm_load_ps(&n->lo[a][4 * g]), _mm_set1_ps(p->hi[a])));
            in = _mm_and_ps(in, _mm_cmpge_ps(_mm_load_ps(&n->hi[a][4 * g]), _mm_set1_ps(p->lo[a])));
        }
        hit |= (uint32_t)_mm_movemask_ps(in) << 4 * g;
    }
    return hit;
}

static inline uint32_t lanes_sphere(const bpx_bvh_node *n, const bpx_prepared *p)
{
    uint32_t hit = 0;
    __m256d zero = _mm256_setzero_pd(), r2 = _mm256_set1_pd(p->radius2);
    for (int g = 0; g < GROUPS; g++) {
        __m256d d2 = _mm256_setzero_pd();
        for (int a = 0; a < 3; a++) {
            __m256d c = _mm256_set1_pd(p->centre[a]);
            __m256d below = _mm256_sub_pd(_mm256_cvtps_pd(_mm_load_ps(&n->lo[a][4 * g])), c);
            __m256d above = _mm256_sub_pd(c, _mm256_cvtps_pd(_mm_load_ps(&n->hi[a][4 * g])));
            __m256d gap = _mm256_max_pd(_mm256_max_pd(below, above), zero);
            d2 = _mm256_add_pd(d2, _mm256_mul_pd(gap, gap));
        }
        hit |= (uint32_t)_mm256_movemask_pd(_mm256_cmp_pd(d2, r2, _CMP_LE_OQ)) << 4 * g;
    }
    return hit;
}

static inline __m256d plane(const bpx_bvh_node *n, uint32_t offset, int g)
{
    return _mm256_cvtps_pd(_mm_load_ps((const float *)((const char *)n + offset) + 4 * g));
}

static inline uint32_t lanes_cast(const bpx_bvh_node *n, const bpx_prepared *p, float limit,
                                  float enter[BPX_BVH_WIDTH])
{
    uint32_t hit = 0;
    for (int g = 0; g < GROUPS; g++) {
        __m256d in = _mm256_setzero_pd(), out = _mm256_set1_pd(p->max_fraction);
        __m128 overlap = _mm_castsi128_ps(_mm_set1_epi32(-1));
        for (int a = 0; a < 3; a++) {
            if (!p->moving[a]) {
                overlap = _mm_and_ps(
                    overlap, _mm_cmple_ps(_mm_load_ps(&n->lo[a][4 * g]), _mm_set1_ps(p->hi[a])));
                overlap = _mm_and_ps(
                    overlap, _mm_cmpge_ps(_mm_load_ps(&n->hi[a][4 * g]), _mm_set1_ps(p->lo[a])));
                continue;
            }
            __m256d inv = _mm256_set1_pd(p->inv[a]);
            __m256d t1 = _mm256_mul_pd(
                _mm256_sub_pd(plane(n, p->near_plane[a], g), _mm256_set1_pd(p->q_near[a])), inv);
            __m256d t2 = _mm256_mul_pd(
                _mm256_sub_pd(plane(n, p->far_plane[a], g), _mm256_set1_pd(p->q_far[a])), inv);
            in = _mm256_max_pd(t1, in);
            out = _mm256_min_pd(t2, out);
        }
        __m128 rounded = _mm256_cvtpd_ps(in);
        _mm_storeu_ps(enter + 4 * g, rounded);
        uint32_t h = (uint32_t)_mm256_movemask_pd(_mm256_cmp_pd(in, out, _CMP_LE_OQ));
        h &= (uint32_t)_mm_movemask_ps(
            _mm_and_ps(overlap, _mm_cmple_ps(rounded, _mm_set1_ps(limit))));
        hit |= h << 4 * g;
    }
    return hit;
}

#define BPX_TRAVERSE bpx__traverse_avx2
#include "traverse.h"
