// The model's comparator (paper §4.3, Figures 3-4, Table 1): six 2m-width memories (each m
// dual-port RAMs holding the same data), the Table 1 address generator, and 2m - 1 comparison
// units doing the six comparisons of one pair each and ANDing them. Four register stages:
// addresses -> RAM read registers -> RAM output registers -> comparison results (read by the
// emitter). The output registers are the RTL's: on an ECP5 a block RAM's clock-to-output and
// six 32-bit compares after it did not fit one 108 MHz clock (docs/rtl.md).
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "bpx/model.h"

enum {
    BPX_HW_MAX_UNITS = 2 * BPX_MODEL_MAX_M - 1, // comparison units
    BPX_HW_AXES = 6,                            // min x, max x, min y, max y, min z, max z
    BPX_HW_RAM_SLACK = 2 * BPX_MODEL_MAX_M,     // floats after the memories (see mem)
};

/// The address generator of Table 1. Port 0 holds the first address; ports 1 .. 2m - 1 read
/// base, base + 1, ..., advancing by 2m - 1 each clock until one of them reaches max; then
/// the first address moves on and the others restart (at first + 1 on the diagonal, where a set
/// is compared with itself, or at `sweep` when one tile is compared with another).
typedef struct bpx_hw_addrgen {
    bool active;
    bool diagonal;
    int lanes;          // 2m - 1
    uint32_t first;     // port 0
    uint32_t first_end; // rows run for first < first_end
    uint32_t base;      // port 1 this clock; port k reads base + k - 1
    uint32_t sweep;     // port 1 at the start of each row (off-diagonal)
    uint32_t max;       // the maximum address
} bpx_hw_addrgen;

/// Starts rows first_begin .. first_end - 1. Diagonal: first_end = max and each row starts at
/// first + 1. Inactive when there is no row.
void bpx__hw_addrgen_start(bpx_hw_addrgen *g, int lanes, uint32_t first_begin, uint32_t first_end,
                           bool diagonal, uint32_t sweep, uint32_t max);

/// The next clock's addresses.
static inline void bpx__hw_addrgen_next(bpx_hw_addrgen *g)
{
    if (g->base + (uint32_t)g->lanes - 1 >= g->max) { // a port reached the maximum address
        if (++g->first >= g->first_end) {
            g->active = false;
            return;
        }
        g->base = g->diagonal ? g->first + 1 : g->sweep;
    } else {
        g->base += (uint32_t)g->lanes;
    }
}

/// One copy of the comparator's registers (the model keeps two: current and next).
typedef struct bpx_hw_cmp_regs {
    // Stage 0: the addresses presented to the RAMs this clock, and the global index offsets
    // they carry (global i = first + i_offset, global j = address + j_offset, mod 2^32).
    bpx_hw_addrgen a;
    uint32_t a_i_offset;
    uint32_t a_j_offset;
    // Stage 1: the RAMs' read registers. A block RAM registers its address at the clock edge
    // and drives that word during the next clock; the model keeps the registered addresses
    // (port 0: r_first; port k + 1: r_base + k) and looks the words up when the comparison
    // units use them (the same values: nothing writes the RAMs while the comparator runs).
    bool r_valid;
    uint32_t r_i;  // global index of the first address
    uint32_t r_j0; // global index read by unit 0
    uint32_t r_first;
    uint32_t r_base;
    int r_kept; // units 0 .. r_kept - 1 have addresses <= max; the rest are discarded
    // Stage 2: the RAMs' output registers: stage 1 a clock later (the same words).
    bool o_valid;
    uint32_t o_i;
    uint32_t o_j0;
    uint32_t o_first;
    uint32_t o_base;
    int o_kept;
    // Stage 3: comparison results, read by the emitter.
    bool h_valid;
    uint32_t h_i;
    uint32_t h_j0; // unit k's pair is (h_i, h_j0 + k)
    uint64_t h_mask;
} bpx_hw_cmp_regs;

typedef struct bpx_hw_comparator {
    int m;
    int lanes;      // 2m - 1
    uint32_t depth; // words per RAM
    /// The six memories, each m RAMs with the same data: RAM r of memory x is
    /// mem + (x * m + r) * depth. Port p reads RAM p / 2 (its port A or B). The allocation has
    /// BPX_HW_RAM_SLACK floats more, which discarded ports past the last RAM's end may read.
    float *mem;
    /// Word of unit k's port (k + 1) within one memory, less the base address: the offset of
    /// the RAM it reads, (k + 1) / 2 * depth, plus k.
    uint32_t lane_word[BPX_HW_MAX_UNITS];
    bpx_hw_cmp_regs regs[2];
    bpx_hw_cmp_regs *cur; // committed
    bpx_hw_cmp_regs *nxt;
    bool stall; // this clock's input: hold every register
    // Write port, driven by the updater this clock: the same address in all m RAMs.
    bool write;
    uint32_t write_address;
    float write_data[BPX_HW_AXES];
    // Counters since the last reset.
    uint64_t address_clocks; // clocks with addresses presented and not stalled
    uint64_t discarded;      // comparison units x those clocks beyond the maximum address
} bpx_hw_comparator;

/// Sets the comparator up for m and RAM depth; mem must hold 6 * m * depth + BPX_HW_RAM_SLACK
/// floats (zeroed: the block RAMs' power-up contents).
void bpx__hw_comparator_init(bpx_hw_comparator *c, int m, uint32_t depth, float *mem);

/// Clears the pipeline and counters (memory contents stay).
void bpx__hw_comparator_reset(bpx_hw_comparator *c);

/// Starts a schedule on the current RAM contents (the pipeline must be empty).
void bpx__hw_comparator_start(bpx_hw_comparator *c, uint32_t first_begin, uint32_t first_end,
                              bool diagonal, uint32_t sweep, uint32_t max, uint32_t i_offset,
                              uint32_t j_offset);

/// Anything in the pipeline (addresses still to present or results not yet taken).
static inline bool bpx__hw_comparator_busy(const bpx_hw_comparator *c)
{
    return c->cur->a.active || c->cur->r_valid || c->cur->o_valid || c->cur->h_valid;
}

/// The 2m - 1 comparison units on the words at the registered addresses (port 0: first; unit k:
/// base + k): each does the six comparisons of Algorithm 1 and ANDs them; units from `kept` on
/// are discarded by the index check (address > max) and their words never used. Bit k: unit k
/// found a collision. (The model tests x for every unit first and y, z only for units that
/// passed x: the same AND, less work for the host.)
static inline uint64_t bpx__hw_comparator_units(const bpx_hw_comparator *c, uint32_t first,
                                                uint32_t base, int kept)
{
    const size_t depth = c->depth;
    const size_t memory = (size_t)c->m * depth; // floats per 2m-width memory
    // x. RAM 0's port A holds the first address, its port B unit 0's; RAM r's ports A and B
    // hold units 2r - 1 and 2r, at base + 2r - 1 and base + 2r.
    const float fl = c->mem[first], fh = c->mem[memory + first];
    const float *lo = c->mem + base, *hi = lo + memory;
    uint64_t mask = (uint64_t)((fh >= lo[0]) & (fl <= hi[0]));
    for (int r = 1, k = 1; r < c->m; r++, k += 2) {
        lo += depth;
        hi += depth;
        uint64_t a = (uint64_t)((fh >= lo[k]) & (fl <= hi[k]));
        uint64_t b = (uint64_t)((fh >= lo[k + 1]) & (fl <= hi[k + 1]));
        mask |= (a | b << 1) << k;
    }
    mask &= (1ull << kept) - 1;
    // y and z, for the units that passed x.
    for (int axis = 1; axis < 3 && mask; axis++) {
        lo = c->mem + 2 * axis * memory;
        hi = lo + memory;
        const float al = lo[first], ah = hi[first];
        for (uint64_t left = mask; left; left &= left - 1) {
            int k = __builtin_ctzll(left);
            uint32_t w = base + c->lane_word[k];
            if (!((ah >= lo[w]) & (al <= hi[w])))
                mask &= ~(1ull << k);
        }
    }
    return mask;
}

/// Units whose addresses are <= the maximum this clock (the rest are discarded).
static inline int bpx__hw_addrgen_kept(const bpx_hw_addrgen *g)
{
    uint32_t last = g->base + (uint32_t)g->lanes - 1;
    return last <= g->max ? g->lanes : (int)(g->max - g->base + 1);
}

/// Evaluate: from the committed registers and RAMs, the next registers (unless stalled).
static inline void bpx__hw_comparator_evaluate(bpx_hw_comparator *c, bool stall)
{
    c->stall = stall;
    if (stall) // a FIFO might overflow: every register holds (the clock enable is low)
        return;
    const bpx_hw_cmp_regs *cur = c->cur;
    bpx_hw_cmp_regs *nxt = c->nxt;
    const int lanes = c->lanes;

    // Stage 3: the comparison units on the RAMs' words.
    nxt->h_valid = cur->o_valid;
    if (cur->o_valid) {
        nxt->h_mask = bpx__hw_comparator_units(c, cur->o_first, cur->o_base, cur->o_kept);
        nxt->h_i = cur->o_i;
        nxt->h_j0 = cur->o_j0;
    }

    // Stage 2: the RAMs' output registers take their read registers.
    nxt->o_valid = cur->r_valid;
    if (cur->r_valid) {
        nxt->o_first = cur->r_first;
        nxt->o_base = cur->r_base;
        nxt->o_kept = cur->r_kept;
        nxt->o_i = cur->r_i;
        nxt->o_j0 = cur->r_j0;
    }

    // Stage 1: the RAMs register the presented addresses. Port 0 and port 1 share RAM 0 (its
    // ports A and B), ports 2 and 3 RAM 1, and so on. Ports beyond the maximum address read
    // too, and their words are never used (past a RAM's end a block RAM wraps the address; the
    // model reads the words that follow instead).
    const bpx_hw_addrgen *g = &cur->a;
    nxt->r_valid = g->active;
    if (g->active) {
        int kept = bpx__hw_addrgen_kept(g);
        nxt->r_first = g->first;
        nxt->r_base = g->base;
        nxt->r_kept = kept;
        nxt->r_i = g->first + cur->a_i_offset;
        nxt->r_j0 = g->base + cur->a_j_offset;
        c->address_clocks++;
        c->discarded += (uint64_t)(lanes - kept);
    }

    // Stage 0: the address generator.
    nxt->a = cur->a;
    nxt->a_i_offset = cur->a_i_offset;
    nxt->a_j_offset = cur->a_j_offset;
    if (nxt->a.active)
        bpx__hw_addrgen_next(&nxt->a);
}

/// Commit: registers take their next values (all at once); a pending RAM write happens.
static inline void bpx__hw_comparator_commit(bpx_hw_comparator *c)
{
    if (!c->stall) {
        bpx_hw_cmp_regs *t = c->cur;
        c->cur = c->nxt;
        c->nxt = t;
    }
    if (c->write) { // the updater writes one address in all m RAMs of each memory
        const size_t m = (size_t)c->m;
        for (int x = 0; x < BPX_HW_AXES; x++)
            for (size_t r = 0; r < m; r++)
                c->mem[(x * m + r) * c->depth + c->write_address] = c->write_data[x];
        c->write = false;
    }
}

/// Quiet clocks: while no other unit has work (the updater idle, the FIFOs and the emitter's
/// output empty, no SSRAM read in flight), the other units' steps change nothing, so the
/// machine may step the comparator alone. Runs clocks one by one until one registers a result
/// with a hit (the emitter takes it next clock) or the pipeline is empty, and returns how many.
/// Each clock is evaluate-then-commit of the same three stages, with the registers held in
/// locals; none is stalled.
static inline uint64_t bpx__hw_comparator_run_quiet(bpx_hw_comparator *c)
{
    bpx_hw_cmp_regs *reg = c->cur;
    if (!bpx__hw_comparator_busy(c) || (reg->h_valid && reg->h_mask))
        return 0;
    bpx_hw_addrgen a = reg->a;
    const uint32_t i_offset = reg->a_i_offset, j_offset = reg->a_j_offset;
    bool r_valid = reg->r_valid, o_valid = reg->o_valid, h_valid = reg->h_valid;
    uint32_t r_i = reg->r_i, r_j0 = reg->r_j0, r_first = reg->r_first, r_base = reg->r_base;
    uint32_t o_i = reg->o_i, o_j0 = reg->o_j0, o_first = reg->o_first, o_base = reg->o_base;
    uint32_t h_i = reg->h_i, h_j0 = reg->h_j0;
    int r_kept = reg->r_kept, o_kept = reg->o_kept;
    uint64_t h_mask = reg->h_mask, clocks = 0, address_clocks = 0, discarded = 0;
    for (;;) {
        // Evaluate.
        uint64_t next_mask = o_valid ? bpx__hw_comparator_units(c, o_first, o_base, o_kept) : 0;
        bool next_r = a.active;
        int kept = 0;
        if (a.active) {
            kept = bpx__hw_addrgen_kept(&a);
            address_clocks++;
            discarded += (uint64_t)(a.lanes - kept);
        }
        // Commit: every stage takes its next value.
        h_valid = o_valid;
        h_mask = next_mask;
        h_i = o_i;
        h_j0 = o_j0;
        o_valid = r_valid;
        o_i = r_i;
        o_j0 = r_j0;
        o_first = r_first;
        o_base = r_base;
        o_kept = r_kept;
        r_valid = next_r;
        if (next_r) {
            r_first = a.first;
            r_base = a.base;
            r_kept = kept;
            r_i = a.first + i_offset;
            r_j0 = a.base + j_offset;
            bpx__hw_addrgen_next(&a);
        }
        clocks++;
        if ((h_valid && h_mask) || !(a.active || r_valid || o_valid || h_valid))
            break;
    }
    reg->a = a;
    reg->o_valid = o_valid;
    reg->o_i = o_i;
    reg->o_j0 = o_j0;
    reg->o_first = o_first;
    reg->o_base = o_base;
    reg->o_kept = o_kept;
    reg->r_valid = r_valid;
    reg->r_i = r_i;
    reg->r_j0 = r_j0;
    reg->r_first = r_first;
    reg->r_base = r_base;
    reg->r_kept = r_kept;
    reg->h_valid = h_valid;
    reg->h_mask = h_mask;
    reg->h_i = h_i;
    reg->h_j0 = h_j0;
    c->address_clocks += address_clocks;
    c->discarded += discarded;
    return clocks;
}
