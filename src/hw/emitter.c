// The model's collision emitter: per-unit FIFOs drained by a round-robin scheduler.
#include "hw/emitter.h"

#include <string.h>

void bpx__hw_emitter_init(bpx_hw_emitter *e, int lanes, uint32_t depth, bpx_pair *slots)
{
    memset(e, 0, sizeof *e);
    e->lanes = lanes;
    e->depth = depth;
    e->slots = slots;
    bpx__hw_emitter_reset(e);
}

void bpx__hw_emitter_reset(bpx_hw_emitter *e)
{
    memset(e->head, 0, sizeof e->head);
    memset(e->fill, 0, sizeof e->fill);
    e->nonempty = 0;
    e->next_lane = 0;
    e->read_valid = false;
    e->out_valid = false;
    e->push = 0;
    e->pop = -1;
    e->advance = true;
    e->stall_next = false;
    e->stall_decided = false;
    e->peak_fill = 0;
    e->emitted = 0;
}

uint32_t bpx__hw_emitter_fill_max(const bpx_hw_emitter *e)
{
    uint32_t most = 0;
    for (int k = 0; k < e->lanes; k++)
        most = e->fill[k] > most ? e->fill[k] : most;
    return most;
}
