#include "cpu_features.h"

#include <stdatomic.h>
#include <string.h>

#include "bpx/bpx.h"

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

// ---------------------------------------------------------------------------------------------
// The kernels of each instruction set in this build, and the choice among them

#define BPX_DECLARE_KERNELS(isa)                                                                   \
    bpx_brute_rows_fn bpx__brute_rows_##isa;                                                       \
    bpx_prune_rows_fn bpx__prune_rows_##isa;                                                       \
    bpx_scan_differs_fn bpx__scan_differs_##isa;
BPX_DECLARE_KERNELS(scalar)
#if BPX_HAVE_SSE2
BPX_DECLARE_KERNELS(sse2)
#endif
#if BPX_HAVE_AVX2
BPX_DECLARE_KERNELS(avx2)
#endif
#if BPX_HAVE_AVX512
BPX_DECLARE_KERNELS(avx512)
#endif
#if BPX_HAVE_NEON
BPX_DECLARE_KERNELS(neon)
#endif

typedef struct simd_variant {
    const char *name;
    int lanes;
    bpx_brute_rows_fn *brute; // NULL: not compiled into this build
    bpx_prune_rows_fn *prune;
    bpx_scan_differs_fn *scan;
} simd_variant;

#define BPX_KERNELS(isa) bpx__brute_rows_##isa, bpx__prune_rows_##isa, bpx__scan_differs_##isa
static const simd_variant variants[BPX_SIMD_COUNT] = {
    [BPX_SIMD_AUTO] = {"auto", 0, NULL, NULL, NULL},
    [BPX_SIMD_SCALAR] = {"scalar", 1, BPX_KERNELS(scalar)},
#if BPX_HAVE_SSE2
    [BPX_SIMD_SSE2] = {"sse2", 4, BPX_KERNELS(sse2)},
#else
    [BPX_SIMD_SSE2] = {"sse2", 4, NULL, NULL, NULL},
#endif
#if BPX_HAVE_AVX2
    [BPX_SIMD_AVX2] = {"avx2", 8, BPX_KERNELS(avx2)},
#else
    [BPX_SIMD_AVX2] = {"avx2", 8, NULL, NULL, NULL},
#endif
#if BPX_HAVE_AVX512
    [BPX_SIMD_AVX512] = {"avx512", 16, BPX_KERNELS(avx512)},
#else
    [BPX_SIMD_AVX512] = {"avx512", 16, NULL, NULL, NULL},
#endif
#if BPX_HAVE_NEON
    [BPX_SIMD_NEON] = {"neon", 4, BPX_KERNELS(neon)},
#else
    [BPX_SIMD_NEON] = {"neon", 4, NULL, NULL, NULL},
#endif
};

static bpx_simd usable(bpx_simd simd)
{
    if (simd == BPX_SIMD_AUTO)
        return bpx_simd_best();
    return bpx_simd_supported(simd) ? simd : BPX_SIMD_SCALAR;
}

bpx_brute_rows_fn *bpx__brute_rows_for(bpx_simd simd)
{
    return variants[usable(simd)].brute;
}

bpx_prune_rows_fn *bpx__prune_rows_for(bpx_simd simd)
{
    return variants[usable(simd)].prune;
}

bpx_scan_differs_fn *bpx__scan_differs_for(bpx_simd simd)
{
    return variants[usable(simd)].scan;
}

const char *bpx_simd_name(bpx_simd simd)
{
    return (unsigned)simd < BPX_SIMD_COUNT ? variants[simd].name : NULL;
}

bpx_status bpx_simd_from_name(const char *name, bpx_simd *out)
{
    if (!name || !out)
        return BPX_ERR_NULL_ARGUMENT;
    for (int s = 0; s < BPX_SIMD_COUNT; s++)
        if (strcmp(variants[s].name, name) == 0) {
            *out = (bpx_simd)s;
            return BPX_OK;
        }
    return BPX_ERR_INVALID_ARGUMENT;
}

int bpx_simd_lanes(bpx_simd simd)
{
    if (simd == BPX_SIMD_AUTO)
        simd = bpx_simd_best();
    return (unsigned)simd < BPX_SIMD_COUNT ? variants[simd].lanes : 0;
}

bool bpx__simd_compiled(bpx_simd simd)
{
    return (unsigned)simd < BPX_SIMD_COUNT && variants[simd].brute;
}

bool bpx_simd_supported(bpx_simd simd)
{
    if (simd == BPX_SIMD_AUTO)
        return true;
    return bpx__simd_compiled(simd) && bpx__cpu_supports(simd);
}

bpx_simd bpx_simd_best(void)
{
    static const bpx_simd widest_first[] = {BPX_SIMD_AVX512, BPX_SIMD_AVX2, BPX_SIMD_NEON,
                                            BPX_SIMD_SSE2};
    for (size_t k = 0; k < sizeof widest_first / sizeof widest_first[0]; k++)
        if (bpx_simd_supported(widest_first[k]))
            return widest_first[k];
    return BPX_SIMD_SCALAR;
}
