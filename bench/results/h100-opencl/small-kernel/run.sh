#!/bin/bash
# Device run: the one-launch small-set kernel (working tree) against the snapshot in .gpu/src.
T0=$(date +%s); el() { echo "=== [$(( $(date +%s) - T0 ))s] $*"; }
G=$(pwd)/.gpu; OLD=$G/src; NEW=$(pwd)
NVOCL=$(find /usr/local/nvidia /usr/lib/x86_64-linux-gnu /usr/lib64 /usr/lib /lib -name 'libnvidia-opencl.so.1' 2>/dev/null | head -1)
mkdir -p /etc/OpenCL/vendors && echo "$NVOCL" > /etc/OpenCL/vendors/nvidia.icd
el build
for v in old new; do
  src=$OLD; [ $v = new ] && src=$NEW
  cmake -S $src -B /tmp/b$v -G Ninja -DCMAKE_BUILD_TYPE=Release > /tmp/cfg$v.log 2>&1 || { tail -20 /tmp/cfg$v.log; }
  ninja -C /tmp/b$v bpx_cli test_opencl test_differential 2>&1 | grep -E "error|FAILED" | head
done
/tmp/bnew/bpx backends | grep opencl
el test_opencl new
(cd /tmp/bnew && timeout 150 ./test/test_opencl 2>&1 | grep -v "^  " | tail -8; echo "rc=${PIPESTATUS[0]}")
el test_differential new
(cd /tmp/bnew && timeout 150 ./test/test_differential 2>&1 | tail -4; echo "rc=${PIPESTATUS[0]}")
for round in 1 2; do for v in old new; do
  el "table2 $v round $round"
  timeout 120 /tmp/b$v/bpx bench --table2 --backend opencl > /tmp/t2_${v}_$round.md 2>/dev/null; echo rc=$?
  grep -E "^\| (50|100|200|300|400|500) \|" /tmp/t2_${v}_$round.md | head -20
  grep -A 14 "Mean us per cycle of every" /tmp/t2_${v}_$round.md | tail -12
done; done
for v in old new; do
  el "scale $v"
  timeout 100 /tmp/b$v/bpx bench --backend opencl --sizes 256,512,1000,2000 --scene uniform --seconds 1 2>/dev/null | grep -E "^\| uniform" ; echo rc=$?
done
el done
for v in old new; do cp /tmp/t2_${v}_1.md $OUT/table2_$v.md; cp /tmp/t2_${v}_2.md $OUT/table2_${v}_repeat.md; done
