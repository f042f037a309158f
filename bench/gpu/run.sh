#!/bin/sh
# shellcheck disable=SC2317 # the phases' helpers run through `run.sh --do`
# Every GPU figure in one command, within a lent machine's budget. A session has 15 minutes of
# device time, the machine's start (1-2 min) included, and at most 10 minutes a command; so this
# script keeps to BUDGET_S seconds (default 480), doing the most telling work first and cutting
# or skipping what no longer fits, and writes each file as soon as it has it (a run cut short
# still returns what it had):
#
#   bench/gpu/run.sh OUT_DIR [BUDGET_S]
#
# From a device session: run(command="bench/gpu/run.sh $OUT", timeout_s=600), then copy the
# returned files into bench/results/<device>/ (the device's name is in run.log) and commit them.
# That leaves ~4 minutes on a warm machine to rerun one phase (PHASES="scale" bench/gpu/run.sh
# $OUT 200, say). PHASES (default all, in this order): build cuda_test gpubench table2 suites
# sanitizer clresident scale.
#
# The 8 files (a device call returns at most 8): run.log (machine, driver, toolkit, commit, the
# phases with their times and exit codes, each test's and sanitizer's verdict), tests.log (the
# tests' and compute-sanitizer's output),
# gpubench.md/.csv (cuda device-resident and over the link against the host's grid on every
# thread, n = 500 .. 10M, exactness checked), table2.md (the paper's Table 2 with the
# communication share of cuda and opencl), clresident.md (the opencl tree with pairs out to the
# host against its device-resident cycle), scale.md/.csv (bpx bench's rows for cuda, opencl,
# hybrid, grid and sap).
set -u
cd "$(dirname "$0")/../.." || exit 1
self=$(pwd)/bench/gpu/run.sh
build=build/gpu
targets="bpx_cli bpx_gpubench bpx_clscale test_cuda test_cuda_device test_cuda_twin
         test_differential test_determinism test_hybrid test_errors test_out_of_memory test_opencl
         test_opencl_tree test_opencl_resident test_opencl_faults"

# The phases' work, run under timeout through this script itself (`run.sh --do NAME ARGS`), in
# the environment the main run exports (out, log).
build_all() {
    generator=""
    command -v ninja >/dev/null 2>&1 && generator="-G Ninja"
    # shellcheck disable=SC2086 # the generator and the targets are words
    if ! cmake -S . -B "$build" $generator -DCMAKE_BUILD_TYPE=Release -DBPX_CUDA=ON \
        -DCMAKE_CUDA_ARCHITECTURES=90 -DBPX_MPI=OFF >>"$out/tests.log" 2>&1 ||
        ! cmake --build "$build" -j "$(nproc)" --target $targets >>"$out/tests.log" 2>&1; then
        tail -40 "$out/tests.log" >>"$log"
        return 1
    fi
}
# suite TIMEOUT JOBS REGEX: ctest for the named tests; each test's verdict goes to run.log, the
# output to tests.log.
suite() {
    before=$(wc -l <"$out/tests.log")
    (cd "$build" && ctest --output-on-failure --timeout "$1" -j "$2" -R "$3") >>"$out/tests.log" 2>&1
    rc=$?
    tail -n +$((before + 1)) "$out/tests.log" | grep -E "Test +#|tests passed|tests failed" >>"$log"
    return "$rc"
}
# sanitize: compute-sanitizer's memcheck, racecheck and synccheck over test_cuda --quick and
# test_cuda_device --quick (every path on small sets), in turn, as long as the phase's time lasts.
sanitize() {
    cs=$(command -v compute-sanitizer ||
        find /usr/local/cuda/bin /usr/local/cuda/compute-sanitizer /opt/nvidia -maxdepth 2 \
            -name compute-sanitizer -type f 2>/dev/null | head -1)
    [ -n "$cs" ] || { echo "no compute-sanitizer" >>"$log"; return 77; }
    for tool in memcheck racecheck synccheck; do
        for test in test_cuda test_cuda_device; do
            echo "== compute-sanitizer --tool $tool $test --quick" >>"$out/tests.log"
            "$cs" --tool "$tool" --error-exitcode 1 "$build/test/$test" --quick \
                >>"$out/tests.log" 2>&1
            echo "compute-sanitizer $tool $test: exit $?" >>"$log"
        done
    done
}
if [ "${1:-}" = "--do" ]; then
    shift
    "$@"
    exit
fi

out=${1:?usage: bench/gpu/run.sh OUT_DIR [BUDGET_S]}
budget=${2:-480}
phases=${PHASES:-build cuda_test gpubench table2 suites sanitizer clresident scale}
mkdir -p "$out"
out=$(cd "$out" && pwd)
log=$out/run.log
export out log
start=$(date +%s)
elapsed() { echo $(($(date +%s) - start)); }
note() { echo "== $(elapsed) s: $*" | tee -a "$log"; }
wanted() { case " $phases " in *" $1 "*) return 0 ;; esac; return 1; }

# phase NAME CAP_S COMMAND...: runs COMMAND for at most CAP_S seconds and what is left of the
# budget (keeping 10 s for the end), logs how it went; a phase with under 20 s left is skipped.
phase() {
    name=$1 cap=$2
    shift 2
    wanted "$name" || return 0
    left=$((budget - $(elapsed) - 10))
    [ "$cap" -gt "$left" ] && cap=$left
    if [ "$cap" -lt 20 ]; then
        note "$name: skipped, ${left} s of the budget left"
        return 0
    fi
    note "$name: start (at most $cap s)"
    t0=$(date +%s)
    timeout -k 5 "$cap" "$@"
    rc=$?
    what="exit $rc"
    [ $rc -eq 124 ] && what="cut at $cap s (timeout)"
    [ $rc -eq 77 ] && what="skipped by the program (77)"
    note "$name: $what after $(($(date +%s) - t0)) s"
    return 0
}

{
    echo "bench/gpu/run.sh: budget $budget s, phases: $phases"
    date -u
    git rev-parse HEAD 2>/dev/null || echo "(no git)"
    git status --short 2>/dev/null | head -20
    nvidia-smi --query-gpu=name,driver_version,memory.total,pcie.link.gen.current,pcie.link.width.current \
        --format=csv 2>&1 | head -3
    nvcc --version 2>&1 | tail -2
    cmake --version | head -1
    lscpu 2>/dev/null | grep -E 'Model name|^CPU\(s\)'
    free -g | head -2
} >"$log" 2>&1

# The toolkit's compiler, where the image has it but not on the PATH.
if ! command -v nvcc >/dev/null 2>&1 && [ -x /usr/local/cuda/bin/nvcc ]; then
    PATH=/usr/local/cuda/bin:$PATH
    export PATH
fi

# NVIDIA's OpenCL driver, registered with the ICD loader where the image has not (the opencl
# rows must run on the GPU; PoCL may be the only vendor listed).
nv_ocl=$(find /usr/local/nvidia /usr/lib/x86_64-linux-gnu /usr/lib64 /usr/lib -name 'libnvidia-opencl.so.1' 2>/dev/null | head -1)
if [ -n "$nv_ocl" ] && ! grep -qs nvidia /etc/OpenCL/vendors/*.icd; then
    mkdir -p /etc/OpenCL/vendors 2>/dev/null && echo "$nv_ocl" >/etc/OpenCL/vendors/nvidia.icd 2>/dev/null &&
        echo "registered $nv_ocl as an OpenCL vendor" >>"$log"
fi

: >"$out/tests.log"
phase build 240 "$self" --do build_all
if wanted build && ! [ -x "$build/bpx" ]; then
    note "no build: see the end of this log"
    exit 1
fi
{
    "$build/bpx" backends
    "$build/bpx" devices
} >>"$log" 2>&1

# The cuda backend's own test first: it has never run before the first GPU run.
phase cuda_test 120 "$self" --do suite 110 2 '^test_cuda(_device|_twin)?$'
phase gpubench 150 sh -c "'$build/bench/gpu/bpx_gpubench' --sizes 500,2000,10000,100000,1000000,10000000 \
    --seconds 0.5 --csv '$out/gpubench.csv' >'$out/gpubench.md' 2>&1"
phase table2 70 sh -c "'$build/bpx' bench --table2 --backend sap,cuda,opencl --cycles 2000 \
    >'$out/table2.md' 2>&1"
# The suites that run every available backend, and the opencl backend's own tests, on the GPU.
phase suites 150 "$self" --do suite 140 8 '^(test_differential|test_determinism|test_hybrid|test_errors|test_out_of_memory|test_opencl|test_opencl_tree|test_opencl_resident|test_opencl_faults)$'
phase sanitizer 120 "$self" --do sanitize
phase clresident 60 sh -c "'$build/bench/opencl/bpx_clscale' --sizes 100000,1000000,10000000 \
    --scene uniform,heavy --method tree --mode host,resident --cycles 7 >'$out/clresident.md' 2>&1"
phase scale 120 sh -c "'$build/bpx' bench --backend cuda,opencl,hybrid,grid,sap \
    --sizes 10000,100000,1000000 --scene uniform,heavy --seconds 0.5 --csv '$out/scale.csv' \
    >'$out/scale.md' 2>&1"
note "done"
# The headline tables on stdout too (a device call returns the output's tail).
for f in gpubench.md clresident.md; do
    [ -s "$out/$f" ] && { echo "--- $f"; tail -12 "$out/$f"; }
done
[ -s "$out/table2.md" ] && { echo "--- table2.md"; grep -E "^\| *(50|100|200|300|400|500) *\|" "$out/table2.md" | head -20; }
exit 0
