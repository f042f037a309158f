// bpx OpenCL kernels: the pieces shared, word for word, by the device program and its plain-C
// twin (src/opencl/twin.c), so that the logic can be stepped through on the host.
// SPDX-License-Identifier: MIT
//
// Valid OpenCL C 1.2 and C11. Boxes live on the device as keys: each float coordinate mapped to
// an unsigned integer with the same order (-0.0 and +0.0 to the same key). Every overlap decision
// is then an integer comparison, exact on any device, whatever it does with subnormal floats.
#ifndef BPX_OPENCL_TWIN_H
#define BPX_OPENCL_TWIN_H

#ifdef __OPENCL_VERSION__
#define BPX_FN
#define BPX_G __global
typedef uint bpx_u32;
typedef ulong bpx_u64;
#define BPX_FLOAT_BITS(f) as_uint(f)
#else
#include <stdint.h>
#include <string.h>
#define BPX_FN static inline
#define BPX_G
typedef uint32_t bpx_u32;
typedef uint64_t bpx_u64;
static inline bpx_u32 bpx_float_bits_(float f)
{
    bpx_u32 u;
    memcpy(&u, &f, sizeof u);
    return u;
}
#define BPX_FLOAT_BITS(f) bpx_float_bits_(f)
#endif

/// Key of a padding box's minimum: above every finite key, so a padding box overlaps nothing.
#define BPX_KEY_PAD_LO 0xFFFFFFFFu
/// Key of a padding box's maximum: below every finite key.
#define BPX_KEY_PAD_HI 0u
/// Keys per box and side on the device: x, y, z and a fourth lane that always passes
/// (lo.w = hi.w = 0), so one four-lane compare does three axes.
#define BPX_KEY_LANES 4

/// Order-preserving key of a float's bits: for non-NaN a, b, a <= b iff key(a) <= key(b).
/// Negative floats have their bits inverted, others get the sign bit set; -0.0 becomes +0.0 first.
BPX_FN bpx_u32 bpx_key(bpx_u32 bits)
{
    bits = bits == 0x80000000u ? 0u : bits;
    return (bits & 0x80000000u) ? ~bits : (bits | 0x80000000u);
}

/// Algorithm 1 on keys, lane by lane (the device kernels do the same with vector compares).
BPX_FN int bpx_keys_overlap(const BPX_G bpx_u32 *lo_i, const BPX_G bpx_u32 *hi_i,
                            const BPX_G bpx_u32 *lo_j, const BPX_G bpx_u32 *hi_j)
{
    int hit = 1;
    for (int a = 0; a < 3; a++)
        hit &= (lo_i[a] <= hi_j[a]) & (lo_j[a] <= hi_i[a]);
    return hit;
}

/// A box's keys from its six floats in bpx_box order (min x, y, z, max x, y, z), `plane` floats
/// apart: 1 for an array of bpx_box, the plane length for six planes (x min plane, ...).
BPX_FN void bpx_box_keys(const BPX_G float *box, bpx_u32 plane, BPX_G bpx_u32 *lo,
                         BPX_G bpx_u32 *hi)
{
    for (bpx_u32 a = 0; a < 3; a++) {
        lo[a] = bpx_key(BPX_FLOAT_BITS(box[(bpx_u64)a * plane]));
        hi[a] = bpx_key(BPX_FLOAT_BITS(box[(bpx_u64)(3 + a) * plane]));
    }
    lo[3] = 0u;
    hi[3] = 0u;
}

/// The paper's updater for object i: min = centre + minimum, max = centre - minimum, per axis,
/// in single precision (one correctly rounded add each, as on the host). Centres are x, y, z per
/// object; minima are three planes of `stride` floats (x plane, then y, then z).
BPX_FN void bpx_update_keys(const BPX_G float *centres, const BPX_G float *minima, bpx_u32 stride,
                            bpx_u32 i, BPX_G bpx_u32 *lo, BPX_G bpx_u32 *hi)
{
    for (int a = 0; a < 3; a++) {
        float c = centres[3 * (bpx_u64)i + (bpx_u32)a];
        float m = minima[(bpx_u64)a * stride + i];
        float low = c + m;
        float high = c - m;
        lo[a] = bpx_key(BPX_FLOAT_BITS(low));
        hi[a] = bpx_key(BPX_FLOAT_BITS(high));
    }
    lo[3] = 0u;
    hi[3] = 0u;
}

/// Why a box from a caller's device buffer is invalid: 0 valid, 1 a coordinate not finite,
/// 2 min > max. The axis goes to *axis. Same order as the host's check: every coordinate's
/// finiteness first, then min <= max.
BPX_FN int bpx_box_problem(const BPX_G float *box, int *axis)
{
    for (int a = 0; a < 6; a++) {
        bpx_u32 bits = BPX_FLOAT_BITS(box[a]);
        if ((bits & 0x7F800000u) == 0x7F800000u) {
            *axis = a % 3;
            return 1;
        }
    }
    for (int a = 0; a < 3; a++)
        if (bpx_key(BPX_FLOAT_BITS(box[a])) > bpx_key(BPX_FLOAT_BITS(box[3 + a]))) {
            *axis = a;
            return 2;
        }
    return 0;
}

/// The first axis on which object i's box (centre + minimum, centre - minimum, as
/// bpx_update_keys makes it) is not finite, or -1: the host's check of bpx_world_update_centres.
/// A NaN fails both comparisons.
BPX_FN int bpx_centre_problem(const BPX_G float *centres, const BPX_G float *minima, bpx_u32 stride,
                              bpx_u32 i)
{
    for (int a = 0; a < 3; a++) {
        float c = centres[3 * (bpx_u64)i + (bpx_u32)a];
        float m = minima[(bpx_u64)a * stride + i];
        float low = c + m;
        float high = c - m;
        if (!(-3.40282347e38f <= low && high <= 3.40282347e38f))
            return a;
    }
    return -1;
}

/// Sort and sweep, one sorted position p: boxes sorted by min-x key (ties by index), their keys
/// gathered into sorted order, `index` the box number at each position. Walks q = p + 1, ...
/// while q's min x <= p's max x; every overlapping q makes the pair (min, max) of the two box
/// numbers. Counts them (out == 0) or writes them to out_i / out_j from `offset` (pairs at or
/// beyond `capacity` are dropped; the caller re-runs with room). Returns the count.
BPX_FN bpx_u32 bpx_sweep_position(const BPX_G bpx_u32 *lo, const BPX_G bpx_u32 *hi,
                                  const BPX_G bpx_u32 *index, bpx_u32 n, bpx_u32 p,
                                  BPX_G bpx_u32 *out_i, BPX_G bpx_u32 *out_j, bpx_u64 offset,
                                  bpx_u64 capacity)
{
    const BPX_G bpx_u32 *lo_p = lo + (bpx_u64)p * BPX_KEY_LANES;
    const BPX_G bpx_u32 *hi_p = hi + (bpx_u64)p * BPX_KEY_LANES;
    bpx_u32 count = 0;
    bpx_u32 reach = hi_p[0];
    bpx_u32 me = index[p];
    for (bpx_u32 q = p + 1; q < n && lo[(bpx_u64)q * BPX_KEY_LANES] <= reach; q++) {
        const BPX_G bpx_u32 *lo_q = lo + (bpx_u64)q * BPX_KEY_LANES;
        const BPX_G bpx_u32 *hi_q = hi + (bpx_u64)q * BPX_KEY_LANES;
        if (bpx_keys_overlap(lo_p, hi_p, lo_q, hi_q)) {
            bpx_u64 slot = offset + count;
            if (out_i && slot < capacity) {
                bpx_u32 other = index[q];
                out_i[slot] = me < other ? me : other;
                out_j[slot] = me < other ? other : me;
            }
            count++;
        }
    }
    return count;
}

#endif
