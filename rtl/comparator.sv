// bpx RTL: the comparator (paper §4.3, Figures 3-4, Table 1), mirroring src/hw/comparator.h.
//
// Six 2M-width memories (min x, max x, min y, max y, min z, max z), each M dual-port block
// RAMs holding the same data, so each memory offers 2M read ports per clock. Port 0 reads the
// first address; port p >= 1 reads base + p - 1. Port 2r and port 2r + 1 are ports A and B of
// RAM r. The RAMs hold each float as an ordered integer key (-0 and +0 the same key), so the
// 2M - 1 comparison units compare unsigned integers; closed intervals (touching boxes collide).
//
// Four register stages, all held while `stall` is high (the clock enable is low):
//   stage 0: the address generator (a_*), presented to the RAMs this clock;
//   stage 1: the RAMs' read registers and the registered addresses (r_*);
//   stage 2: the RAMs' output registers (o_*): a block RAM's clock-to-output (5.8 ns on an
//            ECP5) leaves too little of a 108 MHz clock for six 32-bit compares after it;
//   stage 3: the comparison results (h_*), read by the emitter.
// The RAMs' read and output registers take their own copies of the stall, as clock enables
// (ram_en): one net to all of them was the longest path at 108 MHz on an ECP5 (docs/rtl.md).
// The first box's output registers (RAM 0, port A) are kept in M copies, one next to each RAM,
// for the units that read that RAM (f below): the same values, fewer loads per register.
// The updater writes one box (six words) into all M RAMs of each memory through port A.
module bpx_comparator #(
    parameter integer M = 4,
    parameter integer DEPTH = 512,
    parameter integer AW = 11,  // address-generator width: holds DEPTH - 1 + 2M - 1
    parameter integer IW = 9    // box index width: holds DEPTH - 1
) (
    input  wire              clk,
    input  wire              clear,     // empty the pipeline (start of a run)
    input  wire              stall,     // hold every register (a FIFO might overflow)
    input  wire [6*M-1:0]    ram_en,    // not stall, one copy per RAM (x * M + r)
    input  wire              start,     // start Table 1 on boxes 0 .. max (needs max >= 1)
    input  wire [AW-1:0]     start_max,
    // Write port, from the updater: one address in all M RAMs of the six memories.
    input  wire              we,
    input  wire [AW-1:0]     waddr,
    input  wire [6*32-1:0]   wdata,     // float bits, memory order (min x, max x, ...)
    output wire              busy,      // addresses to present or results not yet taken
    output wire              busy_d,    // busy after this clock edge
    // Stage 0, for the trace: the port addresses presented this clock.
    output wire              a_active,
    output wire [AW-1:0]     a_max,
    output wire [2*M*AW-1:0] ports,     // port p at [p*AW +: AW]
    // Stages 1 and 2 hold a result (the stall's lookahead, rtl/emitter.sv).
    output reg               r_valid,
    output reg               o_valid,
    // Stage 3: unit k found pair (h_i, h_j0 + k).
    output reg               h_valid,
    output reg  [IW-1:0]     h_i,
    output reg  [AW-1:0]     h_j0,
    output reg  [2*M-2:0]    h_mask
);
    localparam integer L = 2 * M - 1;  // comparison units
    localparam integer RW = (DEPTH > 1) ? $clog2(DEPTH) : 1;

    // A float as an ordered unsigned key: -0 -> +0; negatives bit-inverted, positives with the
    // sign bit set. (Non-finite values never reach the chip: the host rejects them.)
    function automatic [31:0] fkey(input [31:0] f);
        if (f == 32'h8000_0000)
            fkey = 32'h8000_0000;
        else if (f[31])
            fkey = ~f;
        else
            fkey = f | 32'h8000_0000;
    endfunction

    // ---- stage 0: the address generator (Table 1, diagonal: first_end = max) --------------
    reg          g_active;
    reg [AW-1:0] g_first, g_base, g_max;
    assign a_active = g_active;
    assign a_max = g_max;

    wire [AW-1:0] g_last = g_base + L[AW-1:0] - 1'b1;   // the last port's address
    wire          g_wrap = g_last >= g_max;             // a port reached the maximum address
    wire [AW-1:0] g_first1 = g_first + 1'b1;
    wire [AW-1:0] g_kept = (g_last <= g_max) ? L[AW-1:0] : (g_max - g_base + 1'b1);

    genvar gp;
    generate
        for (gp = 0; gp < 2 * M; gp = gp + 1) begin : port
            if (gp == 0) begin : first
                assign ports[0 +: AW] = g_first;
            end else begin : other
                assign ports[gp*AW +: AW] = g_base + gp - 1;
            end
        end
    endgenerate

    // ---- stages 1 and 2: registered addresses (the RAMs' registers are below) -------------
    reg [AW-1:0] r_first, r_base, r_kept;
    reg [AW-1:0] o_first, o_base, o_kept;

    wire en = !stall;
    always @(posedge clk) begin
        if (clear) begin
            g_active <= 1'b0;
            r_valid <= 1'b0;
            o_valid <= 1'b0;
            h_valid <= 1'b0;
        end else if (start) begin
            g_active <= 1'b1;
            g_first <= {AW{1'b0}};
            g_base <= {{(AW-1){1'b0}}, 1'b1};
            g_max <= start_max;
            r_valid <= 1'b0;
            o_valid <= 1'b0;
            h_valid <= 1'b0;
        end else if (en) begin
            // stage 0 -> next addresses
            if (g_active) begin
                if (g_wrap) begin
                    g_first <= g_first1;
                    if (g_first1 >= g_max)
                        g_active <= 1'b0;
                    else
                        g_base <= g_first1 + 1'b1;
                end else begin
                    g_base <= g_base + L[AW-1:0];
                end
            end
            // stage 0 -> stage 1
            r_valid <= g_active;
            if (g_active) begin
                r_first <= g_first;
                r_base <= g_base;
                r_kept <= g_kept;
            end
            // stage 1 -> stage 2
            o_valid <= r_valid;
            if (r_valid) begin
                o_first <= r_first;
                o_base <= r_base;
                o_kept <= r_kept;
            end
            // stage 2 -> stage 3
            h_valid <= o_valid;
            if (o_valid) begin
                h_i <= o_first[IW-1:0];
                h_j0 <= o_base;
                h_mask <= units;
            end
        end
    end

    wire g_active_n = stall ? g_active : (g_active && !(g_wrap && g_first1 >= g_max));
    wire r_valid_n = stall ? r_valid : g_active;
    wire o_valid_n = stall ? o_valid : r_valid;
    wire h_valid_n = stall ? h_valid : o_valid;
    assign busy = g_active | r_valid | o_valid | h_valid;
    assign busy_d = start | (!clear & (g_active_n | r_valid_n | o_valid_n | h_valid_n));

    // ---- the six memories: M dual-port RAMs each, same data -------------------------------
    // q[(x*M + r)*2 + side]: RAM r of memory x, port A (side 0) or B (side 1).
    // f[x*M + r]: the first box's word of memory x (RAM 0's port A) for the units that read
    // RAM r: RAM 0's output register for r = 0, else a copy of it next to RAM r, taken from
    // RAM 0's read register with RAM r's clock enable (the same value at the same clock). One
    // output register driving all 2M - 1 units was the longest path at 108 MHz on an ECP5
    // (docs/rtl.md, "What limits fmax", round 5).
    wire [31:0] q [0:6*M*2-1];
    wire [31:0] f [0:6*M-1];
    wire [31:0] q0 [0:5];       // RAM 0's read register (port A), per memory
    wire [31:0] wkey [0:5];
    genvar gx, gr;
    generate
        for (gx = 0; gx < 6; gx = gx + 1) begin : mem
            assign wkey[gx] = fkey(wdata[gx*32 +: 32]);
            for (gr = 0; gr < M; gr = gr + 1) begin : ram
                reg [31:0] word [0:DEPTH-1];
                reg [31:0] qa, qb, oa, ob;  // read registers, output registers
                wire [AW-1:0] ra = ports[(2*gr)*AW +: AW];
                wire [AW-1:0] rb = ports[(2*gr+1)*AW +: AW];
                wire [RW-1:0] adr_a = we ? waddr[RW-1:0] : ra[RW-1:0];
                wire [RW-1:0] adr_b = rb[RW-1:0];
                wire en_ram = ram_en[gx*M + gr];
                always @(posedge clk) begin
                    if (we)
                        word[adr_a] <= wkey[gx];
                    if (en_ram)
                        qa <= word[adr_a];
                end
                always @(posedge clk) begin
                    if (en_ram)
                        qb <= word[adr_b];
                end
                always @(posedge clk) begin
                    if (en_ram) begin
                        oa <= qa;
                        ob <= qb;
                    end
                end
                assign q[(gx*M + gr)*2 + 0] = oa;
                assign q[(gx*M + gr)*2 + 1] = ob;
                if (gr == 0) begin : first
                    assign q0[gx] = qa;
                    assign f[gx*M] = oa;
                end else begin : copy
                    (* keep *) reg [31:0] fo;
                    always @(posedge clk) begin
                        if (en_ram)
                            fo <= q0[gx];
                    end
                    assign f[gx*M + gr] = fo;
                end
            end
        end
    endgenerate

    // ---- stage 2 -> 3: the comparison units ------------------------------------------------
    // Unit k uses port k + 1: RAM (k + 1) / 2, side (k + 1) % 2; port 0 (RAM 0, A) is the
    // first box, its copy f next to RAM (k + 1) / 2. Six comparisons, ANDed; units k >= o_kept are discarded (index check).
    wire [L-1:0] units;
    genvar gk;
    generate
        for (gk = 0; gk < L; gk = gk + 1) begin : unit
            localparam integer R = (gk + 1) / 2;
            localparam integer S = (gk + 1) % 2;
            wire [31:0] fmin_x = f[0*M + R], fmax_x = f[1*M + R];
            wire [31:0] fmin_y = f[2*M + R], fmax_y = f[3*M + R];
            wire [31:0] fmin_z = f[4*M + R], fmax_z = f[5*M + R];
            wire [31:0] omin_x = q[(0*M + R)*2 + S], omax_x = q[(1*M + R)*2 + S];
            wire [31:0] omin_y = q[(2*M + R)*2 + S], omax_y = q[(3*M + R)*2 + S];
            wire [31:0] omin_z = q[(4*M + R)*2 + S], omax_z = q[(5*M + R)*2 + S];
            assign units[gk] = (fmax_x >= omin_x) & (fmin_x <= omax_x) &
                               (fmax_y >= omin_y) & (fmin_y <= omax_y) &
                               (fmax_z >= omin_z) & (fmin_z <= omax_z) &
                               (o_kept > gk);
        end
    endgenerate
endmodule
