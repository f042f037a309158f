// Four boxes between array-of-structures form (bpx_box: min x y z, max x y z, 24 bytes each) and
// structure-of-arrays form (six vectors: min x of the four, min y, ... max z), with SSE2, the
// x86-64 baseline. The updater's transpose and sap's box check run 3-4x faster this way than
// box by box (set_boxes of 1,000 boxes takes 7 us box by box).
#pragma once

#include "bpx/types.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#define BPX_HAVE_TRANSPOSE4 1

/// boxes[0..3] -> v[0] = min x of the four, v[1] = min y, v[2] = min z, v[3..5] = max x, y, z.
static inline void bpx__boxes4_to_soa(const bpx_box *boxes, __m128 v[6])
{
    const float *f = (const float *)(const void *)boxes; // 6 floats a box, no padding
    __m128 a = _mm_loadu_ps(f), b = _mm_loadu_ps(f + 4), c = _mm_loadu_ps(f + 8);
    __m128 d = _mm_loadu_ps(f + 12), e = _mm_loadu_ps(f + 16), g = _mm_loadu_ps(f + 20);
    // a = x0 y0 z0 X0 | b = Y0 Z0 x1 y1 | c = z1 X1 Y1 Z1 (lower case: min, upper: max)
    __m128 box1 = _mm_shuffle_ps(b, c, _MM_SHUFFLE(1, 0, 3, 2)); // x1 y1 z1 X1
    __m128 box3 = _mm_shuffle_ps(e, g, _MM_SHUFFLE(1, 0, 3, 2)); // x3 y3 z3 X3
    __m128 t0 = _mm_unpacklo_ps(a, box1), t1 = _mm_unpackhi_ps(a, box1); // x0 x1 y0 y1 | z0 z1 X0 X1
    __m128 t2 = _mm_unpacklo_ps(d, box3), t3 = _mm_unpackhi_ps(d, box3); // x2 x3 y2 y3 | z2 z3 X2 X3
    v[0] = _mm_movelh_ps(t0, t2);
    v[1] = _mm_movehl_ps(t2, t0);
    v[2] = _mm_movelh_ps(t1, t3);
    v[3] = _mm_movehl_ps(t3, t1);
    __m128 yz01 = _mm_shuffle_ps(b, c, _MM_SHUFFLE(3, 2, 1, 0)); // Y0 Z0 Y1 Z1
    __m128 yz23 = _mm_shuffle_ps(e, g, _MM_SHUFFLE(3, 2, 1, 0)); // Y2 Z2 Y3 Z3
    v[4] = _mm_shuffle_ps(yz01, yz23, _MM_SHUFFLE(2, 0, 2, 0));
    v[5] = _mm_shuffle_ps(yz01, yz23, _MM_SHUFFLE(3, 1, 3, 1));
}

/// The inverse: six SoA vectors -> boxes[0..3].
static inline void bpx__soa4_to_boxes(const __m128 v[6], bpx_box *boxes)
{
    // t0 = x0 y0 x1 y1, t1 = x2 y2 x3 y3, t2 = z0 X0 z1 X1, t3 = z2 X2 z3 X3,
    // t4 = Y0 Z0 Y1 Z1, t5 = Y2 Z2 Y3 Z3
    __m128 t0 = _mm_unpacklo_ps(v[0], v[1]), t1 = _mm_unpackhi_ps(v[0], v[1]);
    __m128 t2 = _mm_unpacklo_ps(v[2], v[3]), t3 = _mm_unpackhi_ps(v[2], v[3]);
    __m128 t4 = _mm_unpacklo_ps(v[4], v[5]), t5 = _mm_unpackhi_ps(v[4], v[5]);
    float *f = (float *)(void *)boxes;
    _mm_storeu_ps(f, _mm_movelh_ps(t0, t2));                                 // x0 y0 z0 X0
    _mm_storeu_ps(f + 4, _mm_shuffle_ps(t4, t0, _MM_SHUFFLE(3, 2, 1, 0)));  // Y0 Z0 x1 y1
    _mm_storeu_ps(f + 8, _mm_shuffle_ps(t2, t4, _MM_SHUFFLE(3, 2, 3, 2)));  // z1 X1 Y1 Z1
    _mm_storeu_ps(f + 12, _mm_movelh_ps(t1, t3));                            // x2 y2 z2 X2
    _mm_storeu_ps(f + 16, _mm_shuffle_ps(t5, t1, _MM_SHUFFLE(3, 2, 1, 0))); // Y2 Z2 x3 y3
    _mm_storeu_ps(f + 20, _mm_shuffle_ps(t3, t5, _MM_SHUFFLE(3, 2, 3, 2))); // z3 X3 Y3 Z3
}
#endif
