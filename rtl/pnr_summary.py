"""Summary of one ECP5 place and route (rtl/pnr_ecp5.sh): resources from Yosys's stat and
nextpnr's report, fmax and the critical path's start and end cells from nextpnr's report.
Usage: pnr_summary.py M DEPTH FREQ STAT REPORT_JSON TIMES"""
import json
import re
import sys

m, depth, freq, stat_path, report_path, times = sys.argv[1:7]
stat = open(stat_path).read()


def cells(name):
    found = re.search(r"^\s*(\d+)\s+" + name + r"\s*$", stat, re.M)
    return int(found.group(1)) if found else 0


report = json.load(open(report_path))
util = report.get("utilization", report.get("utilisation", {}))
comb = util.get("TRELLIS_COMB", {})
ff = util.get("TRELLIS_FF", {})
ebr = util.get("DP16KD", {})
lut4 = cells("LUT4") + 2 * cells("CCU2C")  # a CCU2C is two LUT4s with their carry
print(f"M {m} DEPTH {depth} FDEPTH 1024 LAT 2 on LFE5U-85F CABGA381, target {freq} MHz")
print(f"LUT4 {lut4} (synth: {cells('LUT4')} LUT4 + {cells('CCU2C')} CCU2C)"
      f"  TRELLIS_COMB {comb.get('used')}/{comb.get('available')}"
      f"  FF {ff.get('used')}/{ff.get('available')}  DP16KD {ebr.get('used')}/{ebr.get('available')}")
for clk, f in report.get("fmax", {}).items():
    ok = "meets" if f["achieved"] >= float(freq) else "misses"
    print(f"fmax {f['achieved']:.1f} MHz ({clk}; {ok} {freq} MHz)")
for path in report.get("critical_paths", [])[:1]:
    steps = path["path"]
    logic = sum(s["delay"] for s in steps if s["type"] != "routing")
    total = sum(s["delay"] for s in steps)
    print(f"critical path {total:.2f} ns ({logic:.2f} ns logic, {len(steps)} steps): "
          f"from {steps[0]['from']['cell']}.{steps[0]['from']['port']}")
    print(f"  to {steps[-1]['to']['cell']}.{steps[-1]['to']['port']}")
print(times)
