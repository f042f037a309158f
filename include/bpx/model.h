// bpx: broad-phase collision detection. SPDX-License-Identifier: MIT
//
// A clock-by-clock model of the paper's FPGA design (Woulfe, Dingliana & Manzke 2007, §4):
// updater, comparator (Table 1 addressing), collision emitter (FIFOs + round robin) and the
// CPU-IC interface (six SSRAM banks, registers, a PCI link). Each unit is a state that is
// evaluated and then committed once per clock, so all registers change together.
//
// It finds exactly the pairs of the reference backend (it is also the backend "model") and
// predicts, for a given clock and link, how long one broad-phase cycle takes on the board.
// docs/model.md says how each part maps to the paper and what is measured vs. predicted.
//
// Typical use (the paper's two phases):
//   bpx_model_config config = bpx_model_default_config();  // m = 4, 108 MHz, 512 boxes
//   bpx_model *model;
//   bpx_model_create(&config, &model);
//   bpx_model_load_extents(model, minima, n, NULL);         // initialisation phase
//   each cycle:
//     bpx_model_report report;
//     bpx_model_run_centres(model, centres, &report);       // one updating phase
//     const bpx_pair *pairs = bpx_model_pairs(model, &count);
//   bpx_model_destroy(model);
#pragma once

#include "base.h"
#include "types.h"

#ifdef __cplusplus
extern "C" {
#endif

/// Largest m (2m read ports per memory, 2m - 1 comparison units).
#define BPX_MODEL_MAX_M 32

/// A port address beyond the maximum address: read, and its comparison discarded (Table 1 "-").
#define BPX_MODEL_DISCARDED UINT32_MAX

/// Where the boxes live when there are more than the on-chip RAMs hold (ram_depth). Up to
/// ram_depth boxes, every store works exactly as the paper's build: all boxes on chip.
typedef enum bpx_model_store {
    /// The paper's build: n <= ram_depth, else BPX_ERR_TOO_MANY_BOXES.
    BPX_MODEL_STORE_ON_CHIP = 0,
    /// Boxes stay in the board's SSRAM (n <= ssram_depth) and are loaded into the on-chip RAMs
    /// in tiles of ram_depth / 2 by the updater; tile pairs are compared one after another.
    BPX_MODEL_STORE_SSRAM,
    /// Like SSRAM, but each tile is sent by the host over the link when it is loaded: any n.
    BPX_MODEL_STORE_STREAM,
    BPX_MODEL_STORE_COUNT
} bpx_model_store;

/// What the chip is doing in a clock (for the trace hook).
typedef enum bpx_model_phase {
    BPX_MODEL_PHASE_INIT = 0, ///< initialisation: the updater stores the minima on chip
    BPX_MODEL_PHASE_UPDATE,   ///< updater: SSRAM -> centre + minimum -> the comparator's RAMs
    BPX_MODEL_PHASE_COMPARE,  ///< comparator addressing its RAMs (stalls included)
    BPX_MODEL_PHASE_DRAIN,    ///< comparator done; the emitter empties its FIFOs
    BPX_MODEL_PHASE_WAIT,     ///< waiting for a link transfer (streamed tiles); emitter may run
    BPX_MODEL_PHASE_COUNT
} bpx_model_phase;

/// One chip clock, as seen by the trace hook. Pointers are valid during the call only.
typedef struct bpx_model_clock {
    uint64_t clock; ///< chip clock since the start of this run, from 0
    bpx_model_phase phase;
    int port_count;  ///< 2m
    bool addressing; ///< the comparator presented addresses to its RAMs this clock
    /// When addressing: the 2m port addresses (RAM addresses; port 0 is the first address),
    /// BPX_MODEL_DISCARDED where beyond the maximum address. NULL otherwise.
    const uint32_t *ports;
    uint32_t max_address;   ///< the comparator's maximum address (when addressing)
    uint64_t hits;          ///< bit k: comparison unit k's registered result is a collision
    uint32_t hit_row;       ///< box index (global) of those results' first address
    bool stalled;           ///< the comparator is held: a FIFO it must write is full
    /// The emitter's output register holds a collision after this clock (the collision port's
    /// valid; it is written, and the next one moves up, at a clock whose ready is true).
    bool emitted;
    bpx_pair pair;          ///< that collision (natural, unsorted order)
    uint32_t fifo_fill_max; ///< the fullest FIFO pair after this clock
} bpx_model_clock;

/// Called once per simulated clock, after all registers were committed. Clocks spent only
/// waiting for the link with nothing else to do are skipped (the clock number jumps).
typedef void bpx_model_trace_fn(const bpx_model_clock *clock, void *user);

/// The host link. Every DMA transfer costs setup_ns + bytes / bytes_per_s; every register
/// access costs register_ns.
typedef struct bpx_model_link {
    /// Sustained bytes per second. Default 264e6: PCI, 32 bits at 66 MHz (the theoretical peak).
    double bytes_per_s;
    /// Fixed cost per DMA transfer (driver call, descriptor set-up, interrupt), ns. Default
    /// 104000: fitted (least squares, with the other link defaults) to Table 2's communication
    /// column by `bpx model --paper`; see docs/model.md for what the fit leaves unexplained.
    double setup_ns;
    /// One register read or write over the bus, ns. Default 500 (an assumption: a PCI target
    /// read round trip on a 2007 chipset).
    double register_ns;
} bpx_model_link;

/// Parameters of the modelled board. Get one from bpx_model_default_config().
typedef struct bpx_model_config {
    /// 2m read ports per memory (m dual-port RAMs, data replicated), 2m - 1 comparison units.
    /// Range 1..BPX_MODEL_MAX_M. Default 4.
    int m;
    /// Chip clock, Hz. Default 108e6 (the paper's build for m = 4 and m = 8).
    double clock_hz;
    /// Boxes each on-chip RAM holds (block-RAM depth). Default 512, the paper's limit; range
    /// 4m..1048576, even (tiles are half of it).
    uint32_t ram_depth;
    /// Words per SSRAM bank (the SSRAM store's box limit). Default 524288 (512K x 36 bit).
    uint32_t ssram_depth;
    /// Where boxes beyond ram_depth live. Default BPX_MODEL_STORE_ON_CHIP (the paper's limit).
    bpx_model_store store;
    /// Entries per FIFO (4m - 2 FIFOs: one index each, written in pairs). Default 1024, one
    /// 18 Kb block RAM (1K x 18). Range 1..1048576.
    uint32_t fifo_depth;
    /// Clocks from an SSRAM read address to its data (ZBT, pipelined). Default 2; range 1..8.
    int ssram_latency;
    /// The host link. Default PCI 32 bit, 66 MHz, DMA.
    bpx_model_link link;
    /// Optional per-clock hook (NULL: none) and its argument.
    bpx_model_trace_fn *trace;
    void *trace_user;
    /// Optional back-pressure on the collision output (NULL: always ready), the RTL's
    /// col_ready: called before each stepped clock with its number (bpx_model_clock.clock); on
    /// a clock it returns false the output register holds its collision and the emitter reads
    /// no FIFO, so the FIFOs fill and, when full, stall the comparator; no pair is dropped. It
    /// must depend on the clock number alone: clocks the model skips do not call it.
    bool (*collision_ready)(uint64_t clock, void *user);
    void *collision_ready_user;
} bpx_model_config;

/// What one run (initialisation or one updating phase) cost, clock by clock. Stage clocks
/// add up: chip_clocks = update_clocks + compare_clocks + emit_clocks.
typedef struct bpx_model_report {
    uint32_t n;          ///< boxes (the n register)
    uint64_t collisions; ///< the collision-count register
    int m;
    double clock_hz;
    bpx_model_store store; ///< the configured store
    bool on_chip;          ///< all boxes fit the on-chip RAMs (the paper's case)
    uint32_t tiles;        ///< tiles of ram_depth / 2 boxes (1 when on chip)
    uint64_t tile_loads;   ///< updater passes into the on-chip RAMs

    uint64_t update_clocks;    ///< updater (every tile load included), pipeline fill included
    uint64_t compare_clocks;   ///< comparator busy, stalls included
    uint64_t stall_clocks;     ///< of compare_clocks: held by the almost-full stall
    uint64_t emit_clocks;      ///< after the comparator: the emitter draining its FIFOs
    uint64_t chip_clocks;      ///< update + compare + emit
    uint64_t transfer_clocks;  ///< link time in chip clocks (rounded up)
    uint64_t simulated_clocks; ///< clocks stepped one by one (link waits are skipped)

    double chip_ns;             ///< chip_clocks at clock_hz
    double transfer_ns;         ///< link: DMA transfers + register accesses
    double cycle_ns;            ///< predicted time of the run: chip_ns + transfer_ns
    double communication_share; ///< transfer_ns / cycle_ns (0 when cycle_ns is 0)

    uint64_t dma_transfers;     ///< DMA transfers (each pays link.setup_ns)
    uint64_t register_accesses; ///< register reads and writes
    uint64_t bytes_to_board;    ///< minima, centres, boxes or streamed tiles
    uint64_t bytes_to_host;     ///< collisions read back

    uint64_t unit_tests;      ///< comparison-unit results: addressing clocks x (2m - 1)
    uint64_t discarded_tests; ///< of unit_tests: beyond the maximum address
    /// The paper's peak read bandwidth of one 2m-width memory: 2m ports x 4 bytes x clock_hz.
    /// (All six memories read six times this.)
    double peak_read_bytes_per_s;
    /// Bytes the six memories delivered to kept comparisons per second of compare time.
    double achieved_read_bytes_per_s;

    uint32_t fifo_peak;       ///< highest fill of any FIFO pair this run
    uint64_t on_chip_bytes;   ///< comparator RAMs (6 x m x ram_depth words) + updater minima
                              ///< RAM (3 x ram_depth words) + FIFOs ((4m - 2) x depth x 2 B)
    int block_rams;           ///< 18 Kb block RAMs that takes (XC2V6000: 144)
    uint64_t collision_words; ///< SSRAM addresses written with collisions (one per collision)
    bool collision_overflow;  ///< more collisions than one SSRAM bank holds (ssram_depth)
} bpx_model_report;

typedef struct bpx_model bpx_model;

/// The paper's build: m = 4, 108 MHz, 512-box on-chip RAMs (BPX_MODEL_STORE_ON_CHIP),
/// 1024-entry FIFOs, SSRAM latency 2, 524288-word SSRAM banks, PCI 32 bit / 66 MHz DMA link.
BPX_API bpx_model_config bpx_model_default_config(void);

/// Checks a configuration. INVALID_ARGUMENT names the first bad field in err (may be NULL).
BPX_API bpx_status bpx_model_check_config(const bpx_model_config *config, bpx_error *err);

/// Creates a model. Errors: NULL_ARGUMENT, INVALID_ARGUMENT (see bpx_model_check_config),
/// OUT_OF_MEMORY. On error *out is NULL.
BPX_API bpx_status bpx_model_create(const bpx_model_config *config, bpx_model **out);

/// Frees a model. NULL is allowed.
BPX_API void bpx_model_destroy(bpx_model *model);

/// The model's last error (BPX_OK after a successful call).
BPX_API const bpx_error *bpx_model_error(const bpx_model *model);

/// Initialisation phase: the host writes n objects' origin-centred minima (x, y, z each, 3n
/// floats, each finite and <= 0) to the SSRAM and sets the n register; with n <= ram_depth the
/// updater copies them into its on-chip RAM. report (may be NULL) gets the cost.
/// Errors: NULL_ARGUMENT, TOO_MANY_BOXES (beyond the store's limit: with the default on-chip
/// store, more than ram_depth = 512), NOT_FINITE, MIN_GREATER_THAN_MAX, OUT_OF_MEMORY.
BPX_API bpx_status bpx_model_load_extents(bpx_model *model, const float *minima, uint32_t n,
                                          bpx_model_report *report);

/// One updating phase: the host writes the n centres (3n floats) and starts the chip; the
/// updater makes min = centre + minimum, max = centre - minimum, the comparator and emitter
/// run, and the host reads the collisions back. report (may be NULL) gets the cost.
/// Errors: BAD_STATE (no extents loaded), NULL_ARGUMENT, NOT_FINITE, OUT_OF_MEMORY.
BPX_API bpx_status bpx_model_run_centres(bpx_model *model, const float *centres,
                                         bpx_model_report *report);

/// One cycle in general mode (not in the paper: its future work): the host writes each box's
/// min and max (6 floats, 24 bytes; one address across the six banks) and the updater passes
/// them through. It replaces loaded extents: bpx_model_run_centres then needs
/// bpx_model_load_extents again. Errors: NULL_ARGUMENT, TOO_MANY_BOXES, NOT_FINITE,
/// MIN_GREATER_THAN_MAX, OUT_OF_MEMORY (on a validation error nothing changes).
BPX_API bpx_status bpx_model_run_boxes(bpx_model *model, const bpx_box *boxes, uint32_t n,
                                       bpx_model_report *report);

/// The last run's pairs sorted by (i, j), as the host makes them from the collision RAM:
/// the same bytes as the reference backend. NULL with *count 0 before any run.
BPX_API const bpx_pair *bpx_model_pairs(const bpx_model *model, size_t *count);

/// The last run's pairs in the order the emitter wrote them (round robin over the FIFOs).
BPX_API const bpx_pair *bpx_model_emitted(const bpx_model *model, size_t *count);

/// The comparator's address schedule (Table 1) for maximum address max_address: one row per
/// clock, 2m port addresses each (BPX_MODEL_DISCARDED beyond the maximum), row after row into
/// ports. *rows gets the number of rows; if it exceeds capacity (rows), returns CAPACITY and
/// writes nothing. Errors: NULL_ARGUMENT (rows NULL, or ports NULL with capacity > 0),
/// INVALID_ARGUMENT (m out of range), CAPACITY.
BPX_API bpx_status bpx_model_schedule(int m, uint32_t max_address, uint32_t *ports, size_t capacity,
                                      size_t *rows);

/// Name of a store ("on-chip", "ssram", "stream"); NULL when out of range.
BPX_API const char *bpx_model_store_name(bpx_model_store store);

#ifdef __cplusplus
}
#endif
