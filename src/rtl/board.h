// The Verilated board (rtl/bpx_board.sv: the chip and its six SSRAM banks) behind a C interface,
// so that the rtl backend (backend.c) stays C and only board.cpp is C++. The board is driven
// through its ports alone, as a host would: SSRAM writes, the registers, clocks, and the
// collision write port (the board's collision SSRAM is the caller's pair callback).
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "bpx/base.h"

#ifdef __cplusplus
extern "C" {
#endif

/// The chip's parameters (rtl/CMakeLists.txt's names): the paper's build, DEPTH 512 boxes on
/// chip, m = 4 (8 read ports, 7 comparison units), FIFOs of 1024 entries, SSRAM latency 2.
enum {
    BPX_RTL_M = 4,
    BPX_RTL_DEPTH = 512,
    BPX_RTL_FDEPTH = 1024,
    BPX_RTL_LAT = 2,
};

/// CONTROL's mode field: general boxes (six banks), the paper's initialisation (minima in
/// banks 0-2) and updating (centres in banks 0-2) phases.
enum { BPX_RTL_MODE_BOXES = 0, BPX_RTL_MODE_MINIMA = 1, BPX_RTL_MODE_CENTRES = 2 };

typedef struct bpx_rtl_board bpx_rtl_board;

/// What one run did.
typedef struct bpx_rtl_run {
    uint64_t clocks;           // from start to STATUS.done
    uint64_t address_clocks;   // clocks the comparator addressed its RAMs (2M - 1 tests each)
    uint32_t count;            // the COUNT register: collisions written
    bool error, overflow;      // STATUS bits: n > DEPTH; a box rounded beyond FLT_MAX
    bool finished;             // STATUS.done came within the clock limit
} bpx_rtl_run;

/// Takes one collision write (i, j), in the chip's emission order; false stops the recording
/// (the chip still runs to its end).
typedef bool bpx_rtl_emit(void *user, uint32_t i, uint32_t j);

/// A board at rest; NULL when out of memory (the board's storage comes from the library's
/// allocator, the Verilated model's own from C++'s).
bpx_rtl_board *bpx__rtl_board_create(void);
void bpx__rtl_board_destroy(bpx_rtl_board *board);
/// Writes words[0], words[stride], ... (n words) into SSRAM bank `bank` (0-5) at addresses
/// 0 .. n - 1, one word a clock.
void bpx__rtl_board_write(bpx_rtl_board *board, int bank, const float *words, uint32_t n,
                          uint32_t stride);
/// The DEPTH register: the boxes the chip holds (a larger N sets STATUS.error).
uint32_t bpx__rtl_board_depth(bpx_rtl_board *board);
/// Writes N and CONTROL (start, mode), clocks until STATUS.done and hands each collision write
/// to emit. Returns what the run did.
bpx_rtl_run bpx__rtl_board_run(bpx_rtl_board *board, uint32_t n, int mode, bpx_rtl_emit *emit,
                               void *user);

#ifdef __cplusplus
}
#endif
