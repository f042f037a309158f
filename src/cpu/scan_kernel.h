// sap's scan mend (sap/scan.c): the boxes of a sorted run tested against a box's old and new fat
// boxes at once, written once over the wide-float layer like prune_kernel.h.
#include "cpu/backends.h"

#ifndef BPX_SCAN_DIFFERS
#error "define BPX_SCAN_DIFFERS before including scan_kernel.h"
#endif

// Positions [k0, k1) of s whose box overlaps exactly one of a and b (each min then max per slot,
// in s's slot order; closed intervals), ascending into out; returns their count. Reads up to
// BPX_W - 1 positions past k1 (s is padded).
uint32_t BPX_SCAN_DIFFERS(const bpx_sorted *s, uint32_t k0, uint32_t k1, const float a[6],
                          const float b[6], uint32_t *out)
{
    const bpx_wf alx = bpx_wf_set1(a[0]), aly = bpx_wf_set1(a[1]), alz = bpx_wf_set1(a[2]);
    const bpx_wf ahx = bpx_wf_set1(a[3]), ahy = bpx_wf_set1(a[4]), ahz = bpx_wf_set1(a[5]);
    const bpx_wf blx = bpx_wf_set1(b[0]), bly = bpx_wf_set1(b[1]), blz = bpx_wf_set1(b[2]);
    const bpx_wf bhx = bpx_wf_set1(b[3]), bhy = bpx_wf_set1(b[4]), bhz = bpx_wf_set1(b[5]);
    const uint32_t all = (uint32_t)((1ull << BPX_W) - 1);
    uint32_t count = 0;
    for (uint32_t k = k0; k < k1; k += BPX_W) {
        bpx_wf lx = bpx_wf_loadu(s->lo[0] + k), hx = bpx_wf_loadu(s->hi[0] + k);
        bpx_wf ly = bpx_wf_loadu(s->lo[1] + k), hy = bpx_wf_loadu(s->hi[1] + k);
        bpx_wf lz = bpx_wf_loadu(s->lo[2] + k), hz = bpx_wf_loadu(s->hi[2] + k);
        bpx_wm ma = bpx_wm_le(lx, ahx);
        ma = bpx_wm_le_and(ma, alx, hx);
        ma = bpx_wm_le_and(ma, ly, ahy);
        ma = bpx_wm_le_and(ma, aly, hy);
        ma = bpx_wm_le_and(ma, lz, ahz);
        ma = bpx_wm_le_and(ma, alz, hz);
        bpx_wm mb = bpx_wm_le(lx, bhx);
        mb = bpx_wm_le_and(mb, blx, hx);
        mb = bpx_wm_le_and(mb, ly, bhy);
        mb = bpx_wm_le_and(mb, bly, hy);
        mb = bpx_wm_le_and(mb, lz, bhz);
        mb = bpx_wm_le_and(mb, blz, hz);
        uint32_t left = k1 - k;
        uint32_t valid = left >= BPX_W ? all : (uint32_t)((1ull << left) - 1);
        uint32_t bits = (bpx_wm_bits(ma) ^ bpx_wm_bits(mb)) & valid;
        while (bits) {
            out[count++] = k + (uint32_t)__builtin_ctz(bits);
            bits &= bits - 1;
        }
    }
    return count;
}
