// The model's updater (paper §4.2, Figure 2). Initialisation: it stores the origin-centred
// minima the host wrote to the SSRAM in its own on-chip RAM. Updating: for each object it reads
// the centre from the SSRAM, adds the stored minimum to get the box's minimum and subtracts it
// to get the maximum (the maximum is the minimum with its sign changed), and writes the box
// into the comparator's six memories. Pipeline: SSRAM read (latency L) -> operand register ->
// eight adder registers -> add register -> RAM write, one object per clock: a pass over n objects
// takes n + L + BPX_HW_UPDATE_STAGES clocks. The chip's binary32 adder is nine steps with a
// register after each but the last (rtl/fadd.sv; in one or two stages it was the chip's longest
// path, far from 108 MHz on an ECP5), so the model computes the sum when the data arrives and
// moves it through as many registers: the same bits at the same clock.
#pragma once

#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "hw/comparator.h"
#include "hw/interface.h"

typedef enum bpx_hw_update_mode {
    /// Initialisation: banks 0-2 hold minima; they go to the updater's own RAM.
    BPX_HW_STORE_MINIMA,
    /// Updating, minima on chip: banks 0-2 hold centres.
    BPX_HW_ADD_ON_CHIP,
    /// Updating, minima off chip (tiles): banks 0-2 centres, banks 3-5 minima.
    BPX_HW_ADD_FROM_BANKS,
    /// General boxes (not in the paper): banks 0-5 hold min x, y, z and max x, y, z.
    BPX_HW_PASS_BOXES,
} bpx_hw_update_mode;

enum {
    /// Registers from the arriving SSRAM word to the RAM write: the operand register, the eight
    /// between the adder's steps and the add register (rtl/updater.sv's S). Was 9 before the
    /// adder's magnitude compare got a step of its own (issue 30, docs/rtl.md).
    BPX_HW_UPDATE_STAGES = 10,
};

/// One register of the updater's pipeline: a box (memory order: min x, max x, min y, max y,
/// min z, max z) or three minima, and the RAM address it goes to.
typedef struct bpx_hw_update_reg {
    bool valid;
    uint32_t address;
    float word[BPX_HW_AXES];
} bpx_hw_update_reg;

typedef struct bpx_hw_updater {
    uint32_t depth;   // words of the minima RAM
    float *minima[3]; // the on-chip minima RAM, x, y, z
    bpx_hw_update_mode mode;
    bool active;
    uint32_t next;        // next SSRAM address to read
    uint32_t end;         // one past the last
    uint32_t destination; // RAM address = SSRAM address + destination (mod 2^32)
    uint32_t in_flight;   // reads not yet returned
    // The pipeline, pipe[0] the operand register (here already the whole sum) and
    // pipe[BPX_HW_UPDATE_STAGES - 1] the add register, written to the RAMs; `valid` counts the
    // registers holding an object.
    bpx_hw_update_reg pipe[BPX_HW_UPDATE_STAGES];
    int valid;
    // Evaluate -> commit.
    bool issue;
    bool next_valid;
    uint32_t next_address;
    float next_stage[BPX_HW_AXES];
    bool store_minima; // write the add register into the minima RAM at commit
} bpx_hw_updater;

/// minima: three arrays of depth floats (the updater's RAM).
void bpx__hw_updater_init(bpx_hw_updater *u, uint32_t depth, float *minima_x, float *minima_y,
                          float *minima_z);

/// Starts a pass over SSRAM addresses [begin, end) written to RAM addresses from `to`.
void bpx__hw_updater_start(bpx_hw_updater *u, bpx_hw_update_mode mode, uint32_t begin, uint32_t end,
                           uint32_t to);

/// The pass has written its last box.
static inline bool bpx__hw_updater_done(const bpx_hw_updater *u)
{
    return !u->active;
}

/// Evaluate: request the next address, compute the sum from the arriving data, and drive the
/// comparator's write port (or the minima RAM) from the add register.
static inline void bpx__hw_updater_evaluate(bpx_hw_updater *u, bpx_hw_interface *ifc,
                                            bpx_hw_comparator *c)
{
    u->issue = false;
    u->store_minima = false;
    u->next_valid = false;
    if (!u->active)
        return;

    // Address counter: one SSRAM read per clock (x, y, z at one address across three banks,
    // six banks when the minima or maxima come from the SSRAM too).
    if (u->next < u->end) {
        bool three = u->mode == BPX_HW_STORE_MINIMA || u->mode == BPX_HW_ADD_ON_CHIP;
        bpx__hw_interface_request(ifc, u->next, three ? 0x07u : 0x3fu);
        u->issue = true;
    }

    // Operand register: the data of the read issued `latency` clocks ago, and the whole sum
    // (the chip's adder steps are the registers after it, moved on at commit).
    const bpx_hw_read *in = bpx__hw_interface_data(ifc);
    if (in->valid) {
        u->next_valid = true;
        u->next_address = in->address + u->destination;
        const float *w = in->word;
        switch (u->mode) {
        case BPX_HW_STORE_MINIMA:
            for (int a = 0; a < 3; a++)
                u->next_stage[a] = w[a];
            break;
        case BPX_HW_ADD_ON_CHIP:
        case BPX_HW_ADD_FROM_BANKS:
            for (int a = 0; a < 3; a++) {
                // The minimum comes from the updater's RAM, read at the same address as the
                // SSRAM so that it arrives with the centre, or from banks 3-5.
                float m = u->mode == BPX_HW_ADD_ON_CHIP ? u->minima[a][in->address] : w[3 + a];
                u->next_stage[2 * a] = w[a] + m;     // minimum
                u->next_stage[2 * a + 1] = w[a] - m; // maximum: the minimum's sign changed
            }
            break;
        case BPX_HW_PASS_BOXES:
            for (int a = 0; a < 3; a++) {
                u->next_stage[2 * a] = w[a];
                u->next_stage[2 * a + 1] = w[3 + a];
            }
            break;
        }
    }

    // Write stage: the add register goes into every RAM of the six memories (one address).
    const bpx_hw_update_reg *last = &u->pipe[BPX_HW_UPDATE_STAGES - 1];
    if (last->valid) {
        if (u->mode == BPX_HW_STORE_MINIMA) {
            u->store_minima = true;
        } else {
            c->write = true;
            c->write_address = last->address;
            memcpy(c->write_data, last->word, sizeof c->write_data);
        }
    }
}

/// Commit: address counter, the pipeline's registers, minima RAM write.
static inline void bpx__hw_updater_commit(bpx_hw_updater *u)
{
    if (!u->active)
        return;
    bpx_hw_update_reg *pipe = u->pipe;
    enum { LAST = BPX_HW_UPDATE_STAGES - 1 };
    if (u->store_minima)
        for (int a = 0; a < 3; a++)
            u->minima[a][pipe[LAST].address] = pipe[LAST].word[a];
    if (u->issue) {
        u->next++;
        u->in_flight++;
    }
    if (u->next_valid)
        u->in_flight--;
    // Every register takes the one before it (only the valid ones carry anything).
    u->valid -= pipe[LAST].valid;
    for (int k = LAST; k > 0; k--)
        if (pipe[k].valid || pipe[k - 1].valid)
            pipe[k] = pipe[k - 1];
    pipe[0].valid = u->next_valid;
    if (u->next_valid) {
        pipe[0].address = u->next_address;
        memcpy(pipe[0].word, u->next_stage, sizeof pipe[0].word);
        u->valid++;
    }
    u->active = u->next < u->end || u->in_flight > 0 || u->valid > 0;
}
