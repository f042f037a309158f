// The brute backend: the paper's comparator on CPU SIMD lanes and threads.
// Rows are split into blocks of about equal work (emitter.c); each block is one task; the
// kernel for the world's SIMD width (kernels_<isa>.c) is picked at run time.
#include <stdio.h>
#include <string.h>

#include "core/world.h"
#include "cpu_features.h"
#include "kernels.h"

#define BPX_DECLARE_KERNELS(isa)                                                                  \
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

bool bpx_simd_supported(bpx_simd simd)
{
    if (simd == BPX_SIMD_AUTO)
        return true;
    return (unsigned)simd < BPX_SIMD_COUNT && variants[simd].brute && bpx__cpu_supports(simd);
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

static bool brute_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    bpx_simd simd = def->simd == BPX_SIMD_AUTO ? bpx_simd_best() : def->simd;
    *reason = "";
    if ((unsigned)simd >= BPX_SIMD_COUNT) {
        *reason = "no such SIMD width";
        return false;
    }
    if (!variants[simd].brute) {
        *reason = "SIMD width not compiled into this build";
        return false;
    }
    if (!bpx__cpu_supports(simd)) {
        *reason = "CPU lacks the instruction set";
        return false;
    }
    snprintf(detail, size, "%s, %d lanes, threads", variants[simd].name, variants[simd].lanes);
    return true;
}

typedef struct brute_job {
    bpx_world *world;
    bpx_soa soa;
    bpx_brute_rows_fn *rows;
} brute_job;

static void brute_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    brute_job *job = context;
    for (int b = begin; b < end; b++) {
        bpx_block *block = &job->world->blocks[b];
        block->hits.count = 0;
        block->tests = 0;
        block->status = BPX_OK;
        job->rows(&job->soa, block->row_begin, block->row_end, block);
    }
}

static bpx_status brute_compare(bpx_world *w)
{
    if (w->planned_n != w->n) {
        bpx_status status = bpx__emitter_plan(w, false);
        if (status != BPX_OK)
            return status;
    }
    brute_job job = {w, bpx__world_soa(w), bpx__brute_rows_for(w->simd)};
    bpx__parallel_for(&w->executor, brute_task, w->block_count, &job);
    return BPX_OK;
}

const bpx_backend_impl bpx__brute_backend = {
    .id = BPX_BACKEND_BRUTE,
    .name = "brute",
    .query = brute_query,
    .compare = brute_compare,
};
