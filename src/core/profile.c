// A cycle's per-stage profile (profile.h).
#include "profile.h"

#include <string.h>

#include "clock.h"

uint64_t bpx__profile_now(void)
{
    return bpx__now_ns();
}

void bpx__profile_book(bpx_profile *p, const char *backend, const char *name, uint64_t ns,
                       bpx_access access, uint64_t read, uint64_t written, uint64_t random)
{
    bpx_stage_stats *s = NULL;
    for (uint32_t k = 0; k < p->count && !s; k++)
        if (strcmp(p->stage[k].name, name) == 0 && strcmp(p->stage[k].backend, backend) == 0)
            s = &p->stage[k];
    if (!s) {
        if (p->count == BPX_MAX_STAGES)
            return;
        s = &p->stage[p->count++];
        *s = (bpx_stage_stats){.name = name, .backend = backend, .access = access};
    }
    s->ns += ns;
    s->bytes_read += read;
    s->bytes_written += written;
    s->random += random;
}
