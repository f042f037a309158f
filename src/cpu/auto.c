// The auto backend: each cycle, the CPU backend that is fastest for the world's n.
//
// The rule (measured with `bpx bench` on the scenes of the benchmark; docs/architecture.md):
//   n <= 96        brute: no sort to pay for, and a few SIMD steps per row
//   n <= 200,000   prune: one sort on x, then a sweep that meets few boxes per box
//   above          grid:  the sweep's candidates grow like n^(5/3); columns keep them linear
// The choice depends on n only, so the output (identical for every backend anyway) and the
// work done are reproducible. Each delegate keeps its own state between cycles.
#include <stdio.h>

#include "core/alloc.h"
#include "core/world.h"

enum { AUTO_BRUTE_MAX = 96, AUTO_PRUNE_MAX = 200000 };

typedef struct auto_state {
    void *states[BPX_BACKEND_COUNT]; // each delegate's backend_state
} auto_state;

static const bpx_backend_impl *delegate_for(uint32_t n)
{
    if (n <= AUTO_BRUTE_MAX)
        return &bpx__brute_backend;
    if (n <= AUTO_PRUNE_MAX)
        return &bpx__prune_backend;
    return &bpx__grid_backend;
}

bpx_backend bpx__auto_choice(uint32_t n)
{
    return delegate_for(n)->id;
}

static bpx_status auto_compare(bpx_world *w)
{
    auto_state *st = w->backend_state;
    if (!st) {
        if (!(st = bpx__alloc(sizeof *st)))
            return BPX_ERR_OUT_OF_MEMORY;
        *st = (auto_state){{0}};
        w->backend_state = st;
    }
    const bpx_backend_impl *impl = delegate_for(w->n);
    w->backend_state = st->states[impl->id];
    bpx_status status = impl->compare(w);
    st->states[impl->id] = w->backend_state;
    w->backend_state = st;
    return status;
}

static void auto_destroy(bpx_world *w)
{
    auto_state *st = w->backend_state;
    if (!st)
        return;
    const bpx_backend_impl *delegates[] = {&bpx__brute_backend, &bpx__prune_backend,
                                           &bpx__grid_backend};
    for (size_t k = 0; k < sizeof delegates / sizeof delegates[0]; k++) {
        w->backend_state = st->states[delegates[k]->id];
        if (w->backend_state && delegates[k]->destroy)
            delegates[k]->destroy(w);
    }
    bpx__free(st, sizeof *st);
    w->backend_state = NULL;
}

static bool auto_query(const bpx_world_def *def, const char **reason, char *detail, size_t size)
{
    // Every delegate runs on any SIMD width the CPU has (scalar at worst).
    char inner[96];
    if (!bpx__brute_backend.query(def, reason, inner, sizeof inner))
        return false;
    snprintf(detail, size, "brute to n = %d, prune to %d, grid beyond (%.40s)", AUTO_BRUTE_MAX,
             AUTO_PRUNE_MAX, inner);
    return true;
}

const bpx_backend_impl bpx__auto_backend = {
    .id = BPX_BACKEND_AUTO,
    .name = "auto",
    .query = auto_query,
    .compare = auto_compare,
    .destroy = auto_destroy,
};
