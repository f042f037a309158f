// bpx RTL: IEEE-754 binary32 addition: round to nearest, ties to even; subnormal inputs and
// results exact (no flush to zero); the same bits as C's float + (SSE) for every finite pair
// (rtl/harness/fadd_test.cpp checks it). A finite sum beyond FLT_MAX rounds to infinity and
// raises `overflow`. Non-finite inputs (which the host never sends): infinities add as IEEE
// says, a NaN or inf - inf gives the quiet NaN 0x7fc00000.
//
// Two halves, so that the updater can put a register between them (one add is too long for
// one clock at the paper's 108 MHz on an ECP5: docs/rtl.md):
//   bpx_fadd_align: the operand of larger magnitude is x; y's significand is aligned to it with
//     three extra bits (guard, round, sticky: the OR of everything shifted out); the significands
//     are added or subtracted. Out: the raw sum, x's exponent, the signs, the special cases.
//   bpx_fadd_round: the sum is normalised (right by one after a carry; left by its leading
//     zeros, but not below the smallest exponent, which makes subnormals) and rounded.
// bpx_fadd is the two in one combinational stage (the adder test's top).
`define BPX_FADD_PW 41  // {nan, inf, sx, sy, e[8:0], sum[27:0]}

module bpx_fadd_align (
    input  wire [31:0]               a,
    input  wire [31:0]               b,
    output wire [`BPX_FADD_PW-1:0]   p
);
    reg        swap, sx, sy, sub, nan, inf;
    reg [7:0]  ex, ey;
    reg [22:0] fx, fy;
    reg [23:0] mx, my;
    reg [8:0]  e, d;
    reg [53:0] wide;
    reg [26:0] xa, ya;
    reg [27:0] sum;

    always @* begin
        wide = 54'd0;
        swap = b[30:0] > a[30:0];
        sx = swap ? b[31] : a[31];
        sy = swap ? a[31] : b[31];
        ex = swap ? b[30:23] : a[30:23];
        ey = swap ? a[30:23] : b[30:23];
        fx = swap ? b[22:0] : a[22:0];
        fy = swap ? a[22:0] : b[22:0];
        mx = {ex != 8'd0, fx};
        my = {ey != 8'd0, fy};
        e = (ex == 8'd0) ? 9'd1 : {1'b0, ex};
        d = e - ((ey == 8'd0) ? 9'd1 : {1'b0, ey});
        sub = sx ^ sy;

        // Align y: three extra bits, the last one sticky.
        xa = {mx, 3'b000};
        if (d > 9'd30) begin
            ya = {26'd0, |my};
        end else begin
            wide = {my, 3'b000, 27'd0} >> d;
            ya = {wide[53:28], wide[27] | (|wide[26:0])};
        end
        sum = sub ? ({1'b0, xa} - {1'b0, ya}) : ({1'b0, xa} + {1'b0, ya});

        // Non-finite inputs: a NaN or inf - inf is NaN; else an infinity is x's.
        nan = (ex == 8'hff && fx != 0) || (ey == 8'hff && fy != 0) || (ey == 8'hff && sub);
        inf = ex == 8'hff;
    end
    assign p = {nan, inf, sx, sy, e, sum};
endmodule

module bpx_fadd_round (
    input  wire [`BPX_FADD_PW-1:0] p,
    output reg  [31:0]             s,
    output reg                     overflow
);
    wire       nan = p[40], inf = p[39], sx = p[38], sy = p[37];
    reg        up, zero;
    reg [31:0] x;
    reg [8:0]  e, shift;
    reg [27:0] sum;
    reg [4:0]  lz;
    reg [30:0] mag;

    always @* begin
        lz = 5'd0;
        x = 32'd0;
        shift = 9'd0;
        e = p[36:28];
        sum = p[27:0];
        zero = sum == 28'd0;

        // Normalise.
        if (sum[27]) begin
            sum = {1'b0, sum[27:2], sum[1] | sum[0]};
            e = e + 9'd1;
        end else begin
            // Leading zeros of sum[26:0] by halving (five levels, not a 27-step chain).
            x = {sum[26:0], 5'b11111};
            lz[4] = x[31:16] == 0;
            if (lz[4]) x = x << 16;
            lz[3] = x[31:24] == 0;
            if (lz[3]) x = x << 8;
            lz[2] = x[31:28] == 0;
            if (lz[2]) x = x << 4;
            lz[1] = x[31:30] == 0;
            if (lz[1]) x = x << 2;
            lz[0] = !x[31];
            shift = ({4'd0, lz} < e - 9'd1) ? {4'd0, lz} : e - 9'd1;
            sum = sum << shift;
            e = e - shift;
        end

        // Round to nearest even: {exponent, fraction} + 1 carries into the exponent as needed
        // (subnormal -> normal, FLT_MAX -> infinity).
        up = sum[2] & (sum[1] | sum[0] | sum[3]);
        mag = {(sum[26] ? e[7:0] : 8'd0), sum[25:3]} + {30'd0, up};
        overflow = 1'b0;
        if (e >= 9'd255 || mag[30:23] == 8'hff) begin
            mag = {8'hff, 23'd0};
            overflow = 1'b1;
        end
        s = {zero ? (sx & sy) : sx, zero ? 31'd0 : mag};

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
    wire [`BPX_FADD_PW-1:0] p;
    bpx_fadd_align al (.a(a), .b(b), .p(p));
    bpx_fadd_round rn (.p(p), .s(s), .overflow(overflow));
endmodule
