// Wide-float layer, AVX2: 8 lanes. See wide_avx512.h for the operations' contract.
#pragma once

#include <immintrin.h>
#include <stdint.h>

#define BPX_W 8
typedef __m256 bpx_wf;
typedef __m256 bpx_wm;

static inline bpx_wf bpx_wf_load(const float *p) { return _mm256_load_ps(p); }
static inline bpx_wf bpx_wf_loadu(const float *p) { return _mm256_loadu_ps(p); }
static inline bpx_wf bpx_wf_set1(float x) { return _mm256_set1_ps(x); }
static inline bpx_wm bpx_wm_le(bpx_wf a, bpx_wf b) { return _mm256_cmp_ps(a, b, _CMP_LE_OQ); }
static inline bpx_wm bpx_wm_le_and(bpx_wm m, bpx_wf a, bpx_wf b)
{
    return _mm256_and_ps(m, _mm256_cmp_ps(a, b, _CMP_LE_OQ));
}
static inline bpx_wm bpx_wm_or(bpx_wm a, bpx_wm b) { return _mm256_or_ps(a, b); }
static inline int bpx_wm_any(bpx_wm m) { return !_mm256_testz_ps(m, m); }
static inline uint32_t bpx_wm_bits(bpx_wm m) { return (uint32_t)_mm256_movemask_ps(m); }
