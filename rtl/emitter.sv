// bpx RTL: the collision emitter (paper §4.4, Figure 5), mirroring src/hw/emitter.h.
//
// Each of the 2M - 1 comparison units owns two FIFOs, one for the i index and one for the j
// index of its hits (4M - 2 FIFOs), written and read together, so they share one pair of
// pointers. A registered comparator result writes every hit into its unit's FIFOs; the round
// robin serves the first non-empty FIFO pair at or after the one after the last served and moves
// its head into the output register (one collision per clock). When a result has a hit for a
// full FIFO, `blocks` is high: the comparator holds (nothing of that result is written) until
// that FIFO has room. A pair is never dropped.
//
// The output register is the read register of the served FIFO's block RAMs plus the registered
// lane number that selects it: the same value the model's output register holds.
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
    input  wire           h_valid,
    input  wire [IW-1:0]  h_i,
    input  wire [AW-1:0]  h_j0,
    input  wire [2*M-2:0] h_mask,
    output wire           blocks,     // a hit of the registered result meets a full FIFO
    output reg            out_valid,
    output wire [IW-1:0]  out_i,
    output wire [IW-1:0]  out_j,
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
    (* fsm_encoding = "none" *) reg [LW-1:0] out_sel;   // likewise: as an FSM it took 2/3 of
                                                         // the LUTs at M = 8 (docs/rtl.md)
    wire [L-1:0]  nonempty, full;
    wire [L-1:0]  push = (!stall && h_valid) ? h_mask : {L{1'b0}};

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
        pop_valid = |nonempty;
        pop = any_hi ? pick_hi : pick_lo;
    end

    assign blocks = h_valid && |(h_mask & full);

    wire [L-1:0] nonempty_n;
    wire [IW-1:0] q_i [0:L-1];
    wire [IW-1:0] q_j [0:L-1];
    genvar g;
    generate
        for (g = 0; g < L; g = g + 1) begin : lane
            reg [IW-1:0] fifo_i [0:FDEPTH-1];
            reg [IW-1:0] fifo_j [0:FDEPTH-1];
            reg [IW-1:0] qi, qj;
            wire popped = pop_valid && pop == g;
            wire [FW:0] sum = {1'b0, fill[g]} + head[g];
            wire [PW-1:0] tail = (sum >= FDEPTH) ? (sum - FDEPTH) : sum[PW-1:0];
            wire [IW-1:0] j = h_j0[IW-1:0] + g;
            wire [FW-1:0] fill_n = fill[g] + push[g] - popped;
            assign nonempty[g] = fill[g] != 0;
            assign full[g] = fill[g] == FDEPTH;
            assign nonempty_n[g] = clear ? 1'b0 : (fill_n != 0);
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
                if (clear) begin
                    fill[g] <= {FW{1'b0}};
                    head[g] <= {PW{1'b0}};
                end else begin
                    fill[g] <= fill_n;
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
            out_valid <= 1'b0;
            next_lane <= {LW{1'b0}};
        end else begin
            out_valid <= pop_valid;
            if (pop_valid) begin
                out_sel <= pop;
                next_lane <= (pop == L - 1) ? {LW{1'b0}} : pop + 1'b1;
            end
        end
    end
    assign out_i = q_i[out_sel];
    assign out_j = q_j[out_sel];
    assign busy = |nonempty || out_valid;
    assign busy_d = !clear && (|nonempty_n || pop_valid);

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
