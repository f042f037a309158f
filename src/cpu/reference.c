// The reference backend: Algorithm 1 verbatim (double loop over i < j, one thread). Paper
// modules: the comparator, one pair per step; its hits are already the emitter's order.
// It is the oracle of every test, so it stays the plainest code that could be right.
#include <stdio.h>

#include "core/backend.h"

static bpx_box box_at(const bpx_soa *s, uint32_t i)
{
    return (bpx_box){{s->lo[0][i], s->lo[1][i], s->lo[2][i]},
                     {s->hi[0][i], s->hi[1][i], s->hi[2][i]}};
}

static bool reference_query(const bpx_world_def *def, const char **reason, char *detail,
                            size_t size)
{
    (void)def;
    *reason = "";
    snprintf(detail, size, "Algorithm 1, scalar, 1 thread");
    return true;
}

static bpx_status reference_compare(void **state, bpx_cycle *c)
{
    (void)state;
    bpx_block *out;
    bpx_status status = bpx__emitter_one_block(c->sink, c->n, &out);
    if (status != BPX_OK)
        return status;
    bpx_soa s = c->boxes;
    for (uint32_t i = 0; i < s.n; i++) {
        bpx_box a = box_at(&s, i);
        for (uint32_t j = i + 1; j < s.n; j++) {
            bpx_box b = box_at(&s, j);
            if (bpx_overlap(&a, &b)) {
                if (!bpx__list_reserve(&out->hits, 1))
                    return BPX_ERR_OUT_OF_MEMORY;
                out->hits.pairs[out->hits.count++] = (bpx_pair){i, j};
            }
        }
        out->tests += s.n - 1 - i;
    }
    return BPX_OK;
}

const bpx_backend_impl bpx__reference_backend = {
    .id = BPX_BACKEND_REFERENCE,
    .name = "reference",
    .query = reference_query,
    .compare = reference_compare,
};
