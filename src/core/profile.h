// A cycle's per-stage profile (bpx_world_def.profile): what the backends and the world fill
// into bpx_cycle_stats.stages. Off, the backend's bpx_cycle.profile is NULL and every call here
// is one test of that pointer per stage: no clock read, no count, nothing written.
#pragma once

#include "bpx/types.h"

typedef struct bpx_profile {
    uint32_t count;
    bpx_stage_stats stage[BPX_MAX_STAGES];
} bpx_profile;

// profile.c: the clock, and a stage's sums.
uint64_t bpx__profile_now(void);
void bpx__profile_book(bpx_profile *p, const char *backend, const char *name, uint64_t ns,
                       bpx_access access, uint64_t read, uint64_t written, uint64_t random);

// The clock when profiling (a stage's start), else 0.
static inline uint64_t bpx__profile_clock(const bpx_profile *p)
{
    return p ? bpx__profile_now() : 0;
}

// Adds ns and bytes to the stage of this backend and name (made, in order, at its first use; a
// stage run several times in a cycle sums; past BPX_MAX_STAGES stages are dropped).
static inline void bpx__profile_add_ns(bpx_profile *p, const char *backend, const char *name,
                                       uint64_t ns, bpx_access access, uint64_t read,
                                       uint64_t written, uint64_t random)
{
    if (p)
        bpx__profile_book(p, backend, name, ns, access, read, written, random);
}

// Adds a stage that ran from *since to now, and sets *since to now (the next stage's start).
static inline void bpx__profile_add(bpx_profile *p, const char *backend, const char *name,
                                    uint64_t *since, bpx_access access, uint64_t read,
                                    uint64_t written, uint64_t random)
{
    if (!p)
        return;
    uint64_t now = bpx__profile_now();
    bpx__profile_book(p, backend, name, now - *since, access, read, written, random);
    *since = now;
}
