// The model's updater: centre + stored minimum -> box, one object per clock.
#include "hw/updater.h"

#include <string.h>

void bpx__hw_updater_init(bpx_hw_updater *u, uint32_t depth, float *minima_x, float *minima_y,
                          float *minima_z)
{
    memset(u, 0, sizeof *u);
    u->depth = depth;
    u->minima[0] = minima_x;
    u->minima[1] = minima_y;
    u->minima[2] = minima_z;
}

void bpx__hw_updater_start(bpx_hw_updater *u, bpx_hw_update_mode mode, uint32_t begin, uint32_t end,
                           uint32_t to)
{
    u->mode = mode;
    u->next = begin;
    u->end = end;
    u->destination = to - begin;
    u->in_flight = 0;
    for (int k = 0; k < BPX_HW_UPDATE_STAGES; k++)
        u->pipe[k].valid = false;
    u->valid = 0;
    u->active = begin < end;
}
