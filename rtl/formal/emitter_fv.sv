// Formal wrapper: the emitter neither drops nor duplicates a hit (docs/rtl.md, "Formal proofs").
//
// The solver drives the comparator's stage-3 register (valid, i, j0, mask: any values). As in
// the chip, the register holds while `stall` is high, the emitter's stall_next registered
// again; the comparator's stages 1 and 2 are taken as always valid (any result may come next,
// which is what the emitter's lookahead has to allow for). A watched payload (wi, wj) is chosen by the solver (anyconst) and assumed to arrive
// at most once (the comparator presents each pair once: comparator_fv); since it can be any
// payload, any lane and any clock, the checks below hold for every hit:
//   - it comes out at most once, and never if it never came in;
//   - it comes out within BOUND clocks of its write (FDEPTH entries of its lane, the round
//     robin serving that lane at least once every L clocks, one clock each for the FIFO's read
//     register and the output register);
//   - nothing comes out before something went in;
//   - no hit is written into a full FIFO (the almost-full stall came in time);
//   - a stall lasts at most L + 2 clocks (the full lane is served within L clocks and the
//     stall ends two clocks after it is released: no deadlock).
// A FIFO that overwrote or lost an entry would drop the watched hit when it is that entry.
module emitter_fv #(
    parameter integer M = 2,
    parameter integer FDEPTH = 2
) (
    input wire clk
);
    localparam integer L = 2 * M - 1;
    localparam integer AW = 2;  // narrow indices: the emitter only stores and moves them
    localparam integer IW = 2;
    // A hit waits for the FDEPTH - 1 ahead of it in its lane and for itself, each pop of its lane
    // at most L clocks after the previous one; if its lane was empty, the round robin may have
    // just passed it (L + 1). One more clock for the FIFO's read register is included in both;
    // the output register after it adds one.
    localparam integer BOUND = ((FDEPTH * L > L + 1) ? FDEPTH * L : L + 1) + 1;

    reg init = 1'b1;  // the first clock clears the emitter, as a run's start does
    always @(posedge clk) init <= 1'b0;

    (* anyseq *) wire          n_valid;
    (* anyseq *) wire [IW-1:0] n_i;
    (* anyseq *) wire [AW-1:0] n_j0;
    (* anyseq *) wire [L-1:0]  n_mask;
    (* anyconst *) wire [IW-1:0] wi, wj;

    // The comparator's stage 3: takes a new result only when not stalled.
    reg          h_valid = 1'b0;
    reg [IW-1:0] h_i;
    reg [AW-1:0] h_j0;
    reg [L-1:0]  h_mask;
    wire blocks, stall_next, out_valid, busy, busy_d;
    reg stall = 1'b0;  // as the chip registers it
    always @(posedge clk) stall <= stall_next;
    wire [IW-1:0] out_i, out_j;
    wire [31:0] fill_max;
    always @(posedge clk) begin
        if (init) begin
            h_valid <= 1'b0;  // a run's start clears the comparator too
        end else if (!stall) begin
            h_valid <= n_valid;
            h_i <= n_i;
            h_j0 <= n_j0;
            h_mask <= n_mask;
        end
    end

    bpx_emitter #(.M(M), .FDEPTH(FDEPTH), .AW(AW), .IW(IW), .TRACE(0)) dut (
        .clk(clk), .clear(init), .stall(stall), .r_valid(1'b1), .o_valid(1'b1),
        .h_valid(h_valid), .h_i(h_i), .h_j0(h_j0), .h_mask(h_mask), .ready(1'b1),
        .blocks(blocks), .stall_next(stall_next), .out_valid(out_valid), .out_i(out_i), .out_j(out_j),
        .busy(busy), .busy_d(busy_d), .fill_max(fill_max));

`ifdef FORMAL
    // What the emitter writes this clock: every hit of a result it does not block.
    wire [L-1:0] push = (!init && h_valid && !stall) ? h_mask : {L{1'b0}};
    wire [L-1:0] push_w;  // the watched payload written by lane g
    genvar g;
    generate
        for (g = 0; g < L; g = g + 1) begin : lane
            wire [IW-1:0] j = h_j0[IW-1:0] + g;
            assign push_w[g] = push[g] && h_i == wi && j == wj;
        end
    endgenerate

    function automatic [3:0] ones(input [L-1:0] v);
        integer k;
        begin
            ones = 0;
            for (k = 0; k < L; k = k + 1)
                ones = ones + v[k];
        end
    endfunction

    wire out_v = !init && out_valid;  // before the clear, the output register is unknown
    wire out_w = out_v && out_i == wi && out_j == wj;
    reg [1:0] in_w = 0, out_w_n = 0;  // watched payload: times in, times out
    reg [7:0] n_in = 0;               // all hits in
    reg [7:0] since = 0;              // clocks since the watched write
    reg [3:0] blocked = 0;            // consecutive stalled clocks
    always @(posedge clk) begin
        in_w <= in_w + ones(push_w);
        out_w_n <= out_w_n + out_w;
        n_in <= n_in + ones(push);
        if (|push_w)
            since <= 1;
        else if (in_w != 0 && since != 8'hff)
            since <= since + 1'b1;
        blocked <= (!init && stall) ? blocked + 1'b1 : 4'd0;
    end

    // The comparator presents a pair once: the watched payload arrives at most once.
    always @* assume(in_w + ones(push_w) <= 1);

    always @(posedge clk) begin
        if (!init) begin
            assert(out_w_n <= in_w);                     // no duplicate, nothing invented
            if (in_w == 1 && since > BOUND)
                assert(out_w_n == 1);                    // no drop, within BOUND
            if (n_in == 0)
                assert(!out_v && !busy);
            assert(!(blocks && !stall));                 // no write into a full FIFO
            assert(blocked <= L + 2);                    // every stall ends
        end
    end

    // Reachability (sby cover tasks): a stall, and the watched hit out at the bound itself.
    always @(posedge clk) begin
        if (!init) begin
            cover(stall && blocks);
            cover(out_w && since == BOUND);                 // the bound is tight
        end
    end
`endif
endmodule
