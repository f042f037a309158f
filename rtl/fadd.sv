// bpx RTL: IEEE-754 binary32 addition, combinational: round to nearest, ties to even;
// subnormal inputs and results exact (no flush to zero); the same bits as C's float + (SSE)
// for every finite pair (rtl/harness/fadd_test.cpp checks it). A finite sum beyond FLT_MAX
// rounds to infinity and raises `overflow`. Non-finite inputs (which the host never sends):
// infinities add as IEEE says, a NaN or inf - inf gives the quiet NaN 0x7fc00000.
//
// Method: the operand of larger magnitude is x; y's significand is aligned to it with three
// extra bits (guard, round, sticky: the OR of everything shifted out); the significands are
// added or subtracted; the result is normalised (right by one after a carry; left by its
// leading zeros, but not below the smallest exponent, which makes subnormals) and rounded.
module bpx_fadd (
    input  wire [31:0] a,
    input  wire [31:0] b,
    output reg  [31:0] s,
    output reg         overflow
);
    reg        swap, sx, sy, sub, up, zero;
    reg [7:0]  ex, ey;
    reg [22:0] fx, fy;
    reg [23:0] mx, my;
    reg [8:0]  e, d, shift;
    reg [53:0] wide;
    reg [26:0] xa, ya;
    reg [27:0] sum;
    reg [4:0]  lz;
    reg [30:0] mag;
    reg        found;
    integer    k;

    always @* begin
        wide = 54'd0;
        lz = 5'd0;
        found = 1'b0;
        shift = 9'd0;
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
        zero = sum == 28'd0;

        // Normalise.
        if (sum[27]) begin
            sum = {1'b0, sum[27:2], sum[1] | sum[0]};
            e = e + 9'd1;
        end else begin
            for (k = 26; k >= 0; k = k - 1)
                if (!found) begin
                    if (sum[k])
                        found = 1'b1;
                    else
                        lz = lz + 5'd1;
                end
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

        // Non-finite inputs.
        if (ex == 8'hff || ey == 8'hff) begin
            overflow = 1'b0;
            if ((ex == 8'hff && fx != 0) || (ey == 8'hff && fy != 0) || (ey == 8'hff && sub))
                s = 32'h7fc0_0000;
            else
                s = {sx, 8'hff, 23'd0};
        end
    end
endmodule
