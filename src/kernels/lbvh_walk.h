// bpx kernels: the walk of one box over the linear BVH (lbvh_build.h's tree), written once for
// both backends that build it. SPDX-License-Identifier: MIT
//
// The walk of the box at Morton position t (t + 1 < n) goes over the positions after t only,
// from its leaf up (the build's parents, 2p + side): at each ancestor whose left child holds t,
// the right child (positions after t only) is tested and, when it overlaps, walked down; the
// walk ends at the root. Each pair is found once, by the walk from its lower position, at the two
// leaves' lowest common ancestor. Walking down from the root instead tests both children of
// every node on t's own path (about 1.5 tests per level, none of them finding a pair), so
// starting at the leaf saves about one test per level: the tests per box grow by half a test
// per level of depth rather than by 1.5.
//
// The backends keep their own layouts and their own emitters: the opencl backend's tree holds
// the boxes' order keys (src/opencl/kernels/lbvh.h, and so the program and its plain-C twin);
// the cuda backend's holds float bounds (src/cuda/tree.cuh: the kernels, the fake device's
// kernels and test_cuda_twin). Each defines, before this file, how its walk reads and emits, and
// this file writes the walk itself as BPX_WALK_NAME(t, BPX_WALK_PARAMS), returning the bounds
// tests it made. One walk per including file (the macros are undefined at the end). In the
// OpenCL program, which is these files in a row (src/opencl/opencl.cmake), this file follows
// lbvh.h; C and CUDA include it.
//
//   BPX_WALK_PREFIX      what comes before the return type: BPX_FN, or a template's head
//   BPX_WALK_NAME        the function's name
//   BPX_WALK_PARAMS      its parameters after `bpx_u32 t`; among them leaf_parent and
//                        node_parent (the build's: 2p + side of each leaf's and node's parent)
//   BPX_WALK_BOX         the type of the walking box, private
//   BPX_WALK_SLOT        the type of a child slot as read (a copy or a pointer)
//   BPX_WALK_LOAD(box, t)     reads position t's box into box
//   BPX_WALK_LIVE(box)        box has a centre (inert boxes overlap nothing)
//   BPX_WALK_ID(box, t)       the box number of position t
//   BPX_WALK_READ(p, side)    node p's child slot `side` (0 left, 1 right)
//   BPX_WALK_OVERLAP(box, s)  the box overlaps slot s's bounds (Algorithm 1's six comparisons)
//   BPX_WALK_CODE(s)          slot s's child: BPX_LBVH_LEAF | position, or a node
//   BPX_WALK_BEGIN            declarations the emitter needs (after the box is found live)
//   BPX_WALK_HIT(me, at)      emits the pair of box number me and the box at position at
//   BPX_WALK_END              what the emitter does after the walk (a last flush)
//
// One C subset for OpenCL C 1.2, C11 and CUDA; bpx_u32, BPX_LBVH_LEAF and BPX_LBVH_STACK come
// from lbvh_build.h.

BPX_WALK_PREFIX bpx_u32 BPX_WALK_NAME(bpx_u32 t, BPX_WALK_PARAMS)
{
    BPX_WALK_BOX box;
    BPX_WALK_LOAD(box, t);
    if (!(BPX_WALK_LIVE(box)))
        return 0u; // inert: overlaps nothing
    bpx_u32 me = BPX_WALK_ID(box, t);
    bpx_u32 stack[BPX_LBVH_STACK];
    bpx_u32 tests = 0u;
    BPX_WALK_BEGIN
    bpx_u32 up = leaf_parent[t];
    for (;;) {
        bpx_u32 p = up >> 1;
        if ((up & 1u) == 0u) { // t is in p's left child: its right child comes after t
            BPX_WALK_SLOT right = BPX_WALK_READ(p, 1u);
            tests++;
            if (BPX_WALK_OVERLAP(box, right)) {
                bpx_u32 child = BPX_WALK_CODE(right);
                if (child & BPX_LBVH_LEAF) {
                    BPX_WALK_HIT(me, child & ~BPX_LBVH_LEAF);
                } else {
                    // Down the right child's subtree: every position in it comes after t.
                    int top = 0;
                    bpx_u32 node = child;
                    for (;;) {
                        BPX_WALK_SLOT l = BPX_WALK_READ(node, 0u);
                        BPX_WALK_SLOT r = BPX_WALK_READ(node, 1u);
                        bpx_u32 left = BPX_WALK_CODE(l), right_code = BPX_WALK_CODE(r);
                        int go_left = BPX_WALK_OVERLAP(box, l);
                        int go_right = BPX_WALK_OVERLAP(box, r);
                        tests += 2u;
                        if (go_left && (left & BPX_LBVH_LEAF)) {
                            BPX_WALK_HIT(me, left & ~BPX_LBVH_LEAF);
                            go_left = 0;
                        }
                        if (go_right && (right_code & BPX_LBVH_LEAF)) {
                            BPX_WALK_HIT(me, right_code & ~BPX_LBVH_LEAF);
                            go_right = 0;
                        }
                        if (go_left && go_right) {
                            stack[top++] = right_code;
                            node = left;
                        } else if (go_left) {
                            node = left;
                        } else if (go_right) {
                            node = right_code;
                        } else {
                            if (top == 0)
                                break;
                            node = stack[--top];
                        }
                    }
                }
            }
        }
        if (p == 0u)
            break; // the root
        up = node_parent[p];
    }
    BPX_WALK_END
    return tests;
}

#undef BPX_WALK_PREFIX
#undef BPX_WALK_NAME
#undef BPX_WALK_PARAMS
#undef BPX_WALK_BOX
#undef BPX_WALK_SLOT
#undef BPX_WALK_LOAD
#undef BPX_WALK_LIVE
#undef BPX_WALK_ID
#undef BPX_WALK_READ
#undef BPX_WALK_OVERLAP
#undef BPX_WALK_CODE
#undef BPX_WALK_BEGIN
#undef BPX_WALK_HIT
#undef BPX_WALK_END
