// Wide-float layer, portable scalar: one lane. See wide_avx512.h for the operations' contract.
#pragma once

#include <stdint.h>

#define BPX_W 1
typedef float bpx_wf;
typedef uint32_t bpx_wm;

static inline bpx_wf bpx_wf_load(const float *p) { return *p; }
static inline bpx_wf bpx_wf_loadu(const float *p) { return *p; }
static inline bpx_wf bpx_wf_set1(float x) { return x; }
static inline bpx_wm bpx_wm_le(bpx_wf a, bpx_wf b) { return a <= b; }
static inline bpx_wm bpx_wm_le_and(bpx_wm m, bpx_wf a, bpx_wf b) { return m & (a <= b); }
static inline bpx_wm bpx_wm_or(bpx_wm a, bpx_wm b) { return a | b; }
static inline int bpx_wm_any(bpx_wm m) { return m != 0; }
static inline uint32_t bpx_wm_bits(bpx_wm m) { return m; }
