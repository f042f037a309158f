// The model's collision emitter (paper §4.4, Figure 5): the 2m - 1 comparison units each write
// a hit's two indices into their own pair of FIFOs (4m - 2 FIFOs in all, written and read in
// lockstep, so one pair of FIFOs is kept here as one FIFO of index pairs); a round-robin
// scheduler reads one collision per clock from the FIFOs (the FIFO block RAMs' read registers)
// and moves it into its output register the clock after, which the interface writes to the
// collision RAM. A FIFO that might overflow stalls the comparator, two clocks after the
// emitter decides it (bpx__hw_emitter_stall_next). (The RTL selects the served FIFO's read
// register into the output register: one clock for a block RAM's clock-to-output and that
// select did not fit 108 MHz on an ECP5, so the model has both registers too.)
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "bpx/types.h"
#include "hw/comparator.h"

typedef struct bpx_hw_emitter {
    int lanes;       // FIFO pairs: one per comparison unit
    uint32_t depth;  // entries per FIFO
    bpx_pair *slots; // lanes x depth ring buffers
    uint32_t head[BPX_HW_MAX_UNITS];
    uint32_t fill[BPX_HW_MAX_UNITS];
    uint64_t nonempty; // bit k: FIFO pair k holds an entry (committed)
    int next_lane;     // where the round robin looks first
    // The FIFO read registers (the served lane's) and the output register (committed).
    bool read_valid;
    bpx_pair read;
    bool out_valid;
    bpx_pair out;
    // Evaluate -> commit.
    uint64_t push; // lanes written this clock: (push_i, push_j0 + lane)
    uint32_t push_i;
    uint32_t push_j0;
    int pop; // lane read this clock, or -1
    bool advance; // the output register is empty or taken: the output pipeline moves
    // The stall a clock on (a register; the machine registers it again as the stall), and its
    // next value from this clock's evaluate.
    bool stall_next;
    bool stall_decided;
    // Statistics since the last reset.
    uint32_t peak_fill;
    uint64_t emitted;
} bpx_hw_emitter;

/// slots must hold lanes * depth pairs.
void bpx__hw_emitter_init(bpx_hw_emitter *e, int lanes, uint32_t depth, bpx_pair *slots);
void bpx__hw_emitter_reset(bpx_hw_emitter *e);

/// The almost-full stall (rtl/emitter.sv, docs/model.md): from this clock's registers, whether
/// a result pushed two clocks on could meet a full FIFO. The stall is registered twice before
/// it holds the comparator (its net to every comparator RAM needs a clock of its own on an
/// FPGA), so it is decided from what can still arrive: lane k may take a hit two clocks on
/// only if fill + p0 + p1 < depth, p0 this clock's push, p1 next clock's (known while the
/// comparator holds, else any lane of a valid result: its mask is not computed yet). While
/// both stalls are high the result held is the one pushed, and the test is exact. stall: the
/// stall now; e->stall_next: the stall a clock on.
static inline bool bpx__hw_emitter_stall_decide(const bpx_hw_emitter *e,
                                                const bpx_hw_comparator *c, bool stall)
{
    const bpx_hw_cmp_regs *r = c->cur;
    const bool s1 = e->stall_next;
    const bool hv1 = stall ? r->h_valid : r->o_valid;               // h_valid a clock on
    const bool hv2 = s1 ? hv1 : (stall ? r->o_valid : r->r_valid); // two clocks on
    if (!hv2)
        return false;
    const uint64_t all = e->lanes == 64 ? ~0ull : (1ull << e->lanes) - 1;
    const uint64_t p0 = !stall && r->h_valid ? r->h_mask : 0;
    const uint64_t p1 = !s1 && hv1 ? (stall ? r->h_mask : all) : 0;
    const uint64_t hit = stall && s1 ? r->h_mask : all; // lanes that may be hit two clocks on
    for (uint64_t left = hit; left; left &= left - 1) {
        int k = __builtin_ctzll(left);
        uint32_t arrive = (uint32_t)(p0 >> k & 1) + (uint32_t)(p1 >> k & 1);
        if (e->fill[k] + arrive >= e->depth)
            return true;
    }
    return false;
}

/// FIFOs or output register still hold collisions.
static inline bool bpx__hw_emitter_busy(const bpx_hw_emitter *e)
{
    return e->nonempty != 0 || e->read_valid || e->out_valid;
}

/// Evaluate: latch the comparator's results (unless stalled) as this clock's FIFO writes and
/// pick the FIFO to read: the round robin serves the first non-empty FIFO pair at or after
/// next_lane. ready: the collision port takes the output register this clock; when it holds a
/// collision and ready is false, the read and output registers hold and no FIFO is read.
static inline void bpx__hw_emitter_evaluate(bpx_hw_emitter *e, const bpx_hw_comparator *c,
                                            bool stall, bool ready)
{
    const bpx_hw_cmp_regs *r = c->cur;
    e->push = !stall && r->h_valid ? r->h_mask : 0;
    e->push_i = r->h_i;
    e->push_j0 = r->h_j0;
    e->pop = -1;
    e->advance = !e->out_valid || ready;
    e->stall_decided = bpx__hw_emitter_stall_decide(e, c, stall);
    if (e->nonempty && e->advance) {
        uint64_t after = e->nonempty >> e->next_lane << e->next_lane;
        e->pop = after ? __builtin_ctzll(after) : __builtin_ctzll(e->nonempty);
    }
}

/// Commit: the read register moves to the output register and the read FIFO gives its head to
/// the read register; each unit with a hit writes
/// (i, j) at its FIFO pair's tail (a written FIFO is never full: the stall decided two clocks
/// before saw to it); the round-robin pointer moves past the FIFO read.
static inline void bpx__hw_emitter_commit(bpx_hw_emitter *e)
{
    e->stall_next = e->stall_decided;
    if (e->advance) {
        e->out_valid = e->read_valid;
        e->out = e->read;
        e->read_valid = e->pop >= 0;
    }
    if (e->pop >= 0) {
        int k = e->pop;
        e->read = e->slots[(size_t)k * e->depth + e->head[k]];
        if (++e->head[k] == e->depth)
            e->head[k] = 0;
        e->fill[k]--;
        e->next_lane = k + 1 == e->lanes ? 0 : k + 1;
        e->emitted++;
        if (e->fill[k] == 0)
            e->nonempty &= ~(1ull << k);
    }
    for (uint64_t mask = e->push; mask; mask &= mask - 1) {
        int k = __builtin_ctzll(mask);
        uint32_t tail = e->head[k] + e->fill[k];
        if (tail >= e->depth)
            tail -= e->depth;
        e->slots[(size_t)k * e->depth + tail] = (bpx_pair){e->push_i, e->push_j0 + (uint32_t)k};
        uint32_t fill = ++e->fill[k];
        if (fill > e->peak_fill)
            e->peak_fill = fill;
    }
    e->nonempty |= e->push;
}

/// The fullest FIFO pair now.
uint32_t bpx__hw_emitter_fill_max(const bpx_hw_emitter *e);
