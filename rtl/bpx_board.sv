// bpx RTL: the board around the chip, for simulation: the six SSRAM banks (one address holds
// one box: min x, y, z in banks 0-2, max x, y, z in banks 3-5), a pipelined read port with
// latency LAT (ZBT), and the host's write port into the banks. The collision SSRAM is the
// harness: it records the chip's collision write port.
module bpx_board #(
    parameter integer M = 4,
    parameter integer DEPTH = 512,
    parameter integer FDEPTH = 1024,
    parameter integer LAT = 2,
    parameter integer AW = $clog2(DEPTH + 2 * M) + 1,
    parameter integer IW = (DEPTH > 1) ? $clog2(DEPTH) : 1
) (
    input  wire            clk,
    input  wire            host_we,       // host writes bank host_bank, word host_addr
    input  wire [2:0]      host_bank,
    input  wire [31:0]     host_addr,
    input  wire [31:0]     host_data,
    input  wire            reg_we,
    input  wire [1:0]      reg_addr,
    input  wire [31:0]     reg_wdata,
    output wire [31:0]     reg_rdata,
    input  wire            col_ready,     // the harness's collision SSRAM takes a write
    output wire            col_we,
    output wire [31:0]     col_addr,
    output wire [IW-1:0]   col_i,
    output wire [IW-1:0]   col_j,
    output wire [2:0]      phase,
    output wire            t_addressing,
    output wire [2*M*AW-1:0] t_ports,
    output wire [AW-1:0]   t_max,
    output wire            t_hits_valid,
    output wire [2*M-2:0]  t_hits,
    output wire [IW-1:0]   t_hit_row,
    output wire            t_stalled,
    output wire            t_emitted,
    output wire [IW-1:0]   t_pair_i,
    output wire [IW-1:0]   t_pair_j,
    output wire [31:0]     t_fill_max,
    output wire [31:0]     t_count
);
    wire            ssram_re;
    wire [AW-1:0]   ssram_addr;
    reg  [6*32-1:0] pipe [0:LAT-1];
    reg  [31:0]     bank [0:5][0:DEPTH-1];
    integer b, s;
    always @(posedge clk) begin
        if (host_we && host_addr < DEPTH)
            bank[host_bank][host_addr[IW-1:0]] <= host_data;
        for (s = LAT - 1; s > 0; s = s - 1)
            pipe[s] <= pipe[s-1];
        for (b = 0; b < 6; b = b + 1)
            pipe[0][b*32 +: 32] <= (ssram_re && ssram_addr < DEPTH) ? bank[b][ssram_addr[IW-1:0]] : 32'd0;
    end

    bpx_chip #(.M(M), .DEPTH(DEPTH), .FDEPTH(FDEPTH), .LAT(LAT), .TRACE(1)) chip (
        .clk(clk), .reg_we(reg_we), .reg_addr(reg_addr), .reg_wdata(reg_wdata),
        .reg_rdata(reg_rdata), .ssram_re(ssram_re), .ssram_addr(ssram_addr),
        .ssram_rdata(pipe[LAT-1]), .col_ready(col_ready), .col_we(col_we), .col_addr(col_addr), .col_i(col_i),
        .col_j(col_j), .phase(phase), .t_addressing(t_addressing), .t_ports(t_ports),
        .t_max(t_max), .t_hits_valid(t_hits_valid), .t_hits(t_hits), .t_hit_row(t_hit_row),
        .t_stalled(t_stalled), .t_emitted(t_emitted), .t_pair_i(t_pair_i), .t_pair_j(t_pair_j),
        .t_fill_max(t_fill_max), .t_count(t_count));
endmodule
