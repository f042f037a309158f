// bpx RTL: the collision emitter (paper §4.4, Figure 5), mirroring src/hw/emitter.h.
//
// Each of the 2M - 1 comparison units owns two FIFOs, one for the i index and one for the j
// index of its hits (4M - 2 FIFOs), written and read together, so they share one pair of
// pointers. A registered comparator result writes every hit into its unit's FIFOs; the round
// robin serves the first non-empty FIFO pair at or after the one after the last served and moves
// its head into the output register (one collision per clock). A pair is never dropped: the
// comparator holds (`stall`, nothing of its result is written) while a FIFO might overflow.
//
// The stall is almost-full and takes effect two clocks after it is decided: `stall_next`, a
// register, is computed from registers only (the FIFOs' fill thresholds, the comparator's
// valid bits and result mask, the stall now and next), and the chip registers it again, once
// per comparator RAM, as `stall`. Deciding from this clock's registers whether a push two
// clocks on could find its FIFO full: lane k may then be pushed only if fill + the pushes of
// this clock and the next (p0, p1: at most one each) < FDEPTH. p0 is known; p1 is known when
// the comparator holds (its result stays), else bounded by the valid bit of the result coming
// (its mask needs the comparison units: the slow lookahead this replaced). While both stall
// registers are high, the result held is the one that will be pushed, so the stall is exact:
// the result meets a full FIFO. Any FDEPTH >= 1 works (small FIFOs stall more often).
//
// The served FIFO's block RAMs register its head (their read registers, plus the registered lane
// number that selects them); the output register takes the selected one a clock later: a block
// RAM's clock-to-output and a (2M - 1)-way select did not fit one 108 MHz clock on an ECP5.
// The model's emitter has the same two registers (src/hw/emitter.h). `nonempty` and `full` are
// registers (the model's committed bits), so the round robin and the stall start at flip-flops;
// full_n is `full` after this edge, for the chip's registered stall.
//
// The output register is a valid/ready stream's source: `ready` low while it holds a collision
// holds it and the read register and reads no FIFO (the FIFOs still take hits, and when a hit
// meets a full one the comparator stalls, as always): back-pressure never drops a pair.
module bpx_emitter #(
    parameter integer M = 4,
    parameter integer FDEPTH = 1024,  // entries per FIFO
    parameter integer AW = 11,
    parameter integer IW = 9,
    parameter integer TRACE = 1       // drive fill_max (the trace's fullest FIFO)
) (
    input  wire           clk,
    input  wire           clear,
    input  wire           stall,      // the comparator holds: write nothing this clock
    input  wire           r_valid,    // the comparator's stage 1 and 2 hold a result: the next
    input  wire           o_valid,    //   results' valid bits (h_valid two clocks on)
    input  wire           h_valid,
    input  wire [IW-1:0]  h_i,
    input  wire [AW-1:0]  h_j0,
    input  wire [2*M-2:0] h_mask,
    input  wire           ready,      // the collision port takes the output register this clock
    output wire           blocks,     // a hit of the registered result meets a full FIFO
                                      // (never while not stalled: the formal proof's check)
    output reg            stall_next, // the stall a clock on (the chip registers it as `stall`)
    output reg            out_valid,
    output reg  [IW-1:0]  out_i,
    output reg  [IW-1:0]  out_j,
    output wire           busy,       // FIFOs or output register hold collisions
    output wire           busy_d,     // busy after this clock edge
    output reg  [31:0]    fill_max
);
    localparam integer L = 2 * M - 1;
    localparam integer FW = $clog2(FDEPTH + 1);           // fill counter
    localparam integer PW = (FDEPTH > 1) ? $clog2(FDEPTH) : 1; // FIFO address
    localparam integer LW = (L > 1) ? $clog2(L) : 1;      // lane number

    reg  [FW-1:0] fill [0:L-1];
    reg  [PW-1:0] head [0:L-1];
    (* fsm_encoding = "none" *) reg [LW-1:0] next_lane; // a counter, not an FSM for Yosys
    (* fsm_encoding = "none" *) reg [LW-1:0] f_sel;     // likewise: as an FSM it took 2/3 of
                                                         // the LUTs at M = 8 (docs/rtl.md)
    reg           f_valid;                               // the FIFO read registers hold a pair
    wire [L-1:0]  nonempty, full;
    wire [L-1:0]  push = (!stall && h_valid) ? h_mask : {L{1'b0}};

    function automatic at_least(input [FW-1:0] f, input integer t);
        at_least = (t <= 0) ? 1'b1 : (f >= t);
    endfunction

    // The output pipeline moves unless a collision waits in the output register for `ready`.
    wire         advance = !out_valid || ready;
    // Round robin: the first non-empty lane at or after next_lane, else the first non-empty.
    reg          pop_valid;
    reg [LW-1:0] pop, pick_hi, pick_lo;
    reg          any_hi;
    integer k;
    always @* begin
        k = 0;  // the loop index is a variable too: assigned on every path, no latch
        any_hi = 1'b0;
        pick_hi = {LW{1'b0}};
        pick_lo = {LW{1'b0}};
        for (k = L - 1; k >= 0; k = k - 1) begin
            if (nonempty[k]) begin
                pick_lo = k[LW-1:0];
                if (k >= next_lane) begin
                    pick_hi = k[LW-1:0];
                    any_hi = 1'b1;
                end
            end
        end
        pop_valid = advance && |nonempty;
        pop = any_hi ? pick_hi : pick_lo;
    end

    assign blocks = h_valid && |(h_mask & full);

    // The almost-full stall (see the top). s0 = stall (now), s1 = stall_next (the next clock).
    wire hv1 = stall ? h_valid : o_valid;                    // h_valid a clock on
    wire hv2 = stall_next ? hv1 : (stall ? o_valid : r_valid); // two clocks on
    wire [L-1:0] p0 = push;
    wire [L-1:0] p1 = (!stall_next && hv1) ? (stall ? h_mask : {L{1'b1}}) : {L{1'b0}};
    wire [L-1:0] m2 = (stall && stall_next) ? h_mask : {L{1'b1}}; // lanes hit two clocks on
    wire [L-1:0] over = m2 & (full | (ge1 & (p0 | p1)) | (ge2 & p0 & p1));
    initial stall_next = 1'b0;
    always @(posedge clk)
        stall_next <= !clear && hv2 && |over;

    // Fill thresholds (registers): ge0 fill >= FDEPTH (full), ge1 >= FDEPTH - 1, ge2 >= FDEPTH - 2.
    wire [L-1:0] nonempty_n, full_n, ge1, ge2;
    wire [IW-1:0] q_i [0:L-1];
    wire [IW-1:0] q_j [0:L-1];
    genvar g;
    generate
        for (g = 0; g < L; g = g + 1) begin : lane
            reg [IW-1:0] fifo_i [0:FDEPTH-1];
            reg [IW-1:0] fifo_j [0:FDEPTH-1];
            reg [IW-1:0] qi, qj;
            reg ne_r, full_r, ge1_r, ge2_r;
            assign nonempty[g] = ne_r;
            assign full[g] = full_r;
            assign ge1[g] = ge1_r;
            assign ge2[g] = ge2_r;
            wire popped = pop_valid && pop == g;
            reg [PW-1:0] tail;  // head + fill, wrapped: a register, not an adder on the path
            wire [IW-1:0] j = h_j0[IW-1:0] + g;
            wire [FW-1:0] fill_n = fill[g] + push[g] - popped;
            // The next non-empty and full bits from this clock's bits, not from fill_n's adder.
            wire one = fill[g] == 1, almost = fill[g] == FDEPTH - 1;
            assign nonempty_n[g] = !clear && (push[g] || (nonempty[g] && !(popped && one)));
            assign full_n[g] = !clear && !popped && (full[g] || (push[g] && almost));
            // fill_n >= T from the registered fill's compares with constants (no adder); a clear
            // empties the FIFO (fill 0 >= T for a FIFO of 1 or 2 entries).
            wire up = push[g] && !popped, down = popped && !push[g];
            wire ge1_n = clear ? FDEPTH <= 1 :
                         up ? at_least(fill[g], FDEPTH - 2) :
                         down ? at_least(fill[g], FDEPTH) : at_least(fill[g], FDEPTH - 1);
            wire ge2_n = clear ? FDEPTH <= 2 :
                         up ? at_least(fill[g], FDEPTH - 3) :
                         down ? at_least(fill[g], FDEPTH - 1) : at_least(fill[g], FDEPTH - 2);
            always @(posedge clk) begin
                if (push[g]) begin
                    fifo_i[tail] <= h_i;
                    fifo_j[tail] <= j;
                end
                if (popped) begin
                    qi <= fifo_i[head[g]];
                    qj <= fifo_j[head[g]];
                end
            end
            always @(posedge clk) begin
                ne_r <= nonempty_n[g];
                full_r <= full_n[g];
                ge1_r <= ge1_n;
                ge2_r <= ge2_n;
                if (clear) begin
                    fill[g] <= {FW{1'b0}};
                    head[g] <= {PW{1'b0}};
                    tail <= {PW{1'b0}};
                end else begin
                    fill[g] <= fill_n;
                    if (push[g])
                        tail <= (tail == FDEPTH - 1) ? {PW{1'b0}} : tail + 1'b1;
                    if (popped)
                        head[g] <= (head[g] == FDEPTH - 1) ? {PW{1'b0}} : head[g] + 1'b1;
                end
            end
            assign q_i[g] = qi;
            assign q_j[g] = qj;
        end
    endgenerate

    always @(posedge clk) begin
        if (clear) begin
            f_valid <= 1'b0;
            out_valid <= 1'b0;
            next_lane <= {LW{1'b0}};
        end else if (advance) begin
            f_valid <= pop_valid;
            if (pop_valid) begin
                f_sel <= pop;
                next_lane <= (pop == L - 1) ? {LW{1'b0}} : pop + 1'b1;
            end
            out_valid <= f_valid;
            if (f_valid) begin
                out_i <= q_i[f_sel];
                out_j <= q_j[f_sel];
            end
        end
    end
    assign busy = |nonempty || f_valid || out_valid;
    // Held (not advancing), the output register still holds its collision.
    assign busy_d = !clear && (|nonempty_n || pop_valid || f_valid || !advance);

    // The fullest FIFO now (trace only).
    generate
        if (TRACE) begin : trace
            integer t;
            always @* begin
                t = 0;
                fill_max = 32'd0;
                for (t = 0; t < L; t = t + 1)
                    if (fill[t] > fill_max)
                        fill_max = fill[t];
            end
        end else begin : notrace
            always @* fill_max = 32'd0;
        end
    endgenerate
endmodule
