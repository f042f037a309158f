// bpx kernels: the linear BVH's build (Karras 2012), one item at a time: the Morton code of a
// centre and one internal node's range and split. SPDX-License-Identifier: MIT
//
// One body for three compilers: OpenCL C 1.2 (the opencl backend's program, after twin.h; its
// kernels in src/opencl/kernels/tree.cl), C11 (the opencl backend's host twin) and CUDA
// (src/cuda/tree.cuh: __host__ __device__, for the cuda backend's kernels and its host twin), so
// the tree both backends build is the same tree. Only integer steps and the float arithmetic
// behind the Morton codes are here; the codes only order the leaves, and no pair depends on
// them.
#ifndef BPX_KERNELS_LBVH_BUILD_H
#define BPX_KERNELS_LBVH_BUILD_H

#ifdef __OPENCL_VERSION__
#pragma OPENCL FP_CONTRACT OFF
// bpx_u32, BPX_FN and BPX_G come from twin.h, just before this file in the program.
#define BPX_LB_CLZ(x) ((int)clz(x))
#define BPX_LB_FLOAT(u) as_float(u)
#else
#include <stdint.h>
#include <string.h>
#ifndef BPX_OPENCL_TWIN_H // CUDA includes this file alone
typedef uint32_t bpx_u32;
#define BPX_G
#ifdef __CUDACC__
#define BPX_FN __host__ __device__ static inline
#else
#define BPX_FN static inline
#endif
#endif
BPX_FN int bpx_lb_clz_(bpx_u32 x)
{
#ifdef __CUDA_ARCH__
    return __clz(x);
#else
    return x ? __builtin_clz(x) : 32;
#endif
}
BPX_FN float bpx_lb_float_(bpx_u32 u)
{
#ifdef __CUDA_ARCH__
    return __uint_as_float(u);
#else
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
#endif
}
#define BPX_LB_CLZ(x) bpx_lb_clz_(x)
#define BPX_LB_FLOAT(u) bpx_lb_float_(u)
#endif

/// A child code's flag (a node's children, in the refits and the walk, lbvh_walk.h): the child
/// is a leaf (a Morton position), else an internal node.
#define BPX_LBVH_LEAF 0x80000000u
/// Depth bound of a walk's stack: the tree splits on at most 32 code bits (30 Morton bits and
/// the inert code's), then on at most 32 position bits among equal codes, and a walk holds at
/// most one pending node per level.
#define BPX_LBVH_STACK 64

/// The float of an order key (twin.h's bpx_key, inverted; -0.0 comes back as +0.0).
BPX_FN float bpx_lbvh_key_value(bpx_u32 key)
{
    return BPX_LB_FLOAT((key & 0x80000000u) ? (key & 0x7FFFFFFFu) : ~key);
}

BPX_FN bpx_u32 bpx_lbvh_spread10(bpx_u32 v)
{
    v = (v | (v << 16)) & 0x030000FFu;
    v = (v | (v << 8)) & 0x0300F00Fu;
    v = (v | (v << 4)) & 0x030C30C3u;
    v = (v | (v << 2)) & 0x09249249u;
    return v;
}

/// Cell 0..1023 of c in [lo, hi] on one axis. Halves before the difference so that a span of
/// +-FLT_MAX does not overflow; a division, not a reciprocal, so a subnormal span gives no
/// infinity; q <= 1 because c <= hi and rounding is monotonic. No NaN can arise.
BPX_FN bpx_u32 bpx_lbvh_cell(float c, float lo, float hi)
{
    float span = 0.5f * hi - 0.5f * lo;
    if (!(span > 0.0f))
        return 0u;
    float q = (0.5f * c - 0.5f * lo) / span * 1024.0f;
    return q <= 0.0f ? 0u : q >= 1023.0f ? 1023u : (bpx_u32)q;
}

/// The 30-bit Morton code of centre c in the scene's centre bounds (order keys: min x, y, z,
/// then max x, y, z), x in the highest bit of each triple.
BPX_FN bpx_u32 bpx_lbvh_morton(const float c[3], const BPX_G bpx_u32 *scene)
{
    bpx_u32 code = 0;
    for (int a = 0; a < 3; a++) {
        bpx_u32 cell =
            bpx_lbvh_cell(c[a], bpx_lbvh_key_value(scene[a]), bpx_lbvh_key_value(scene[3 + a]));
        code |= bpx_lbvh_spread10(cell) << (2 - a);
    }
    return code;
}

/// Length of the common prefix of the codes at positions a and b, the positions breaking ties
/// (so that equal codes, e.g. boxes sharing a centre, still make a binary tree); -1 when b is
/// outside [0, n).
BPX_FN int bpx_lbvh_prefix(const BPX_G bpx_u32 *codes, int n, int a, int b)
{
    if (b < 0 || b >= n)
        return -1;
    bpx_u32 ka = codes[a], kb = codes[b];
    return ka == kb ? 32 + BPX_LB_CLZ((bpx_u32)a ^ (bpx_u32)b) : BPX_LB_CLZ(ka ^ kb);
}

/// Internal node i (of n - 1, root 0) of the tree over n sorted codes: finds its range's other
/// end and its split, independently of every other node, and tells its two children that it is
/// their parent, as (i << 1) | side. The node's left child's range ends at the split, its right
/// child's where the node's does: the walk relies on it.
BPX_FN void bpx_lbvh_build_node(const BPX_G bpx_u32 *codes, int n, int i,
                                BPX_G bpx_u32 *leaf_parent, BPX_G bpx_u32 *node_parent)
{
    int d = bpx_lbvh_prefix(codes, n, i, i + 1) - bpx_lbvh_prefix(codes, n, i, i - 1) > 0 ? 1 : -1;
    int least = bpx_lbvh_prefix(codes, n, i, i - d);
    int reach = 2;
    while (bpx_lbvh_prefix(codes, n, i, i + reach * d) > least)
        reach <<= 1;
    int length = 0;
    for (int step = reach >> 1; step > 0; step >>= 1)
        if (bpx_lbvh_prefix(codes, n, i, i + (length + step) * d) > least)
            length += step;
    int j = i + length * d;
    int node_prefix = bpx_lbvh_prefix(codes, n, i, j);
    int split = 0;
    for (int div = 2;; div <<= 1) {
        int step = (length + div - 1) / div;
        if (bpx_lbvh_prefix(codes, n, i, i + (split + step) * d) > node_prefix)
            split += step;
        if (step <= 1)
            break;
    }
    int gamma = i + split * d + (d < 0 ? d : 0);
    int first = i < j ? i : j, last = i < j ? j : i;
    bpx_u32 up = (bpx_u32)i << 1;
    if (first == gamma)
        leaf_parent[gamma] = up;
    else
        node_parent[gamma] = up;
    if (last == gamma + 1)
        leaf_parent[gamma + 1] = up | 1u;
    else
        node_parent[gamma + 1] = up | 1u;
}

#endif
