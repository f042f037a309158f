// bpx RTL: IEEE-754 binary32 addition: round to nearest, ties to even; subnormal inputs and
// results exact (no flush to zero); the same bits as C's float + (SSE) for every finite pair
// (rtl/harness/fadd_test.cpp checks it). A finite sum beyond FLT_MAX rounds to infinity and
// raises `overflow`. Non-finite inputs (which the host never sends): infinities add as IEEE
// says, a NaN or inf - inf gives the quiet NaN 0x7fc00000.
//
// Nine combinational steps, so that the updater can put a register after each (one add is far
// too long for one clock at the paper's 108 MHz on an ECP5: docs/rtl.md, "What limits fmax"):
//   1 compare: which operand has the larger magnitude (`swap`: a 31-bit compare); alongside,
//             both exponents (subnormals: 1), both differences, both significands, the
//             special cases
//   2 swap:   the operand of larger magnitude is x; the exponent difference d = ex - ey (only
//             multiplexers, selected by the registered `swap`)
//   3 coarse: y's significand (with guard, round and sticky room) shifted right by d & ~7
//   4 fine:   ... and by d & 7; the bits shifted out ORed into the sticky bit
//   5 add:    the significands added or subtracted (the raw sum, 28 bits)
//   6 zeros:  the sum's leading zeros, found from 4-bit groups (no shifting)
//   7 clamp:  the left shift, the leading zeros but not below the smallest exponent (which
//             makes subnormals), and the exponent after it
//   8 shift:  normalised: right by one after a carry, else left by that shift
//   9 round:  round to nearest even, overflow to infinity, the special cases
// bpx_fadd is the nine in one combinational stage (the adder test's top).
`define BPX_FADD_P0 89  // {nan, inf, sa, sb, swap, ea[8:0], eb[8:0], dab[8:0], dba[8:0], ma[23:0], mb[23:0]}
`define BPX_FADD_P1 71  // {nan, inf, sx, sy, sub, e[8:0], d[8:0], mx[23:0], my[23:0]}
`define BPX_FADD_P2 97  // {nan, inf, sx, sy, sub, e[8:0], d[2:0], far, sticky, mx, w[53:0]}
`define BPX_FADD_P3 68  // {nan, inf, sx, sy, sub, e[8:0], xa[26:0], ya[26:0]}
`define BPX_FADD_P4 41  // {nan, inf, sx, sy, e[8:0], sum[27:0]}
`define BPX_FADD_P5 55  // {p4, em1[8:0], lz[4:0]}
`define BPX_FADD_P6 47  // {nan, inf, sx, sy, zero, e[8:0], shift[4:0], sum[27:0]}
`define BPX_FADD_P7 42  // {nan, inf, sx, sy, zero, e[8:0], sum[27:0]}

module bpx_fadd_compare (
    input  wire [31:0]             a,
    input  wire [31:0]             b,
    output wire [`BPX_FADD_P0-1:0] p
);
    wire       swap = b[30:0] > a[30:0];
    wire [8:0] ea = (a[30:23] == 8'd0) ? 9'd1 : {1'b0, a[30:23]};  // subnormals: exponent 1
    wire [8:0] eb = (b[30:23] == 8'd0) ? 9'd1 : {1'b0, b[30:23]};
    wire [8:0] dab = ea - eb, dba = eb - ea;  // both differences at once, picked in step 2
    wire [23:0] ma = {a[30:23] != 8'd0, a[22:0]}, mb = {b[30:23] != 8'd0, b[22:0]};
    // Non-finite inputs: a NaN or inf - inf is NaN; else an infinity is x's.
    wire nan_a = a[30:23] == 8'hff && a[22:0] != 0, nan_b = b[30:23] == 8'hff && b[22:0] != 0;
    wire inf_a = a[30:23] == 8'hff, inf_b = b[30:23] == 8'hff;
    wire nan = nan_a || nan_b || (inf_a && inf_b && (a[31] ^ b[31]));
    wire inf = inf_a || inf_b;
    assign p = {nan, inf, a[31], b[31], swap, ea, eb, dab, dba, ma, mb};
endmodule

module bpx_fadd_swap (
    input  wire [`BPX_FADD_P0-1:0] p,
    output wire [`BPX_FADD_P1-1:0] q
);
    wire        nan = p[88], inf = p[87], sa = p[86], sb = p[85], swap = p[84];
    wire [8:0]  ea = p[83:75], eb = p[74:66], dab = p[65:57], dba = p[56:48];
    wire [23:0] ma = p[47:24], mb = p[23:0];
    assign q = {nan, inf, swap ? sb : sa, swap ? sa : sb, sa ^ sb, swap ? eb : ea,
                swap ? dba : dab, swap ? mb : ma, swap ? ma : mb};
endmodule

module bpx_fadd_coarse (
    input  wire [`BPX_FADD_P1-1:0] p,
    output wire [`BPX_FADD_P2-1:0] q
);
    wire [8:0]  d = p[56:48];
    wire [23:0] my = p[23:0];
    wire        far = d > 9'd30;  // y is all sticky
    wire [53:0] w = {my, 3'b000, 27'd0} >> {d[4:3], 3'b000};
    assign q = {p[70:57], d[2:0], far, far & (|my), p[47:24], far ? 54'd0 : w};
endmodule

module bpx_fadd_fine (
    input  wire [`BPX_FADD_P2-1:0] q,
    output wire [`BPX_FADD_P3-1:0] r
);
    wire [2:0]  d = q[82:80];
    wire        far = q[79], sticky = q[78];
    wire [23:0] mx = q[77:54];
    wire [53:0] w = q[53:0] >> d;   // for d <= 30 no set bit falls off the end
    wire [26:0] ya = far ? {26'd0, sticky} : {w[53:28], |w[27:0]};
    assign r = {q[96:83], mx, 3'b000, ya};
endmodule

module bpx_fadd_add (
    input  wire [`BPX_FADD_P3-1:0] r,
    output wire [`BPX_FADD_P4-1:0] p
);
    wire        sub = r[63];
    wire [26:0] xa = r[53:27], ya = r[26:0];
    wire [27:0] sum = sub ? ({1'b0, xa} - {1'b0, ya}) : ({1'b0, xa} + {1'b0, ya});
    assign p = {r[67:64], r[62:54], sum};
endmodule

module bpx_fadd_zeros (
    input  wire [`BPX_FADD_P4-1:0] p,
    output wire [`BPX_FADD_P5-1:0] q
);
    // Leading zeros of sum[26:0] (27 when zero): eight 4-bit groups of {sum[26:0], 5'b11111},
    // the first non-zero group and the zeros inside it. Alongside, e - 1 for the next step.
    wire [31:0] x = {p[26:0], 5'b11111};
    reg  [4:0]  lz;
    reg         found;
    integer g;
    always @* begin
        lz = 5'd0;
        found = 1'b0;
        g = 0;
        for (g = 7; g >= 0; g = g - 1) begin
            if (!found && x[4*g +: 4] != 4'd0) begin
                found = 1'b1;
                lz[4:2] = 3'd7 - g[2:0];
                lz[1:0] = x[4*g+3] ? 2'd0 : x[4*g+2] ? 2'd1 : x[4*g+1] ? 2'd2 : 2'd3;
            end
        end
    end
    assign q = {p, p[36:28] - 9'd1, lz};
endmodule

module bpx_fadd_clamp (
    input  wire [`BPX_FADD_P5-1:0] q,
    output wire [`BPX_FADD_P6-1:0] r
);
    // The left shift: the leading zeros, but not below the smallest exponent (subnormals); the
    // exponent after it (after a carry: one right, e + 1).
    wire [8:0]  e = q[50:42];
    wire [27:0] sum = q[41:14];
    wire [8:0]  em1 = q[13:5];
    wire [4:0]  lz = q[4:0];
    wire        below = {4'd0, lz} < em1;
    wire [4:0]  shift = below ? lz : em1[4:0];  // em1 <= lz <= 27 when not below
    wire [8:0]  e2 = sum[27] ? e + 9'd1 : below ? e - {4'd0, lz} : 9'd1;
    assign r = {q[54:51], sum == 28'd0, e2, shift, sum};
endmodule

module bpx_fadd_shift (
    input  wire [`BPX_FADD_P6-1:0] r,
    output wire [`BPX_FADD_P7-1:0] t
);
    wire [27:0] sum = r[27:0];
    wire [4:0]  shift = r[32:28];
    wire [27:0] s = sum[27] ? {1'b0, sum[27:2], sum[1] | sum[0]} : sum << shift;
    assign t = {r[46:33], s};
endmodule

module bpx_fadd_round (
    input  wire [`BPX_FADD_P7-1:0] t,
    output reg  [31:0]             s,
    output reg                     overflow
);
    wire        nan = t[41], inf = t[40], sx = t[39], sy = t[38], zero = t[37];
    wire [8:0]  e = t[36:28];
    wire [27:0] sum = t[27:0];
    // Round to nearest even: {exponent, fraction} + 1 carries into the exponent as needed
    // (subnormal -> normal, FLT_MAX -> infinity).
    wire        up = sum[2] & (sum[1] | sum[0] | sum[3]);
    wire [30:0] mag = {(sum[26] ? e[7:0] : 8'd0), sum[25:3]} + {30'd0, up};
    // Overflow from the operands of that increment, not from its result (a shorter path): the
    // exponent is already 255 or more, or the rounding carries 0xfe.ffffff into 0xff.
    wire        ovf = e >= 9'd255 || (sum[26] && e[7:0] == 8'hfe && &sum[25:3] && up);
    always @* begin
        overflow = ovf;
        s = {zero ? (sx & sy) : sx, zero ? 31'd0 : ovf ? {8'hff, 23'd0} : mag};
        if (nan || inf) begin
            overflow = 1'b0;
            s = nan ? 32'h7fc0_0000 : {sx, 8'hff, 23'd0};
        end
    end
endmodule

module bpx_fadd (
    input  wire [31:0] a,
    input  wire [31:0] b,
    output wire [31:0] s,
    output wire        overflow
);
    wire [`BPX_FADD_P0-1:0] p0;
    wire [`BPX_FADD_P1-1:0] p1;
    wire [`BPX_FADD_P2-1:0] p2;
    wire [`BPX_FADD_P3-1:0] p3;
    wire [`BPX_FADD_P4-1:0] p4;
    wire [`BPX_FADD_P5-1:0] p5;
    wire [`BPX_FADD_P6-1:0] p6;
    wire [`BPX_FADD_P7-1:0] p7;
    bpx_fadd_compare s0 (.a(a), .b(b), .p(p0));
    bpx_fadd_swap   s1 (.p(p0), .q(p1));
    bpx_fadd_coarse s2 (.p(p1), .q(p2));
    bpx_fadd_fine   s3 (.q(p2), .r(p3));
    bpx_fadd_add    s4 (.r(p3), .p(p4));
    bpx_fadd_zeros  s5 (.p(p4), .q(p5));
    bpx_fadd_clamp  s6 (.q(p5), .r(p6));
    bpx_fadd_shift  s7 (.r(p6), .t(p7));
    bpx_fadd_round  s8 (.t(p7), .s(s), .overflow(overflow));
endmodule
