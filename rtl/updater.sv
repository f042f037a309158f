// bpx RTL: the updater (paper §4.2, Figure 2), mirroring src/hw/updater.h.
//
// One object per clock: an address counter requests the SSRAM word at `next`; the data comes
// back LAT clocks later through the interface's read pipeline into the operand register (with
// the minimum from the minima RAM); eight registers between the adder's nine steps (rtl/fadd.sv)
// follow, then the add register; the clock after, it is written at that address: S = 10
// registers, a pass over n objects takes n + LAT + 10 clocks, in every mode (the modes without
// adds go through as many registers). The model's updater has the same registers
// (BPX_HW_UPDATE_STAGES in src/hw/updater.h).
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
    localparam integer S = 10;  // registers from the arriving data to the write
    localparam integer RW = (DEPTH > 1) ? $clog2(DEPTH) : 1;
    // The adder's widths between its steps (rtl/fadd.sv's BPX_FADD_P0 .. P7; fadd.sv may be
    // read after this file).
    localparam integer P0 = 89, P1 = 71, P2 = 97, P3 = 68, P4 = 41, P5 = 55, P6 = 47, P7 = 42;

    reg [AW-1:0]   next;
    reg [AW-1:0]   left;       // reads still to issue
    reg            pending;    // left != 0, a register: issue and active_d start at flip-flops
    reg [CW-1:0]   in_flight;
    reg [1:0]      mode;
    // Register k of the pipeline: valid and RAM address (0: operands, S - 1: the add register).
    reg            v [0:S-1];
    reg [AW-1:0]   a [0:S-1];
    // The operand register: the arriving word and the minimum read with it.
    reg [6*32-1:0] op;
    reg [3*32-1:0] op_m;
    // The word of modes 0 and 1 alongside the adders (registers 1 .. S - 2), and the add register.
    reg [6*32-1:0] word [1:S-2];
    reg [6*32-1:0] stage;

    // The minima RAM (x, y, z of one object per word) and its read register.
    reg [3*32-1:0] minima [0:DEPTH-1];
    reg [3*32-1:0] mq;
    always @(posedge clk) begin
        if (active && v[S-1] && mode == 2'd1)
            minima[a[S-1][RW-1:0]] <= stage[3*32-1:0];
        mq <= minima[rd_addr_next[RW-1:0]];
    end

    wire issue = active && pending;
    wire take = active && rd_valid;
    assign req = issue;
    assign req_addr = next;
    assign we = active && v[S-1] && mode != 2'd1;
    assign waddr = a[S-1];
    assign wdata = stage;

    // Banks 0-2 are the minima x, y, z and banks 3-5 the maxima; the memories interleave them.
    wire [6*32-1:0] box = {op[5*32 +: 32], op[2*32 +: 32], op[4*32 +: 32], op[1*32 +: 32],
                           op[3*32 +: 32], op[0*32 +: 32]};

    // centre + minimum and centre - minimum, per axis (memory order), one register per step.
    wire [6*32-1:0] sums;
    wire [5:0]      ovf;
    genvar ga;
    generate
        for (ga = 0; ga < 6; ga = ga + 1) begin : adder
            wire [31:0] c = op[(ga/2)*32 +: 32];
            wire [31:0] m0 = op_m[(ga/2)*32 +: 32];
            wire [31:0] m = (ga % 2) ? {~m0[31], m0[30:0]} : m0;  // max = centre - minimum
            wire [P0-1:0] p0;
            wire [P1-1:0] p1;
            wire [P2-1:0] p2;
            wire [P3-1:0] p3;
            wire [P4-1:0] p4;
            wire [P5-1:0] p5;
            wire [P6-1:0] p6;
            reg  [P0-1:0] r0;
            reg  [P1-1:0] r1;
            reg  [P2-1:0] r2;
            reg  [P3-1:0] r3;
            reg  [P4-1:0] r4;
            reg  [P5-1:0] r5;
            reg  [P6-1:0] r6;
            reg  [P7-1:0] r7;
            wire [P7-1:0] p7;
            bpx_fadd_compare s0 (.a(c), .b(m), .p(p0));
            bpx_fadd_swap   s1 (.p(r0), .q(p1));
            bpx_fadd_coarse s2 (.p(r1), .q(p2));
            bpx_fadd_fine   s3 (.q(r2), .r(p3));
            bpx_fadd_add    s4 (.r(r3), .p(p4));
            bpx_fadd_zeros  s5 (.p(r4), .q(p5));
            bpx_fadd_clamp  s6 (.q(r5), .r(p6));
            bpx_fadd_shift  s7 (.r(r6), .t(p7));
            bpx_fadd_round  s8 (.t(r7), .s(sums[ga*32 +: 32]), .overflow(ovf[ga]));
            always @(posedge clk) begin
                r0 <= p0;
                r1 <= p1;
                r2 <= p2;
                r3 <= p3;
                r4 <= p4;
                r5 <= p5;
                r6 <= p6;
                r7 <= p7;
            end
        end
    endgenerate
    assign overflow = active && v[S-2] && mode == 2'd2 && |ovf;

    wire [AW-1:0] next_n = next + issue;
    wire [AW-1:0] left_n = left - issue;
    wire          pending_n = |left[AW-1:1] || (left == 1 && !issue);  // left_n != 0
    wire [CW-1:0] in_flight_n = in_flight + issue - take;
    reg           more;   // a register of the pipeline other than the add register is valid
    integer k, t, w;
    always @* begin
        more = 1'b0;
        k = 0;
        for (k = 0; k < S - 1; k = k + 1)
            more = more | v[k];
    end
    assign active_d = start ? (n != 0)
                      : (active && (pending_n || in_flight_n != 0 || take || more));

    always @(posedge clk) begin
        if (start) begin
            next <= {AW{1'b0}};
            left <= n;
            pending <= n != 0;
            in_flight <= {CW{1'b0}};
            for (t = 0; t < S; t = t + 1)
                v[t] <= 1'b0;
            active <= n != 0;
            mode <= mode_in;
        end else if (active) begin
            next <= next_n;
            left <= left_n;
            pending <= pending_n;
            in_flight <= in_flight_n;
            v[0] <= take;
            a[0] <= rd_addr;
            for (t = 1; t < S; t = t + 1) begin
                v[t] <= v[t-1];
                a[t] <= a[t-1];
            end
            active <= active_d;
        end
    end
    // Data registers: no enable (a register's value matters only while its valid bit is set).
    always @(posedge clk) begin
        op <= rd_data;
        op_m <= mq;
        word[1] <= mode == 2'd0 ? box : op;
        for (w = 2; w < S - 1; w = w + 1)
            word[w] <= word[w-1];
        stage <= mode == 2'd2 ? sums : word[S-2];
    end
endmodule
