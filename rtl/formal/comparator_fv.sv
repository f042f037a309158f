// Formal wrapper: the comparator presents each pair exactly once (docs/rtl.md, "Formal proofs").
//
// Clock 0 clears; clocks 1 .. DEPTH write every box through the updater's port; the next clock
// starts Table 1 on n boxes (the solver picks 2 <= n <= DEPTH). Boxes a and b (the solver picks
// a < b < n and their twelve floats) are arbitrary; every other box spans all floats, so it
// overlaps anything. The stall is arbitrary (the emitter's back-pressure, any pattern). A
// result is taken by the emitter on a clock with h_valid and no stall; unit k's pair is then
// (h_i, h_j0 + k). Checked:
//   - every pair taken has i < j < n (the index check discards the rest);
//   - (a, b) is taken at most once, and, once the pass is over, exactly once if the boxes
//     overlap (closed intervals, on the ordered keys) and never if not;
//   - the pass takes exactly P + 3 clocks without a stall, P = sum over rows r = 1 .. n - 1 of
//     ceil(r / L) (Table 1; the three: RAM read, RAM output and result registers), then the
//     comparator is idle.
module comparator_fv #(
    parameter integer M = 1,
    parameter integer DEPTH = 4
) (
    input wire clk
);
    localparam integer L = 2 * M - 1;
    localparam integer AW = $clog2(DEPTH + 2 * M) + 1;  // as bpx_chip sets them
    localparam integer IW = (DEPTH > 1) ? $clog2(DEPTH) : 1;
    localparam [31:0] ALL_MIN = 32'hffff_ffff, ALL_MAX = 32'h7fff_ffff;  // smallest, largest key

    (* anyconst *) wire [AW-1:0] n, a, b;
    (* anyconst *) wire [6*32-1:0] box_a, box_b;
    (* anyseq *) wire stall_in;

    reg [7:0] t = 0;  // clocks since the first
    always @(posedge clk) if (t != 8'hff) t <= t + 1'b1;
    wire clear = t == 0;
    wire we = t >= 1 && t <= DEPTH;
    wire [AW-1:0] waddr = t - 1;
    wire start = t == DEPTH + 1;
    wire running = t > DEPTH + 1;
    wire stall = running && stall_in;
    wire [6*32-1:0] box_all = {ALL_MAX, ALL_MIN, ALL_MAX, ALL_MIN, ALL_MAX, ALL_MIN};
    wire [6*32-1:0] wdata = waddr == a ? box_a : waddr == b ? box_b : box_all;

    wire busy, busy_d, a_active;
    wire [AW-1:0] a_max;
    wire [2*M*AW-1:0] ports;
    wire h_valid;
    wire [IW-1:0] h_i;
    wire [AW-1:0] h_j0;
    wire [L-1:0] h_mask;

    bpx_comparator #(.M(M), .DEPTH(DEPTH), .AW(AW), .IW(IW)) dut (
        .clk(clk), .clear(clear), .stall(stall), .ram_en({6*M{!stall}}), .start(start), .start_max(n - 1'b1),
        .we(we), .waddr(waddr), .wdata(wdata), .busy(busy), .busy_d(busy_d),
        .a_active(a_active), .a_max(a_max), .ports(ports),
        .h_valid(h_valid), .h_i(h_i), .h_j0(h_j0), .h_mask(h_mask));

`ifdef FORMAL
    always @* begin
        assume(n >= 2 && n <= DEPTH);
        assume(a < b && b < n);
    end

    function automatic [31:0] fkey(input [31:0] f);  // the comparator's ordered key
        if (f == 32'h8000_0000)
            fkey = 32'h8000_0000;
        else if (f[31])
            fkey = ~f;
        else
            fkey = f | 32'h8000_0000;
    endfunction

    // Boxes a and b overlap on all three axes (fields: min x, max x, min y, max y, ...).
    reg overlap;
    integer x;
    always @* begin
        overlap = 1'b1;
        for (x = 0; x < 3; x = x + 1)
            if (fkey(box_a[(2*x+1)*32 +: 32]) < fkey(box_b[(2*x)*32 +: 32]) ||
                fkey(box_b[(2*x+1)*32 +: 32]) < fkey(box_a[(2*x)*32 +: 32]))
                overlap = 1'b0;
    end

    // Table 1's clocks for n boxes: row r (the r pairs of box n - 1 - r) in ceil(r / L).
    reg [15:0] pass;
    integer r;
    always @* begin
        pass = 0;
        for (r = 1; r < DEPTH; r = r + 1)
            if (r < n)
                pass = pass + (r + L - 1) / L;
    end

    wire taken = running && h_valid && !stall;
    reg [1:0] seen = 0;   // times (a, b) was taken
    reg [15:0] ran = 0;   // clocks without a stall since the start
    reg bad;              // a pair taken with i >= j or j >= n
    reg [1:0] ab;         // (a, b) among this clock's pairs
    integer k;
    always @* begin
        bad = 1'b0;
        ab = 0;
        for (k = 0; k < L; k = k + 1)
            if (taken && h_mask[k]) begin
                if ({{(AW-IW){1'b0}}, h_i} >= h_j0 + k || h_j0 + k >= n)
                    bad = 1'b1;
                if ({{(AW-IW){1'b0}}, h_i} == a && h_j0 + k == b)
                    ab = ab + 1'b1;
            end
    end
    always @(posedge clk) begin
        seen <= seen + ab;
        if (running && !stall)
            ran <= ran + 1'b1;
    end

    always @(posedge clk) begin
        if (running) begin
            assert(!bad);
            assert(seen + ab <= 1);
            assert(busy == (ran < pass + 3));   // the pass's length, then idle
            if (ran >= pass + 3)
                assert(seen == overlap);
        end
    end

    always @(posedge clk) begin
        if (running) begin
            cover(ran == pass + 3 && seen == 1 && n == DEPTH && b == n - 1);
            cover(stall && h_valid);
        end
    end
`endif
endmodule
