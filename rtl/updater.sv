// bpx RTL: the updater (paper §4.2, Figure 2), mirroring src/hw/updater.h.
//
// One object per clock: an address counter requests the SSRAM word at `next`; the data comes
// back LAT clocks later through the interface's read pipeline; the add stage registers the box
// (general boxes: min x, y, z from banks 0-2, max x, y, z from banks 3-5); the clock after, the
// box is written into the comparator's six memories at that address. A pass over n objects
// takes n + LAT + 1 clocks.
module bpx_updater #(
    parameter integer AW = 11,
    parameter integer LAT = 2
) (
    input  wire            clk,
    input  wire            start,      // begin a pass over SSRAM addresses 0 .. n - 1
    input  wire [AW-1:0]   n,
    // SSRAM read port (through the interface) and the data arriving this clock.
    output wire            req,
    output wire [AW-1:0]   req_addr,
    input  wire            rd_valid,
    input  wire [AW-1:0]   rd_addr,
    input  wire [6*32-1:0] rd_data,    // banks 0-5
    // The comparator's write port.
    output wire            we,
    output wire [AW-1:0]   waddr,
    output wire [6*32-1:0] wdata,      // memory order: min x, max x, min y, max y, min z, max z
    output reg             active,
    output wire            active_d    // active after this clock edge
);
    localparam integer CW = $clog2(LAT + 2) + 1;  // reads in flight

    reg [AW-1:0]   next, last;
    reg [CW-1:0]   in_flight;
    reg            stage_valid;
    reg [AW-1:0]   stage_addr;
    reg [6*32-1:0] stage;

    wire issue = active && next < last;
    wire take = active && rd_valid;
    assign req = issue;
    assign req_addr = next;
    assign we = active && stage_valid;
    assign waddr = stage_addr;
    assign wdata = stage;

    // Banks 0-2 are the minima x, y, z and banks 3-5 the maxima; the memories interleave them.
    wire [6*32-1:0] box = {rd_data[5*32 +: 32], rd_data[2*32 +: 32],
                           rd_data[4*32 +: 32], rd_data[1*32 +: 32],
                           rd_data[3*32 +: 32], rd_data[0*32 +: 32]};

    wire [AW-1:0] next_n = next + issue;
    wire [CW-1:0] in_flight_n = in_flight + issue - take;
    assign active_d = start ? (n != 0) : (active && (next_n < last || in_flight_n != 0 || take));

    always @(posedge clk) begin
        if (start) begin
            next <= {AW{1'b0}};
            last <= n;
            in_flight <= {CW{1'b0}};
            stage_valid <= 1'b0;
            active <= n != 0;
        end else if (active) begin
            next <= next_n;
            in_flight <= in_flight_n;
            stage_valid <= take;
            if (take) begin
                stage_addr <= rd_addr;
                stage <= box;
            end
            active <= active_d;
        end
    end
endmodule
