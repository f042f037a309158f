#include "cpu_features.h"

#include <stdatomic.h>

#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>

// AVX and AVX-512 need the OS to save their registers: XCR0 tells (Intel SDM 13.3).
static unsigned long long read_xcr0(void)
{
    unsigned eax, edx;
    __asm__ volatile("xgetbv" : "=a"(eax), "=d"(edx) : "c"(0));
    return ((unsigned long long)edx << 32) | eax;
}

static bool detect(bpx_simd simd)
{
    unsigned a, b, c, d;
    switch (simd) {
    case BPX_SIMD_SCALAR:
        return true;
    case BPX_SIMD_SSE2:
        return __get_cpuid(1, &a, &b, &c, &d) && (d & bit_SSE2);
    case BPX_SIMD_AVX2:
    case BPX_SIMD_AVX512: {
        if (!__get_cpuid(1, &a, &b, &c, &d) || !(c & bit_OSXSAVE) || !(c & bit_AVX))
            return false;
        unsigned long long xcr0 = read_xcr0();
        if ((xcr0 & 0x6) != 0x6) // SSE and AVX state
            return false;
        if (!__get_cpuid_count(7, 0, &a, &b, &c, &d))
            return false;
        if (simd == BPX_SIMD_AVX2)
            return (b & bit_AVX2) != 0;
        return (b & bit_AVX512F) && (xcr0 & 0xE6) == 0xE6; // + opmask, ZMM state
    }
    default:
        return false;
    }
}

#elif defined(__aarch64__)

static bool detect(bpx_simd simd)
{
    return simd == BPX_SIMD_SCALAR || simd == BPX_SIMD_NEON; // NEON is baseline on AArch64
}

#else

static bool detect(bpx_simd simd)
{
    return simd == BPX_SIMD_SCALAR;
}

#endif

// CPUID is slow (in a virtual machine it traps to the hypervisor, microseconds), and every
// collide asks: detect once. Racing first callers compute the same answer.
bool bpx__cpu_supports(bpx_simd simd)
{
    static _Atomic int known[BPX_SIMD_COUNT]; // 0 unknown, 1 no, 2 yes
    if ((unsigned)simd >= BPX_SIMD_COUNT)
        return false;
    int k = atomic_load_explicit(&known[simd], memory_order_relaxed);
    if (k == 0) {
        k = detect(simd) ? 2 : 1;
        atomic_store_explicit(&known[simd], k, memory_order_relaxed);
    }
    return k == 2;
}
