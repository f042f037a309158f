#!/bin/bash
T0=$(date +%s); el() { echo "=== [$(( $(date +%s) - T0 ))s] $*"; }
NVOCL=$(find /usr/local/nvidia /usr/lib/x86_64-linux-gnu /usr/lib64 /usr/lib /lib -name 'libnvidia-opencl.so.1' 2>/dev/null | head -1)
mkdir -p /etc/OpenCL/vendors && echo "$NVOCL" > /etc/OpenCL/vendors/nvidia.icd
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
el build
cmake -S . -B /tmp/b -G Ninja -DCMAKE_BUILD_TYPE=Release -DBPX_OPENCL=ON > /tmp/cfg.log 2>&1 || tail -20 /tmp/cfg.log
ninja -C /tmp/b bpx_cli test_opencl test_differential test_determinism 2>&1 | grep -E "error|FAILED" | head
/tmp/b/bpx devices; /tmp/b/bpx backends | grep opencl
for t in test_opencl test_differential test_determinism; do
  el $t
  (cd /tmp/b && timeout 200 ./test/$t 2>&1 | grep -v "^  " | tail -4; echo "rc=${PIPESTATUS[0]}")
done
el table2
timeout 120 /tmp/b/bpx bench --table2 --backend opencl,brute,prune > $OUT/table2.md 2>&1; echo rc=$?
grep -A 14 "Mean us per cycle of every" $OUT/table2.md | tail -12
el scale
timeout 150 /tmp/b/bpx bench --backend opencl --sizes 1000,10000,100000,1000000 --scene uniform --seconds 1 > $OUT/scale.md 2>&1; echo rc=$?
grep -E "^\| uniform" $OUT/scale.md
el done
