// The model's comparator: Table 1 addressing, replicated RAMs, 2m - 1 comparison units.
#include "hw/comparator.h"

#include <string.h>

void bpx__hw_addrgen_start(bpx_hw_addrgen *g, int lanes, uint32_t first_begin, uint32_t first_end,
                           bool diagonal, uint32_t sweep, uint32_t max)
{
    *g = (bpx_hw_addrgen){
        .active = first_begin < first_end,
        .diagonal = diagonal,
        .lanes = lanes,
        .first = first_begin,
        .first_end = first_end,
        .base = diagonal ? first_begin + 1 : sweep,
        .sweep = sweep,
        .max = max,
    };
}

void bpx__hw_comparator_init(bpx_hw_comparator *c, int m, uint32_t depth, float *mem)
{
    memset(c, 0, sizeof *c);
    c->m = m;
    c->lanes = 2 * m - 1;
    c->depth = depth;
    c->mem = mem;
    for (int k = 0; k < c->lanes; k++)
        c->lane_word[k] = (uint32_t)((k + 1) >> 1) * depth + (uint32_t)k;
    bpx__hw_comparator_reset(c);
}

void bpx__hw_comparator_reset(bpx_hw_comparator *c)
{
    c->cur = &c->regs[0];
    c->nxt = &c->regs[1];
    for (int k = 0; k < 2; k++) {
        c->regs[k].a.active = false;
        c->regs[k].r_valid = false;
        c->regs[k].o_valid = false;
        c->regs[k].h_valid = false;
    }
    c->stall = false;
    c->write = false;
    c->address_clocks = 0;
    c->discarded = 0;
}

void bpx__hw_comparator_start(bpx_hw_comparator *c, uint32_t first_begin, uint32_t first_end,
                              bool diagonal, uint32_t sweep, uint32_t max, uint32_t i_offset,
                              uint32_t j_offset)
{
    bpx__hw_addrgen_start(&c->cur->a, c->lanes, first_begin, first_end, diagonal, sweep, max);
    c->cur->a_i_offset = i_offset;
    c->cur->a_j_offset = j_offset;
}
