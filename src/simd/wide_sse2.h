// Wide-float layer, SSE2: 4 lanes. See wide_avx512.h for the operations' contract.
#pragma once

#include <emmintrin.h>
#include <stdint.h>

#define BPX_W 4
typedef __m128 bpx_wf;
typedef __m128 bpx_wm;

static inline bpx_wf bpx_wf_load(const float *p) { return _mm_load_ps(p); }
static inline bpx_wf bpx_wf_loadu(const float *p) { return _mm_loadu_ps(p); }
static inline bpx_wf bpx_wf_set1(float x) { return _mm_set1_ps(x); }
static inline bpx_wm bpx_wm_le(bpx_wf a, bpx_wf b) { return _mm_cmple_ps(a, b); }
static inline bpx_wm bpx_wm_le_and(bpx_wm m, bpx_wf a, bpx_wf b)
{
    return _mm_and_ps(m, _mm_cmple_ps(a, b));
}
static inline bpx_wm bpx_wm_or(bpx_wm a, bpx_wm b) { return _mm_or_ps(a, b); }
static inline int bpx_wm_any(bpx_wm m) { return _mm_movemask_ps(m) != 0; }
static inline uint32_t bpx_wm_bits(bpx_wm m) { return (uint32_t)_mm_movemask_ps(m); }
