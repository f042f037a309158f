#!/bin/sh
# Yosys synthesis of the chip (rtl/bpx_chip.sv, trace logic off) for the paper's Virtex-II
# (synth_xilinx -family xc2v): 512 boxes on chip, 1024-entry FIFOs, SSRAM latency 2, for each M
# given (default: 4 8). Writes bench/results/rtl/synth_m<M>.stat (Yosys's stat; the full log goes
# to ${TMPDIR:-/tmp}/bpx_synth_m<M>.log) and prints LUTs, flip-flops and block RAMs. Usage: rtl/synth.sh [M ...]   (needs yosys on PATH)
set -eu
here=$(cd "$(dirname "$0")" && pwd)
out="$here/../bench/results/rtl"
mkdir -p "$out"
[ $# -gt 0 ] || set -- 4 8
for m in "$@"; do
    log="${TMPDIR:-/tmp}/bpx_synth_m$m.log"
    nice yosys -q -l "$log" -p "
        read_verilog -sv $here/fadd.sv $here/updater.sv $here/comparator.sv $here/emitter.sv $here/interface.sv $here/bpx_chip.sv
        hierarchy -top bpx_chip -chparam M $m -chparam DEPTH 512 -chparam FDEPTH 1024 -chparam LAT 2 -chparam TRACE 0
        synth_xilinx -family xc2v -top bpx_chip -flatten
        tee -o $out/synth_m$m.stat stat
    " >/dev/null 2>&1
    luts=$(awk '/LUT[1-6] /{s+=$2} END{print s+0}' "$out/synth_m$m.stat")
    ffs=$(awk '/FD[A-Z]* /{s+=$2} END{print s+0}' "$out/synth_m$m.stat")
    brams=$(awk '/RAMB16/{s+=$2} END{print s+0}' "$out/synth_m$m.stat")
    echo "M=$m LUTs=$luts FFs=$ffs RAMB16=$brams"
done
