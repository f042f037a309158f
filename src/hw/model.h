// The model's machine: the four units, the clock, and the controller that sequences a run
// (host transfers, updater pass, comparator schedule, emitter drain, read-back). Shared by the
// public bpx_model API and the "model" backend.
#pragma once

#include "bpx/model.h"
#include "core/backend.h"
#include "hw/comparator.h"
#include "hw/emitter.h"
#include "hw/interface.h"
#include "hw/updater.h"

/// What the host writes each cycle.
typedef enum bpx_hw_format {
    /// The paper's updating phase: banks 0-2 centres (3 x 4 bytes per object); banks 3-5 the
    /// minima, read only when the boxes do not fit on chip.
    BPX_HW_FORMAT_CENTRES,
    /// General boxes: banks 0-5 min x, y, z, max x, y, z (6 x 4 bytes per object).
    BPX_HW_FORMAT_BOXES,
} bpx_hw_format;

typedef struct bpx_hw_machine {
    bpx_model_config config;
    uint32_t tile; // boxes per tile when they do not all fit: ram_depth / 2
    bpx_hw_interface ifc;
    bpx_hw_updater upd;
    bpx_hw_comparator cmp;
    bpx_hw_emitter emi;
    float *ram;            // comparator memories (6 x m x depth)
    float *minima_ram;     // updater RAM (3 x depth)
    bpx_pair *fifo;        // emitter FIFO slots
    uint32_t minima_count; // objects whose minima the updater RAM holds (UINT32_MAX: none)
    // The run in progress.
    uint64_t clock;
    bpx_model_phase phase;
    bpx_model_report *report;
    uint64_t phase_clocks[BPX_MODEL_PHASE_COUNT]; // clocks stepped in each phase this run
    uint64_t stall_clocks;
    bool stall; // the comparator holds this clock: the emitter's stall_next, registered
    uint32_t trace_ports[2 * BPX_MODEL_MAX_M];
} bpx_hw_machine;

/// Allocates the units for a checked configuration. OUT_OF_MEMORY leaves nothing allocated.
bpx_status bpx__hw_machine_init(bpx_hw_machine *mc, const bpx_model_config *config);
void bpx__hw_machine_free(bpx_hw_machine *mc);

/// Whether the configured store takes n boxes; the error says which limit and what to change.
bpx_status bpx__hw_machine_check_n(const bpx_model_config *config, uint32_t n, bpx_error *err);

/// Initialisation phase: minima (x, y, z arrays, n each) are in the SSRAM; the updater copies
/// them on chip when n fits. report is filled (required).
bpx_status bpx__hw_machine_extents(bpx_hw_machine *mc, const float *const minima[3], uint32_t n,
                                   bpx_model_report *report);

/// One updating phase on the data in `banks` (see bpx_hw_format). Collisions are written to
/// `collisions` in emitter order (the list grows; it is cleared first). report is filled.
/// Errors: BAD_STATE (centres with minima not on chip for this n), OUT_OF_MEMORY.
bpx_status bpx__hw_machine_cycle(bpx_hw_machine *mc, bpx_hw_format format,
                                 const float *const banks[BPX_HW_BANKS], uint32_t n,
                                 bpx_pair_list *collisions, bpx_model_report *report);
