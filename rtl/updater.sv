// bpx RTL: the updater (paper §4.2, Figure 2), mirroring src/hw/updater.h.
//
// One object per clock: an address counter requests the SSRAM word at `next`; the data comes
// back LAT clocks later through the interface's read pipeline; the adders' first half
// (bpx_fadd_align) goes into the align register and their second half (bpx_fadd_round) into the
// add register; the clock after, it is written at that address. A pass over n objects takes
// n + LAT + 2 clocks, in every mode (the modes without adds go through both registers too).
// Modes (the model's bpx_hw_update_mode):
//   0 boxes   (BPX_HW_PASS_BOXES, not in the paper): min x, y, z from banks 0-2, max x, y, z
//             from banks 3-5, written into the comparator's six memories;
//   1 minima  (BPX_HW_STORE_MINIMA, the paper's initialisation): banks 0-2 hold the
//             origin-centred minima, written into the updater's own minima RAM;
//   2 centres (BPX_HW_ADD_ON_CHIP, the paper's updating phase): banks 0-2 hold the centres;
//             min = centre + minimum, max = centre - minimum (six binary32 adders, the same
//             bits as C's float + and -); a sum beyond FLT_MAX raises `overflow`.
// The minima RAM is read one clock ahead, at the address arriving next clock, so that the
// minimum arrives with the centre (the model reads it at the same address as the SSRAM).
module bpx_updater #(
    parameter integer DEPTH = 512,
    parameter integer AW = 11,
    parameter integer LAT = 2
) (
    input  wire            clk,
    input  wire            start,      // begin a pass over SSRAM addresses 0 .. n - 1
    input  wire [1:0]      mode_in,    // latched at start: 0 boxes, 1 minima, 2 centres
    input  wire [AW-1:0]   n,
    // SSRAM read port (through the interface) and the data arriving this clock.
    output wire            req,
    output wire [AW-1:0]   req_addr,
    input  wire            rd_valid,
    input  wire [AW-1:0]   rd_addr,
    input  wire [6*32-1:0] rd_data,    // banks 0-5
    input  wire [AW-1:0]   rd_addr_next, // the address whose data arrives next clock
    output wire            overflow,   // a centre +/- minimum overflowed this clock
    // The comparator's write port.
    output wire            we,
    output wire [AW-1:0]   waddr,
    output wire [6*32-1:0] wdata,      // memory order: min x, max x, min y, max y, min z, max z
    output reg             active,
    output wire            active_d    // active after this clock edge
);
    localparam integer CW = $clog2(LAT + 2) + 1;  // reads in flight

    localparam integer PW = 41;  // bpx_fadd_align's output (rtl/fadd.sv)

    reg [AW-1:0]   next, last;
    reg [CW-1:0]   in_flight;
    // The align register: the arriving word (modes 0, 1) and the six adders' first halves.
    reg            pipe_valid;
    reg [AW-1:0]   pipe_addr;
    reg [6*32-1:0] pipe;
    reg [6*PW-1:0] pipe_part;
    // The add register: what is written next clock.
    reg            stage_valid;
    reg [AW-1:0]   stage_addr;
    reg [6*32-1:0] stage;
    reg [1:0]      mode;
    localparam integer RW = (DEPTH > 1) ? $clog2(DEPTH) : 1;

    // The minima RAM (x, y, z of one object per word) and its read register.
    reg [3*32-1:0] minima [0:DEPTH-1];
    reg [3*32-1:0] mq;
    always @(posedge clk) begin
        if (active && stage_valid && mode == 2'd1)
            minima[stage_addr[RW-1:0]] <= stage[3*32-1:0];
        mq <= minima[rd_addr_next[RW-1:0]];
    end

    wire issue = active && next < last;
    wire take = active && rd_valid;
    assign req = issue;
    assign req_addr = next;
    assign we = active && stage_valid && mode != 2'd1;
    assign waddr = stage_addr;
    assign wdata = stage;

    // Banks 0-2 are the minima x, y, z and banks 3-5 the maxima; the memories interleave them.
    wire [6*32-1:0] box = {rd_data[5*32 +: 32], rd_data[2*32 +: 32],
                           rd_data[4*32 +: 32], rd_data[1*32 +: 32],
                           rd_data[3*32 +: 32], rd_data[0*32 +: 32]};

    // centre + minimum and centre - minimum, per axis: first halves from the arriving data,
    // second halves from the align register.
    wire [6*PW-1:0] parts;
    wire [6*32-1:0] sums;
    wire [5:0]      ovf;
    genvar ga;
    generate
        for (ga = 0; ga < 3; ga = ga + 1) begin : axis
            wire [31:0] c = rd_data[ga*32 +: 32];
            wire [31:0] m = mq[ga*32 +: 32];
            bpx_fadd_align lo (.a(c), .b(m), .p(parts[(2*ga)*PW +: PW]));
            bpx_fadd_align hi (.a(c), .b({~m[31], m[30:0]}), .p(parts[(2*ga+1)*PW +: PW]));
        end
        for (ga = 0; ga < 6; ga = ga + 1) begin : round
            bpx_fadd_round r (.p(pipe_part[ga*PW +: PW]), .s(sums[ga*32 +: 32]),
                              .overflow(ovf[ga]));
        end
    endgenerate
    assign overflow = pipe_valid && mode == 2'd2 && |ovf;
    wire [6*32-1:0] next_pipe = mode == 2'd0 ? box : rd_data;
    wire [6*32-1:0] next_stage = mode == 2'd2 ? sums : pipe;

    wire [AW-1:0] next_n = next + issue;
    wire [CW-1:0] in_flight_n = in_flight + issue - take;
    assign active_d = start ? (n != 0)
                      : (active && (next_n < last || in_flight_n != 0 || take || pipe_valid));

    always @(posedge clk) begin
        if (start) begin
            next <= {AW{1'b0}};
            last <= n;
            in_flight <= {CW{1'b0}};
            pipe_valid <= 1'b0;
            stage_valid <= 1'b0;
            active <= n != 0;
            mode <= mode_in;
        end else if (active) begin
            next <= next_n;
            in_flight <= in_flight_n;
            pipe_valid <= take;
            if (take) begin
                pipe_addr <= rd_addr;
                pipe <= next_pipe;
                pipe_part <= parts;
            end
            stage_valid <= pipe_valid;
            if (pipe_valid) begin
                stage_addr <= pipe_addr;
                stage <= next_stage;
            end
            active <= active_d;
        end
    end
endmodule
