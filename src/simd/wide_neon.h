// Wide-float layer, NEON (AArch64): 4 lanes. See wide_avx512.h for the operations' contract.
#pragma once

#include <arm_neon.h>
#include <stdint.h>

#define BPX_W 4
typedef float32x4_t bpx_wf;
typedef uint32x4_t bpx_wm;

static inline bpx_wf bpx_wf_load(const float *p) { return vld1q_f32(p); }
static inline bpx_wf bpx_wf_loadu(const float *p) { return vld1q_f32(p); }
static inline bpx_wf bpx_wf_set1(float x) { return vdupq_n_f32(x); }
static inline bpx_wm bpx_wm_le(bpx_wf a, bpx_wf b) { return vcleq_f32(a, b); }
static inline bpx_wm bpx_wm_le_and(bpx_wm m, bpx_wf a, bpx_wf b)
{
    return vandq_u32(m, vcleq_f32(a, b));
}
static inline bpx_wm bpx_wm_or(bpx_wm a, bpx_wm b) { return vorrq_u32(a, b); }
static inline int bpx_wm_any(bpx_wm m) { return vmaxvq_u32(m) != 0; }
static inline uint32_t bpx_wm_bits(bpx_wm m)
{
    const uint32x4_t weights = {1, 2, 4, 8};
    return vaddvq_u32(vandq_u32(m, weights));
}
