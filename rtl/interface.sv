// bpx RTL: the CPU-IC interface (paper §4.5, §4.5.1), mirroring src/hw/interface.h.
//
// - Registers, written and read by the host: N (boxes), CONTROL (bit 0: start; bits 2:1 the
//   mode: 0 general boxes, 1 initialisation (minima), 2 updating (centres)), STATUS (bit 0
//   done, bit 1 error: n beyond DEPTH, bit 2 overflow: a box coordinate rounded beyond
//   FLT_MAX), COUNT (collisions written), DEPTH (read-only: the boxes the chip holds, its limit
//   on N; a larger N sets STATUS.error).
// - The SSRAM read port the updater uses: the board's SSRAM returns data LAT clocks after the
//   address; the interface keeps each read's valid bit and address in a LAT-stage pipeline so
//   that they arrive with the data.
// - The collision output, a valid/ready stream: the emitter's output register is the valid
//   pair; on a clock with col_ready it is taken (written at address COUNT: one collision per
//   address) and COUNT advances; without col_ready the emitter holds it (back-pressure, as the
//   model's collision_ready hook).
module bpx_interface #(
    parameter integer DEPTH = 512,
    parameter integer AW = 11,
    parameter integer IW = 9,
    parameter integer LAT = 2
) (
    input  wire          clk,
    input  wire          clear,       // start of a run: empty the read pipeline, COUNT = 0
    // Host register port.
    input  wire          reg_we,
    input  wire [1:0]    reg_addr,    // 0 N, 1 CONTROL/STATUS, 2 COUNT, 3 DEPTH
    input  wire [31:0]   reg_wdata,
    output reg  [31:0]   reg_rdata,
    output reg  [31:0]   n,
    output wire          start,       // CONTROL bit 0 written with 1
    output wire [1:0]    mode,        // CONTROL bits 2:1 (with start)
    input  wire          done,
    input  wire          error,
    input  wire          overflow,
    // SSRAM read port: the updater's request and the data arriving this clock.
    input  wire          req,
    input  wire [AW-1:0] req_addr,
    output wire          ssram_re,
    output wire [AW-1:0] ssram_addr,
    output wire          rd_valid,
    output wire [AW-1:0] rd_addr,
    output wire [AW-1:0] rd_addr_next, // the read whose data arrives next clock
    // Collision write port (to the board's collision SSRAM).
    input  wire          out_valid,
    input  wire [IW-1:0] out_i,
    input  wire [IW-1:0] out_j,
    input  wire          col_ready,
    output wire          col_we,
    output wire [31:0]   col_addr,
    output wire [IW-1:0] col_i,
    output wire [IW-1:0] col_j,
    output reg  [31:0]   count
);
    assign start = reg_we && reg_addr == 2'd1 && reg_wdata[0];
    assign mode = reg_wdata[2:1];
    always @(posedge clk)
        if (reg_we && reg_addr == 2'd0)
            n <= reg_wdata;
    always @* begin
        case (reg_addr)
            2'd0: reg_rdata = n;
            2'd1: reg_rdata = {29'd0, overflow, error, done};
            2'd2: reg_rdata = count;
            default: reg_rdata = DEPTH;
        endcase
    end

    assign ssram_re = req;
    assign ssram_addr = req_addr;
    reg          pv [0:LAT-1];
    reg [AW-1:0] pa [0:LAT-1];
    integer s;
    always @(posedge clk) begin
        for (s = LAT - 1; s > 0; s = s - 1) begin
            pv[s] <= clear ? 1'b0 : pv[s-1];
            pa[s] <= pa[s-1];
        end
        pv[0] <= clear ? 1'b0 : req;
        pa[0] <= req_addr;
    end
    assign rd_valid = pv[LAT-1];
    assign rd_addr = pa[LAT-1];
    generate
        if (LAT == 1) begin : lat1
            assign rd_addr_next = req_addr;
        end else begin : latn
            assign rd_addr_next = pa[LAT-2];
        end
    endgenerate

    assign col_we = out_valid;
    assign col_addr = count;
    assign col_i = out_i;
    assign col_j = out_j;
    always @(posedge clk)
        if (clear)
            count <= 32'd0;
        else if (out_valid && col_ready)
            count <= count + 1'b1;
endmodule
