// A cycle's per-stage profile (bpx_world_def.profile): what the backends and the world fill
// into bpx_cycle_stats.stages. Off, the backend's bpx_cycle.profile is NULL and every call here
// is one test of that pointer per stage: no clock read, no count, nothing written.
#pragma once

#include <string.h>

#include "bpx/types.h"
#include "clock.h"

typedef struct bpx_profile {
    uint32_t count;
    bpx_stage_stats stage[BPX_MAX_STAGES];
} bpx_profile;

// The clock when profiling (a stage's start), else 0.
static inline uint64_t bpx__profile_clock(const bpx_profile *p)
{
    return p ? bpx__now_ns() : 0;
}

// The stage of this backend and name (made, in order, at its first use), or NULL past
// BPX_MAX_STAGES.
static inline bpx_stage_stats *bpx__profile_slot(bpx_profile *p, const char *backend,
                                                 const char *name, bpx_access access)
{
    for (uint32_t k = 0; k < p->count; k++)
        if (strcmp(p->stage[k].name, name) == 0 && strcmp(p->stage[k].backend, backend) == 0)
            return &p->stage[k];
    if (p->count == BPX_MAX_STAGES)
        return NULL;
    bpx_stage_stats *s = &p->stage[p->count++];
    *s = (bpx_stage_stats){.name = name, .backend = backend, .access = access};
    return s;
}

// Adds ns and bytes to a stage (a stage run several times in a cycle sums).
static inline void bpx__profile_add_ns(bpx_profile *p, const char *backend, const char *name,
                                       uint64_t ns, bpx_access access, uint64_t read,
                                       uint64_t written, uint64_t random)
{
    if (!p)
        return;
    bpx_stage_stats *s = bpx__profile_slot(p, backend, name, access);
    if (!s)
        return;
    s->ns += ns;
    s->bytes_read += read;
    s->bytes_written += written;
    s->random += random;
}

// Adds a stage that ran from *since to now, and sets *since to now (the next stage's start).
static inline void bpx__profile_add(bpx_profile *p, const char *backend, const char *name,
                                    uint64_t *since, bpx_access access, uint64_t read,
                                    uint64_t written, uint64_t random)
{
    if (!p)
        return;
    uint64_t now = bpx__now_ns();
    bpx__profile_add_ns(p, backend, name, now - *since, access, read, written, random);
    *since = now;
}
