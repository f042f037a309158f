// bpx RTL: the chip, mirroring src/hw/model.c (the machine and its controller).
//
// Units: interface (registers, SSRAM read pipeline, collision write port), updater,
// comparator, emitter. A run, all boxes on chip: the host writes object i at SSRAM address i,
// writes N, then CONTROL = 1 | mode << 1:
//   mode 0, general boxes (bpx_model_run_boxes): min x, y, z in banks 0-2, max in banks 3-5;
//   mode 1, initialisation (bpx_model_load_extents): the minima x, y, z in banks 0-2; the run
//           is one INIT phase (the updater fills its minima RAM), then IDLE;
//   mode 2, updating (bpx_model_run_centres): the centres x, y, z in banks 0-2.
// Phases, as the model's controller runs them, with no idle clock between them:
//   UPDATE  while the updater's pass is active (INIT in mode 1);
//   COMPARE (n >= 2) from the clock after the pass's last write, while the comparator's
//           pipeline holds work (stall clocks included);
//   DRAIN   while the emitter's FIFOs or output register hold collisions;
//   then IDLE: STATUS.done; COUNT collisions were written to the collision port.
// n = 0 takes no clock; n > DEPTH sets STATUS.error and takes no clock. A centre +/- minimum
// beyond FLT_MAX sets STATUS.overflow (the run goes on; the host's check rejects such input
// before the model runs). Mode 2 after a mode-1 run with another n is the host's error, as in
// the model (BAD_STATE there); the chip does not check it.
module bpx_chip #(
    parameter integer M = 4,
    parameter integer DEPTH = 512,
    parameter integer FDEPTH = 1024,
    parameter integer LAT = 2,
    parameter integer TRACE = 1,
    parameter integer AW = $clog2(DEPTH + 2 * M) + 1,
    parameter integer IW = (DEPTH > 1) ? $clog2(DEPTH) : 1
) (
    input  wire            clk,
    // Host registers.
    input  wire            reg_we,
    input  wire [1:0]      reg_addr,
    input  wire [31:0]     reg_wdata,
    output wire [31:0]     reg_rdata,
    // The board's SSRAM (six banks, one address): read data arrives LAT clocks after the address.
    output wire            ssram_re,
    output wire [AW-1:0]   ssram_addr,
    input  wire [6*32-1:0] ssram_rdata,
    // Collision output: a valid/ready stream (col_we valid; a pair is taken, written at col_addr
    // = COUNT, on a clock with col_ready) into the board's collision SSRAM.
    input  wire            col_ready,
    output wire            col_we,
    output wire [31:0]     col_addr,
    output wire [IW-1:0]   col_i,
    output wire [IW-1:0]   col_j,
    // Trace (what bpx_model_clock reports), for the lockstep harness.
    output reg  [2:0]      phase,
    output wire            t_addressing,
    output wire [2*M*AW-1:0] t_ports,
    output wire [AW-1:0]   t_max,
    output wire            t_hits_valid,
    output wire [2*M-2:0]  t_hits,
    output wire [IW-1:0]   t_hit_row,
    output wire            t_stalled,
    output wire            t_emitted,
    output wire [IW-1:0]   t_pair_i,
    output wire [IW-1:0]   t_pair_j,
    output wire [31:0]     t_fill_max,
    output wire [31:0]     t_count
);
    localparam [2:0] PH_INIT = 3'd0, PH_UPDATE = 3'd1, PH_COMPARE = 3'd2, PH_DRAIN = 3'd3,
                     PH_IDLE = 3'd7;

    wire [31:0] n;
    wire start_reg;
    wire [1:0] mode;
    reg  error, overflow;
    wire upd_overflow;
    wire [AW-1:0] rd_addr_next;
    wire too_many = n > DEPTH;
    wire run = start_reg && phase == PH_IDLE;   // a start while running is ignored
    wire go = run && !too_many;
    wire clear = run;
    wire [AW-1:0] n_a = n[AW-1:0];

    // Updater.
    wire upd_req, upd_active, upd_active_d, upd_we, rd_valid;
    wire [AW-1:0] upd_req_addr, upd_waddr, rd_addr;
    wire [6*32-1:0] upd_wdata;
    // Comparator.
    wire cmp_busy, cmp_busy_d, cmp_start;
    wire r_valid, o_valid, h_valid;
    wire [IW-1:0] h_i;
    wire [AW-1:0] h_j0;
    wire [2*M-2:0] h_mask;
    // Emitter.
    wire out_valid, emi_busy, emi_busy_d;
    // The stall (hold every comparator register and RAM, write no hit: a FIFO might overflow)
    // is the emitter's almost-full stall_next registered again: once for the comparator's
    // control and the emitter (`stall`) and once per comparator RAM, there as its clock enable
    // (ram_en = not stalled, so no inverter between it and the RAM). All copies are equal; the
    // RAMs' are kept apart from Yosys's merging: merged, one net to every RAM's clock enable was
    // the longest path on an ECP5 (docs/rtl.md). No clear: a run starts only when the
    // comparator is idle, and then stall_next is low.
    reg stall;
    initial stall = 1'b0;
    wire stall_next;
    wire [6*M-1:0] ram_en;
    genvar gs;
    generate
        for (gs = 0; gs < 6 * M; gs = gs + 1) begin : hold
            reg en = 1'b1;
            (* keep *) always @(posedge clk)  // keep: on the always, so the flip-flop has it
                en <= !stall_next;
            assign ram_en[gs] = en;
        end
    endgenerate
    always @(posedge clk)
        stall <= stall_next;
    wire [IW-1:0] out_i, out_j;
    wire [31:0] count;

    bpx_interface #(.DEPTH(DEPTH), .AW(AW), .IW(IW), .LAT(LAT)) ifc (
        .clk(clk), .clear(clear),
        .reg_we(reg_we), .reg_addr(reg_addr), .reg_wdata(reg_wdata), .reg_rdata(reg_rdata),
        .n(n), .start(start_reg), .mode(mode), .done(phase == PH_IDLE), .error(error),
        .overflow(overflow), .rd_addr_next(rd_addr_next),
        .req(upd_req), .req_addr(upd_req_addr), .ssram_re(ssram_re), .ssram_addr(ssram_addr),
        .rd_valid(rd_valid), .rd_addr(rd_addr),
        .out_valid(out_valid), .out_i(out_i), .out_j(out_j), .col_ready(col_ready),
        .col_we(col_we), .col_addr(col_addr), .col_i(col_i), .col_j(col_j), .count(count));

    bpx_updater #(.DEPTH(DEPTH), .AW(AW), .LAT(LAT)) upd (
        .clk(clk), .start(go), .mode_in(mode), .n(n_a), .rd_addr_next(rd_addr_next),
        .overflow(upd_overflow),
        .req(upd_req), .req_addr(upd_req_addr),
        .rd_valid(rd_valid), .rd_addr(rd_addr), .rd_data(ssram_rdata),
        .we(upd_we), .waddr(upd_waddr), .wdata(upd_wdata),
        .active(upd_active), .active_d(upd_active_d));

    bpx_comparator #(.M(M), .DEPTH(DEPTH), .AW(AW), .IW(IW)) cmp (
        .clk(clk), .clear(clear), .stall(stall), .ram_en(ram_en), .start(cmp_start), .start_max(n_a - 1'b1),
        .we(upd_we), .waddr(upd_waddr), .wdata(upd_wdata),
        .busy(cmp_busy), .busy_d(cmp_busy_d),
        .a_active(t_addressing), .a_max(t_max), .ports(t_ports),
        .r_valid(r_valid), .o_valid(o_valid),
        .h_valid(h_valid), .h_i(h_i), .h_j0(h_j0), .h_mask(h_mask));

    bpx_emitter #(.M(M), .FDEPTH(FDEPTH), .AW(AW), .IW(IW), .TRACE(TRACE)) emi (
        .clk(clk), .clear(clear), .stall(stall), .r_valid(r_valid), .o_valid(o_valid),
        .h_valid(h_valid), .h_i(h_i), .h_j0(h_j0), .h_mask(h_mask), .ready(col_ready),
        .blocks(), .stall_next(stall_next), .out_valid(out_valid), .out_i(out_i), .out_j(out_j),
        .busy(emi_busy), .busy_d(emi_busy_d), .fill_max(t_fill_max));

    // The controller: the next clock's phase from the units' state after this edge.
    wire update_ends = phase == PH_UPDATE && !upd_active_d;
    assign cmp_start = update_ends && n_a >= 2;
    always @(posedge clk) begin
        if (run) begin
            error <= too_many;
            overflow <= 1'b0;
            phase <= (too_many || n == 0) ? PH_IDLE : mode == 2'd1 ? PH_INIT : PH_UPDATE;
        end else begin
            overflow <= overflow | upd_overflow;
            case (phase)
                PH_INIT:
                    if (!upd_active_d)
                        phase <= PH_IDLE;
                PH_UPDATE:
                    if (!upd_active_d)
                        phase <= cmp_start ? PH_COMPARE : emi_busy_d ? PH_DRAIN : PH_IDLE;
                PH_COMPARE:
                    if (!cmp_busy_d)
                        phase <= emi_busy_d ? PH_DRAIN : PH_IDLE;
                PH_DRAIN:
                    if (!emi_busy_d)
                        phase <= PH_IDLE;
                default: ;
            endcase
        end
    end
    initial phase = PH_IDLE;
    initial error = 1'b0;
    initial overflow = 1'b0;

    assign t_hits_valid = h_valid;
    assign t_hits = h_mask;
    assign t_hit_row = h_i;
    assign t_stalled = stall;
    assign t_emitted = out_valid;
    assign t_pair_i = out_i;
    assign t_pair_j = out_j;
    assign t_count = count;
endmodule
