// bpx RTL: a synthesis-only top for place and route (rtl/pnr_ecp5.sh), not the chip's interface.
//
// bpx_chip's board ports (host registers, six 32-bit SSRAM banks, the collision port) need
// about 330 pins, more than an ECP5 package has. This top keeps them all but brings the SSRAM
// data in 32 bits per clock through a 192-bit shift register, and registers every other input
// and output at the pins, as a board design would. So every path the timing report sees starts
// and ends at a flip-flop or block RAM of the chip (no pin-to-pin paths), and all the chip's
// logic stays: each of its outputs reaches a pin. The trace ports are left open (TRACE 0).
module bpx_ecp5_top #(
    parameter integer M = 4,
    parameter integer DEPTH = 512,
    parameter integer FDEPTH = 1024,
    parameter integer LAT = 2,
    parameter integer AW = $clog2(DEPTH + 2 * M) + 1,
    parameter integer IW = (DEPTH > 1) ? $clog2(DEPTH) : 1
) (
    input  wire          clk,
    input  wire          reg_we,
    input  wire [1:0]    reg_addr,
    input  wire [31:0]   reg_wdata,
    output reg  [31:0]   reg_rdata,
    output reg           ssram_re,
    output reg  [AW-1:0] ssram_addr,
    input  wire [31:0]   ssram_word,   // one bank's word per clock into the shift register
    input  wire          col_ready,
    output reg           col_we,
    output reg  [31:0]   col_addr,
    output reg  [IW-1:0] col_i,
    output reg  [IW-1:0] col_j
);
    reg          we_q, ready_q;
    reg [1:0]    addr_q;
    reg [31:0]   wdata_q;
    reg [6*32-1:0] rdata_q;
    wire [31:0]  rdata;
    wire         re, cwe;
    wire [AW-1:0] saddr;
    wire [31:0]  caddr;
    wire [IW-1:0] ci, cj;

    always @(posedge clk) begin
        we_q <= reg_we;
        ready_q <= col_ready;
        addr_q <= reg_addr;
        wdata_q <= reg_wdata;
        rdata_q <= {rdata_q[5*32-1:0], ssram_word};
        reg_rdata <= rdata;
        ssram_re <= re;
        ssram_addr <= saddr;
        col_we <= cwe;
        col_addr <= caddr;
        col_i <= ci;
        col_j <= cj;
    end

    bpx_chip #(.M(M), .DEPTH(DEPTH), .FDEPTH(FDEPTH), .LAT(LAT), .TRACE(0)) chip (
        .clk(clk), .reg_we(we_q), .reg_addr(addr_q), .reg_wdata(wdata_q), .reg_rdata(rdata),
        .ssram_re(re), .ssram_addr(saddr), .ssram_rdata(rdata_q),
        .col_ready(ready_q), .col_we(cwe), .col_addr(caddr), .col_i(ci), .col_j(cj),
        .phase(), .t_addressing(), .t_ports(), .t_max(), .t_hits_valid(), .t_hits(),
        .t_hit_row(), .t_stalled(), .t_emitted(), .t_pair_i(), .t_pair_j(), .t_fill_max(),
        .t_count());
endmodule
