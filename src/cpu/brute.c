// The brute backend: the paper's comparator on CPU SIMD lanes and threads (paper modules: the
// comparator, W lanes = its 2m - 1 units; the emitter, as per-row ordered blocks joined in order).
// Rows are split into blocks of about equal work (emitter.c); each block is one task; the
// kernel for the world's SIMD width (kernels_<isa>.c) is picked at run time (cpu_features.c).
#include <stdio.h>

#include "core/backend.h"
#include "cpu_features.h"

static bool brute_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    bpx_simd simd = def->simd == BPX_SIMD_AUTO ? bpx_simd_best() : def->simd;
    *reason = "";
    if ((unsigned)simd >= BPX_SIMD_COUNT) {
        *reason = "no such SIMD width";
        return false;
    }
    if (!bpx__simd_compiled(simd)) {
        *reason = "SIMD width not compiled into this build";
        return false;
    }
    if (!bpx__cpu_supports(simd)) {
        *reason = "CPU lacks the instruction set";
        return false;
    }
    snprintf(detail, size, "%s, %d lanes, threads", bpx_simd_name(simd), bpx_simd_lanes(simd));
    return true;
}

typedef struct brute_job {
    bpx_emitter *sink;
    bpx_soa soa;
    bpx_brute_rows_fn *rows;
} brute_job;

static void brute_task(int begin, int end, int worker, void *context)
{
    (void)worker;
    brute_job *job = context;
    for (int b = begin; b < end; b++) {
        bpx_block *block = &job->sink->blocks[b];
        block->hits.count = 0;
        block->tests = 0;
        block->status = BPX_OK;
        job->rows(&job->soa, block->row_begin, block->row_end, block);
    }
}

static bpx_status brute_compare(void **state, bpx_cycle *c)
{
    (void)state;
    if (c->sink->planned_n != c->n) {
        bpx_status status = bpx__emitter_plan(c->sink, c->n, false);
        if (status != BPX_OK)
            return status;
    }
    brute_job job = {c->sink, c->boxes, bpx__brute_rows_for(c->simd)};
    bpx__parallel_for(c->executor, brute_task, c->sink->block_count, &job);
    return BPX_OK;
}

const bpx_backend_impl bpx__brute_backend = {
    .id = BPX_BACKEND_BRUTE,
    .name = "brute",
    .query = brute_query,
    .compare = brute_compare,
};
