// The Verilated board (board.h): the only C++ of the rtl backend. Drives rtl/bpx_board.sv as
// rtl/harness/lockstep.cpp does, through its ports only (no trace output but the comparator's
// addressing flag, for the test count), so that the units' insides may change freely.
#include <cstring>
#include <new>

// Verilator's headers are not held to the project's warning flags.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
#pragma GCC diagnostic ignored "-Wshadow"
#include <verilated.h>

#include "Vbpx_rtl_board.h"
#pragma GCC diagnostic pop

extern "C" {
#include "core/alloc.h"
}
#include "rtl/board.h"

// Register addresses (rtl/interface.sv).
enum { REG_N = 0, REG_CONTROL = 1, REG_COUNT = 2, REG_DEPTH = 3 };
enum { STATUS_DONE = 1, STATUS_ERROR = 2, STATUS_OVERFLOW = 4 };

struct bpx_rtl_board {
    VerilatedContext context;
    Vbpx_rtl_board top;
    bpx_rtl_board() : top(&context, "bpx_rtl")
    {
        top.clk = 0;
        top.host_we = 0;
        top.reg_we = 0;
        top.col_ready = 1; // the host's collision SSRAM takes every write: no back-pressure
        top.eval();
    }
    void tick()
    {
        top.clk = 1;
        top.eval();
        top.clk = 0;
        top.eval();
    }
    void reg_write(int address, uint32_t value)
    {
        top.reg_we = 1;
        top.reg_addr = address;
        top.reg_wdata = value;
        tick();
        top.reg_we = 0;
        top.eval();
    }
    uint32_t reg_read(int address)
    {
        top.reg_addr = address;
        top.eval();
        return top.reg_rdata;
    }
};

bpx_rtl_board *bpx__rtl_board_create(void)
{
    void *memory = bpx__alloc(sizeof(bpx_rtl_board));
    if (!memory)
        return nullptr;
    try {
        return new (memory) bpx_rtl_board;
    } catch (...) { // std::bad_alloc from the Verilated model's own allocations
        bpx__free(memory, sizeof(bpx_rtl_board));
        return nullptr;
    }
}

void bpx__rtl_board_destroy(bpx_rtl_board *board)
{
    if (!board)
        return;
    board->top.final();
    board->~bpx_rtl_board();
    bpx__free(board, sizeof *board);
}

void bpx__rtl_board_write(bpx_rtl_board *board, int bank, const float *words, uint32_t n,
                          uint32_t stride)
{
    Vbpx_rtl_board &top = board->top;
    top.host_we = 1;
    top.host_bank = bank;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t bits;
        std::memcpy(&bits, &words[(size_t)i * stride], sizeof bits);
        top.host_addr = i;
        top.host_data = bits;
        board->tick();
    }
    top.host_we = 0;
    top.eval();
}

uint32_t bpx__rtl_board_depth(bpx_rtl_board *board)
{
    return board->reg_read(REG_DEPTH);
}

bpx_rtl_run bpx__rtl_board_run(bpx_rtl_board *board, uint32_t n, int mode, bpx_rtl_emit *emit,
                               void *user)
{
    Vbpx_rtl_board &top = board->top;
    bpx_rtl_run run{};
    board->reg_write(REG_N, n);
    board->reg_write(REG_CONTROL, 1u | (uint32_t)mode << 1);
    // Far beyond the longest run (every pair emitted, one a clock, after the comparisons): a
    // chip that never finishes is reported, not waited for.
    const uint64_t limit = (uint64_t)n * n + 64u * (uint64_t)n + 4096u;
    bool recording = true;
    // reg_addr stays at CONTROL, so STATUS is on reg_rdata after each clock's evaluation: no
    // third eval() a clock to read it.
    while (!(top.reg_rdata & STATUS_DONE) && run.clocks < limit) {
        // Before the edge: the collision port's write and the comparator's addressing.
        if (top.col_we && recording)
            recording = emit(user, top.col_i, top.col_j);
        run.address_clocks += top.t_addressing;
        board->tick();
        run.clocks++;
    }
    const uint32_t status = board->reg_read(REG_CONTROL);
    run.finished = status & STATUS_DONE;
    run.error = status & STATUS_ERROR;
    run.overflow = status & STATUS_OVERFLOW;
    run.count = board->reg_read(REG_COUNT);
    return run;
}
