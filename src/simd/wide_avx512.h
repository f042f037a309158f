// Wide-float layer, AVX-512F: 16 lanes.
//
// The contract every wide_*.h keeps (the comparator is written once over it):
//   BPX_W                  lanes
//   bpx_wf_load(p)         W floats from p, aligned to 4 * W bytes
//   bpx_wf_loadu(p)        W floats from p, any alignment
//   bpx_wf_set1(x)         x in every lane
//   bpx_wm_le(a, b)        lane mask of a <= b (ordered: false for NaN, -0.0 == 0.0)
//   bpx_wm_le_and(m, a, b) m AND (a <= b); AVX-512 does it in one masked compare
//   bpx_wm_or(a, b)        a OR b
//   bpx_wm_any(m)          any lane set
//   bpx_wm_bits(m)         lane k -> bit k
#pragma once

#include <immintrin.h>
#include <stdint.h>

#define BPX_W 16
typedef __m512 bpx_wf;
typedef __mmask16 bpx_wm;

static inline bpx_wf bpx_wf_load(const float *p) { return _mm512_load_ps(p); }
static inline bpx_wf bpx_wf_loadu(const float *p) { return _mm512_loadu_ps(p); }
static inline bpx_wf bpx_wf_set1(float x) { return _mm512_set1_ps(x); }
static inline bpx_wm bpx_wm_le(bpx_wf a, bpx_wf b) { return _mm512_cmp_ps_mask(a, b, _CMP_LE_OQ); }
static inline bpx_wm bpx_wm_le_and(bpx_wm m, bpx_wf a, bpx_wf b)
{
    return _mm512_mask_cmp_ps_mask(m, a, b, _CMP_LE_OQ);
}
static inline bpx_wm bpx_wm_or(bpx_wm a, bpx_wm b) { return (bpx_wm)(a | b); }
static inline int bpx_wm_any(bpx_wm m) { return m != 0; }
static inline uint32_t bpx_wm_bits(bpx_wm m) { return (uint32_t)m; }
