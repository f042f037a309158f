#!/bin/sh
# Every GPU figure in one command, for the rare machine with an NVIDIA GPU (within ~35 minutes):
# builds bpx with the cuda and opencl backends, runs the GPU tests, then the GPU benchmark rows,
# and writes everything to bench/results/<device>/ (or to $1).
#
#   bench/gpu/run.sh [OUT_DIR]
#
# Files: env.txt (machine, driver, toolkit, commit), tests.log, gpubench.md/.csv (cuda
# device-resident and over the link against the host's grid on every thread, n = 500 .. 10M),
# table2.md (the paper's Table 2 with the communication share of cuda and opencl), scale.md/.csv
# (bpx bench's scale rows for cuda, opencl, hybrid, grid and sap), clresident.md (the opencl tree's
# cycle with pairs out to the host against its device-resident cycle, bpx_clscale --mode).
set -u
cd "$(dirname "$0")/../.."
device=$(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1 |
         tr 'A-Z ' 'a-z-' | tr -cd 'a-z0-9-')
out=${1:-bench/results/${device:-unknown-gpu}}
mkdir -p "$out"
build=build/gpu
jobs=$(nproc)
start=$(date +%s)
stamp() { echo "== $(( $(date +%s) - start )) s: $*"; }

{
    date -u
    git rev-parse HEAD 2>/dev/null || echo "(no git)"
    git status --short 2>/dev/null | head -20
    nvidia-smi 2>&1 | head -15
    nvcc --version 2>&1 | tail -2
    cmake --version | head -1
    lscpu 2>/dev/null | grep -E 'Model name|^CPU\(s\)'
    free -g | head -2
} >"$out/env.txt" 2>&1

stamp "configure and build" | tee "$out/tests.log"
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DBPX_CUDA=ON \
      -DCMAKE_CUDA_ARCHITECTURES=90 >>"$out/tests.log" 2>&1 &&
cmake --build "$build" -j "$jobs" >>"$out/tests.log" 2>&1 || {
    echo "build failed; see $out/tests.log"; tail -40 "$out/tests.log"; exit 1; }

stamp "GPU tests" | tee -a "$out/tests.log"
# The device's own tests, and the suites that run every available backend.
(cd "$build" && ctest --output-on-failure --timeout 900 -j 4 \
     -R 'test_cuda|test_opencl|test_differential|test_determinism|test_errors|test_out_of_memory') \
    >>"$out/tests.log" 2>&1
grep -E "tests passed|Failed|Skipped|\*\*\*" "$out/tests.log" | tail -12

stamp "gpubench" | tee -a "$out/tests.log"
"$build/bench/gpu/bpx_gpubench" --sizes 500,2000,10000,100000,1000000,10000000 --seconds 1.5 \
    --csv "$out/gpubench.csv" | tee "$out/gpubench.md"

stamp "table 2" | tee -a "$out/tests.log"
"$build/bpx" bench --table2 --backend sap,cuda,opencl --cycles 3000 >"$out/table2.md" 2>&1
tail -30 "$out/table2.md"

stamp "scale rows" | tee -a "$out/tests.log"
"$build/bpx" bench --backend cuda,opencl,hybrid,grid,sap --sizes 10000,100000,1000000 \
    --scene uniform,heavy --seconds 1 --csv "$out/scale.csv" >"$out/scale.md" 2>&1
grep -E "^\|" "$out/scale.md" | head -40

stamp "opencl device-resident" | tee -a "$out/tests.log"
"$build/bench/opencl/bpx_clscale" --sizes 100000,1000000,10000000 --scene uniform,heavy \
    --method tree --mode host,resident --cycles 7 >"$out/clresident.md" 2>&1
cat "$out/clresident.md"
stamp "done" | tee -a "$out/tests.log"
