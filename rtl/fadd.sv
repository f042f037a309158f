// placeholder, replaced below
module bpx_fadd (input wire [31:0] a, input wire [31:0] b, output wire [31:0] s, output wire overflow);
    assign s = 32'd0;
    assign overflow = 1'b0;
endmodule
