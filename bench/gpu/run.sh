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
# memcheck racecheck synccheck clresident scale ("sanitizer" names the three sanitizer phases).
#
# Before the build it looks for the GPU (nvidia-smi, the device nodes, and a five-line CUDA
# probe compiled with the toolkit's nvcc) and says in run.log, and on stdout, whether there is
# one. Without a usable GPU the phases that need one are skipped, each saying why; CI's ground
# (the fake-device tests, the opencl tests on PoCL, test_cuda_twin's host twin, the link-wrapped
# opencl fault test) is never run here. Only the targets this configuration has are built (no
# OpenCL: no bpx_clscale, and the opencl phases skip).
#
# Environment: PHASES (above); BPX_CMAKE_ARGS, extra configure arguments (-DBPX_OPENCL=OFF, say;
# CMake keeps them in the build directory's cache, so give another configuration its own
# BPX_BUILD_DIR, default build/gpu); BPX_GPU_REHEARSE=1 runs the GPU phases even without a GPU
# (a rehearsal on a CPU machine: the cuda tests then skip themselves, the benchmarks' cuda rows
# say unavailable, opencl runs on whatever platform there is).
#
# The 8 files (a device call returns at most 8; nothing else is written into OUT_DIR): run.log
# (machine, driver, toolkit, commit, the GPU check, the phases with their times and exit codes or
# why they were skipped, each test's and sanitizer's verdict), tests.log (the build's, the tests'
# and compute-sanitizer's output), gpubench.md/.csv (cuda device-resident and over the link
# against the host's grid on every thread, n = 500 .. 10M, exactness checked), table2.md (the
# paper's Table 2 with the communication share of cuda and opencl), clresident.md (the opencl
# tree with pairs out to the host against its device-resident cycle), scale.md/.csv (bpx bench's
# rows for cuda, opencl, hybrid, grid and sap).
set -u
cd "$(dirname "$0")/../.." || exit 1
self=$(pwd)/bench/gpu/run.sh
build=${BPX_BUILD_DIR:-build/gpu}
# What the GPU run needs, where this configuration has it: the cuda tests on the device, the
# suites that take every available backend, the opencl tests (run only on a GPU's OpenCL).
wanted_targets="bpx_cli bpx_gpubench bpx_clscale test_cuda test_cuda_device test_differential
                test_determinism test_hybrid test_errors test_out_of_memory test_opencl
                test_opencl_tree test_opencl_resident"

# The phases' work, run under timeout through this script itself (`run.sh --do NAME ARGS`), in
# the environment the main run exports (out, log, build).
build_all() {
    generator=""
    command -v ninja >/dev/null 2>&1 && generator="-G Ninja"
    # shellcheck disable=SC2086 # the generator, the extra arguments and the targets are words
    if ! cmake -S . -B "$build" $generator -DCMAKE_BUILD_TYPE=Release -DBPX_CUDA=ON \
        -DCMAKE_CUDA_ARCHITECTURES=90 -DBPX_MPI=OFF ${BPX_CMAKE_ARGS:-} >>"$out/tests.log" 2>&1; then
        tail -40 "$out/tests.log" >>"$log"
        return 1
    fi
    grep -E '^BPX_(CUDA|OPENCL):' "$build/CMakeCache.txt" | tr '\n' ' ' | sed 's/^/configured: /' >>"$log"
    echo >>"$log"
    # The build tool's own list of targets: a target this configuration lacks is left out (and
    # named), not asked for (an unknown target stops the whole build).
    have=$(cmake --build "$build" --target help 2>/dev/null |
        sed -n 's/^\.\.\. \([^ ]*\).*/\1/p; s/^\([^ :]*\): .*/\1/p')
    targets="" missing=""
    for t in $wanted_targets; do
        if printf '%s\n' "$have" | grep -qx "$t"; then targets="$targets $t"; else missing="$missing $t"; fi
    done
    [ -n "$missing" ] && echo "targets not in this configuration (skipped):$missing" >>"$log"
    echo "$targets" >"$build/gpu-run-targets"
    # shellcheck disable=SC2086
    if ! cmake --build "$build" -j "$(nproc)" --target $targets >>"$out/tests.log" 2>&1; then
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
# sanitize TOOL CAP_S: compute-sanitizer's TOOL over test_cuda --quick and test_cuda_device
# --quick (every path on small sets), the first given half of CAP_S, the second what is left.
sanitize() {
    tool=$1 cap=$2
    cs=$(command -v compute-sanitizer ||
        find /usr/local/cuda/bin /usr/local/cuda/compute-sanitizer /opt/nvidia -maxdepth 2 \
            -name compute-sanitizer -type f 2>/dev/null | head -1)
    [ -n "$cs" ] || { echo "no compute-sanitizer (PATH, /usr/local/cuda, /opt/nvidia)" >>"$log"; return 77; }
    t0=$(date +%s) rc=0
    for test in test_cuda test_cuda_device; do
        per=$((cap / 2))
        [ "$test" = test_cuda_device ] && per=$((cap - ($(date +%s) - t0) - 3))
        if [ "$per" -lt 5 ]; then
            echo "compute-sanitizer $tool $test: not run, ${per} s left of the phase" >>"$log"
            rc=1
            continue
        fi
        echo "== compute-sanitizer --tool $tool $test --quick (at most $per s)" >>"$out/tests.log"
        timeout -k 5 "$per" "$cs" --tool "$tool" --error-exitcode 1 "$build/test/$test" --quick \
            >>"$out/tests.log" 2>&1
        r=$?
        case $r in
        0) what="clean" ;;
        77) what="skipped by the test (77)" ;;
        124 | 137) what="cut at $per s (timeout): no verdict" rc=1 ;;
        *) what="exit $r: errors (tests.log)" rc=1 ;;
        esac
        echo "compute-sanitizer $tool $test: $what" >>"$log"
    done
    return "$rc"
}
if [ "${1:-}" = "--do" ]; then
    shift
    "$@"
    exit
fi

out=${1:?usage: bench/gpu/run.sh OUT_DIR [BUDGET_S]}
budget=${2:-480}
phases=${PHASES:-build cuda_test gpubench table2 suites memcheck racecheck synccheck clresident scale}
mkdir -p "$out" "$build"
out=$(cd "$out" && pwd)
log=$out/run.log
export out log build
start=$(date +%s)
elapsed() { echo $(($(date +%s) - start)); }
note() { echo "== $(elapsed) s: $*" | tee -a "$log"; }
wanted() {
    case " $phases " in *" $1 "*) return 0 ;; esac
    case "$1" in memcheck | racecheck | synccheck) case " $phases " in *" sanitizer "*) return 0 ;; esac ;; esac
    return 1
}
skip() { wanted "$1" && note "$1: skipped: $2"; return 0; }

# phase NAME CAP_S COMMAND...: runs COMMAND for at most CAP_S seconds and what is left of the
# budget (keeping 10 s for the end), logs how it went; a phase with under 20 s left is skipped.
phase() {
    name=$1 cap=$2
    shift 2
    wanted "$name" || return 0
    left=$((budget - $(elapsed) - 10))
    [ "$cap" -gt "$left" ] && cap=$left
    if [ "$cap" -lt 20 ]; then
        note "$name: skipped: ${cap} s for it (${left} s of the budget left; 20 needed)"
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

# The toolkit's compiler, where the image has it but not on the PATH (before anything asks).
if ! command -v nvcc >/dev/null 2>&1 && [ -x /usr/local/cuda/bin/nvcc ]; then
    PATH=/usr/local/cuda/bin:$PATH
    export PATH
fi

{
    echo "bench/gpu/run.sh: budget $budget s, phases: $phases"
    echo "build: $build${BPX_CMAKE_ARGS:+, configure arguments: $BPX_CMAKE_ARGS}${BPX_GPU_REHEARSE:+, BPX_GPU_REHEARSE=$BPX_GPU_REHEARSE}"
    date -u
    git rev-parse HEAD 2>/dev/null || echo "(no git)"
    git status --short 2>/dev/null | head -20
    echo "nvcc: $(command -v nvcc || echo 'none on the PATH or in /usr/local/cuda/bin')"
    nvcc --version 2>&1 | tail -2
    cmake --version | head -1
    lscpu 2>/dev/null | grep -E 'Model name|^CPU\(s\)'
    free -g | head -2
} >"$log" 2>&1

# The GPU, before the build: nvidia-smi, the device nodes, and a CUDA probe (device count,
# names, driver and runtime versions) built with nvcc. The probe decides when it runs; without
# nvcc, nvidia-smi or the device nodes do.
{
    echo "-- the GPU check"
    if command -v nvidia-smi >/dev/null 2>&1; then
        timeout 20 nvidia-smi --query-gpu=name,driver_version,memory.total,pcie.link.gen.current,pcie.link.width.current \
            --format=csv 2>&1 | head -4
    else
        echo "nvidia-smi: not on the PATH"
    fi
    nodes=$(find /dev -maxdepth 1 -name "nvidia[0-9]*" 2>/dev/null | tr "\n" " ")
    echo "device nodes: ${nodes:-none (/dev/nvidia0 ...)}"
} >>"$log" 2>&1
gpu=no gpu_why=""
probe_dir=$build/gpu-probe
if command -v nvcc >/dev/null 2>&1; then
    mkdir -p "$probe_dir"
    cat >"$probe_dir/probe.cu" <<'EOF'
#include <cstdio>
#include <cuda_runtime_api.h>
int main() {
    int n = 0, d = 0, r = 0;
    cudaDriverGetVersion(&d), cudaRuntimeGetVersion(&r);
    cudaError_t e = cudaGetDeviceCount(&n);
    printf("CUDA probe: driver %d, runtime %d: ", d, r);
    if (e != cudaSuccess)
        return printf("%s%s (%s)\n", d ? "" : "no CUDA driver: ", cudaGetErrorName(e),
                      cudaGetErrorString(e)), 1;
    printf("%d device(s)\n", n);
    for (int i = 0; i < n; i++) {
        cudaDeviceProp p;
        if (cudaGetDeviceProperties(&p, i) == cudaSuccess)
            printf("CUDA probe: device %d: %s, sm_%d%d, %.1f GiB\n", i, p.name, p.major, p.minor,
                   p.totalGlobalMem / 1073741824.0);
    }
    return n > 0 ? 0 : 1;
}
EOF
    if timeout 120 nvcc -o "$probe_dir/probe" "$probe_dir/probe.cu" >"$probe_dir/nvcc.log" 2>&1; then
        probe=$(timeout 30 "$probe_dir/probe" 2>&1)
        probe_rc=$?
        echo "$probe" >>"$log"
        if [ $probe_rc -eq 0 ]; then
            gpu=yes
        else
            gpu_why="the CUDA probe: $(echo "$probe" | head -1 | sed 's/^CUDA probe: //; s/ (.*//')"
        fi
    else
        echo "CUDA probe: nvcc failed (below)" >>"$log"
        tail -5 "$probe_dir/nvcc.log" >>"$log"
        gpu_why="the CUDA probe did not build"
    fi
elif [ -n "${nodes:-}" ] || { command -v nvidia-smi >/dev/null 2>&1 && timeout 20 nvidia-smi -L >/dev/null 2>&1; }; then
    gpu=yes
    echo "CUDA probe: no nvcc; nvidia-smi or the device nodes say there is a GPU" >>"$log"
else
    gpu_why="no nvcc for the CUDA probe"
fi
if [ $gpu = yes ]; then
    found=$(grep -m1 '^CUDA probe: device 0' "$log" | sed 's/^CUDA probe: device 0: //')
    note "GPU: found${found:+: $found}"
else
    [ -z "${nodes:-}" ] && gpu_why="$gpu_why; no /dev/nvidia*"
    command -v nvidia-smi >/dev/null 2>&1 || gpu_why="$gpu_why; no nvidia-smi"
    note "GPU: NONE ($gpu_why). The phases that need one skip, saying so${BPX_GPU_REHEARSE:+ (BPX_GPU_REHEARSE: they run anyway)}."
fi

# NVIDIA's OpenCL driver, registered with the ICD loader where the image has not (the opencl
# rows must run on the GPU; PoCL may be the only vendor listed).
nv_ocl=$(find /usr/local/nvidia /usr/lib/x86_64-linux-gnu /usr/lib64 /usr/lib -maxdepth 3 \
    -name 'libnvidia-opencl.so.1' 2>/dev/null | head -1)
if [ -n "$nv_ocl" ] && ! grep -qs nvidia /etc/OpenCL/vendors/*.icd; then
    mkdir -p /etc/OpenCL/vendors 2>/dev/null && echo "$nv_ocl" >/etc/OpenCL/vendors/nvidia.icd 2>/dev/null &&
        echo "registered $nv_ocl as an OpenCL vendor" >>"$log"
fi

: >"$out/tests.log"
phase build 240 "$self" --do build_all
if ! [ -x "$build/bpx" ]; then
    note "no build (bpx missing): see the end of this log and tests.log"
    exit 1
fi
{
    "$build/bpx" backends
    "$build/bpx" devices
} >>"$log" 2>&1

# What this machine and this build can run. BPX_GPU_REHEARSE runs the GPU phases regardless.
has() { grep -qw "$1" "$build/gpu-run-targets" 2>/dev/null && [ -x "$2" ]; }
cuda=no cuda_why="cuda: not in this build"
line=$("$build/bpx" backends 2>/dev/null | awk '$1 == "cuda"')
case "$line" in
*" available"*) cuda=yes ;;
?*) cuda_why="cuda: unavailable ($(echo "$line" | sed 's/^cuda *unavailable *//'))" ;;
esac
[ $gpu = no ] && cuda_why="no GPU; $cuda_why"
cl=no cl_why="opencl: not in this build"
if grep -q '^BPX_OPENCL:BOOL=ON' "$build/CMakeCache.txt" 2>/dev/null; then
    cl_why="opencl: no GPU among the OpenCL devices (CPU only, as PoCL in CI)"
    "$build/bpx" devices 2>/dev/null | awk '$2 == "gpu" { found = 1 } END { exit !found }' && cl=yes
fi
if [ -n "${BPX_GPU_REHEARSE:-}" ]; then
    [ $cuda = no ] && note "rehearsal: the cuda phases run though $cuda_why"
    cuda=yes
    if [ $cl = no ] && [ "$cl_why" != "opencl: not in this build" ]; then
        note "rehearsal: the opencl phases run though $cl_why"
        cl=yes
    fi
fi
devices=""
[ $cuda = yes ] && devices="cuda"
[ $cl = yes ] && devices="${devices:+$devices,}opencl"

# The cuda backend's own tests first: they have never run before the first GPU run.
if [ $cuda = yes ]; then
    phase cuda_test 120 "$self" --do suite 110 2 '^test_cuda(_device)?$'
    if has bpx_gpubench "$build/bench/gpu/bpx_gpubench"; then
        phase gpubench 120 sh -c "'$build/bench/gpu/bpx_gpubench' --sizes 500,2000,10000,100000,1000000,10000000 \
            --seconds 0.5 --csv '$out/gpubench.csv' >'$out/gpubench.md' 2>&1"
    else
        skip gpubench "bpx_gpubench not in this build"
    fi
else
    skip cuda_test "$cuda_why"
    skip gpubench "$cuda_why"
fi
if [ -n "$devices" ]; then
    phase table2 60 sh -c "'$build/bpx' bench --table2 --backend sap,$devices --cycles 2000 \
        >'$out/table2.md' 2>&1"
    # The suites that run every available backend, and the opencl backend's own tests where
    # OpenCL has the GPU.
    tests="test_differential|test_determinism|test_hybrid|test_errors|test_out_of_memory"
    [ $cl = yes ] && tests="$tests|test_opencl|test_opencl_tree|test_opencl_resident"
    phase suites 120 "$self" --do suite 110 8 "^($tests)\$"
else
    skip table2 "no GPU backend ($cuda_why; $cl_why)"
    skip suites "no GPU backend ($cuda_why; $cl_why): nothing CI does not run"
fi
# compute-sanitizer, each tool with its own cap, and each with a fair share of what is left of
# the budget when less is left than the three caps: a slow memcheck does not starve the others.
n_tools=0
for tool in memcheck racecheck synccheck; do wanted $tool && n_tools=$((n_tools + 1)); done
for tool in memcheck racecheck synccheck; do
    wanted $tool || continue
    if [ $cuda = no ]; then
        skip $tool "$cuda_why"
        continue
    fi
    cap=90
    [ $tool = synccheck ] && cap=60
    share=$(((budget - $(elapsed) - 10) / n_tools))
    [ "$share" -lt "$cap" ] && cap=$share
    n_tools=$((n_tools - 1))
    phase $tool "$cap" "$self" --do sanitize $tool "$cap"
done
if [ $cl = yes ] && ! has bpx_clscale "$build/bench/opencl/bpx_clscale"; then
    skip clresident "bpx_clscale not built"
elif [ $cl = yes ]; then
    phase clresident 60 sh -c "'$build/bench/opencl/bpx_clscale' --sizes 100000,1000000,10000000 \
        --scene uniform,heavy --method tree --mode host,resident --cycles 7 >'$out/clresident.md' 2>&1"
else
    skip clresident "$cl_why"
fi
if [ -n "$devices" ]; then
    phase scale 120 sh -c "'$build/bpx' bench --backend $devices,hybrid,grid,sap \
        --sizes 10000,100000,1000000 --scene uniform,heavy --seconds 0.5 --csv '$out/scale.csv' \
        >'$out/scale.md' 2>&1"
else
    skip scale "no GPU backend ($cuda_why; $cl_why)"
fi
note "done"
# The headline tables on stdout too (a device call returns the output's tail).
for f in gpubench.md clresident.md; do
    [ -s "$out/$f" ] && { echo "--- $f"; tail -12 "$out/$f"; }
done
[ -s "$out/table2.md" ] && { echo "--- table2.md"; grep -E "^\| *(50|100|200|300|400|500) *\|" "$out/table2.md" | head -20; }
exit 0
