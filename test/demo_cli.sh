#!/usr/bin/env bash
# End-to-end tests of `bpx demo`: the no-argument run (the README's job), pictures, JSON, the
# trace and its determinism across backends and threads, usage and runtime errors.
# usage: demo_cli.sh PATH/TO/bpx PATH/TO/test_demo SCRATCH_DIR
set -uo pipefail
if [[ $# -ne 3 ]]; then
    echo "usage: $0 PATH/TO/bpx PATH/TO/test_demo SCRATCH_DIR" >&2
    exit 2
fi
bpx=$(realpath "$1")
test_demo=$(realpath "$2")
tmp=$3
rm -rf "$tmp" && mkdir -p "$tmp" && cd "$tmp" || exit 2

failures=0
fail() {
    failures=$((failures + 1))
    echo "FAIL: $*" >&2
    [[ -f err.txt ]] && sed 's/^/  stderr| /' err.txt >&2
}
# run ARGS...: runs bpx demo; stdout in out.txt, stderr in err.txt, status in $rc.
run() {
    rc=0
    "$bpx" demo "$@" >out.txt 2>err.txt || rc=$?
}
size_of() { stat -c %s "$1" 2>/dev/null || echo missing; }
# check_png FILE W H: a valid W x H picture, not blank (skipped without libpng).
check_png() {
    local prc=0
    "$test_demo" --check-png "$1" "$2" "$3" >png.txt 2>&1 || prc=$?
    [[ $prc -eq 0 || $prc -eq 77 ]] || { fail "$1 is not a good ${2}x${3} PNG"; cat png.txt >&2; }
}

# 1. No arguments: the paper's 500 spheres, ten pictures and statistics in ./bpx-demo/.
mkdir noargs && pushd noargs >/dev/null || exit 2
start=$(date +%s)
run
elapsed=$(($(date +%s) - start))
[[ $rc -eq 0 ]] || fail "bpx demo with no arguments exited $rc"
[[ $elapsed -lt 60 ]] || fail "bpx demo with no arguments took ${elapsed}s"
grep -q "| 1. broad phase (bpx) |" out.txt || fail "no stage table"
grep -q "mean overlapping AABB pairs per cycle" out.txt || fail "no pairs per cycle"
grep -q "500 spheres" out.txt || fail "not 500 spheres"
[[ -f bpx-demo/stats.json ]] || fail "no bpx-demo/stats.json"
if grep -q "without libpng" err.txt; then
    echo "note: built without libpng, no pictures to check"
else
    pictures=$(ls bpx-demo/frame_*.png 2>/dev/null | wc -l)
    [[ $pictures -eq 10 ]] || fail "expected 10 pictures, found $pictures"
    check_png bpx-demo/frame_000600.png 640 480
fi
popd >/dev/null || exit 2

# 2. Pictures every 20 cycles into a chosen directory, a trace, JSON on stdout.
run --spheres 60 --cycles 40 --every 20 --out pics/nested --record run.trace --json
[[ $rc -eq 0 ]] || fail "headless run exited $rc"
grep -q '"cycles": 40' out.txt || fail "JSON lacks the cycle count"
grep -q '"pairs_per_cycle"' out.txt || fail "JSON lacks pairs per cycle"
grep -q '"trace": "run.trace"' out.txt || fail "JSON lacks the trace"
[[ $(size_of run.trace) == $((32 + 40 * 60 * 24)) ]] || fail "trace size $(size_of run.trace)"
if ! grep -q "without libpng" err.txt; then
    check_png pics/nested/frame_000020.png 640 480
    check_png pics/nested/frame_000040.png 640 480
    [[ ! -e pics/nested/frame_000030.png ]] || fail "a picture off the --every grid"
fi

# 3. Same seed: the same trace bytes from every backend and thread count; another seed differs.
for variant in "--backend reference" "--backend brute --threads 3" "--threads 2"; do
    # shellcheck disable=SC2086
    run --spheres 60 --cycles 40 --every 0 --record other.trace $variant
    [[ $rc -eq 0 ]] || fail "run with $variant exited $rc"
    cmp -s run.trace other.trace || fail "trace with $variant differs"
done
run --spheres 60 --cycles 40 --every 0 --record seed2.trace --seed 2
cmp -s run.trace seed2.trace && fail "another seed gave the same trace"
[[ ! -e bpx-demo ]] || fail "--every 0 created the picture directory"

# 4. Scenario options are taken; --size changes the pictures.
run --spheres 30 --cycles 10 --every 10 --out small --size 200x150 --dt 1/120 --restitution 0.9 \
    --mass 2 --layers 2 --gap 12 --wall-gap 15 --radius 20 --height 300 --speed 30 --seed 9
[[ $rc -eq 0 ]] || fail "scenario options exited $rc"
grep -q "restitution 0.9, mass 2 kg, seed 9" out.txt || fail "options not reported"
grep -q "of 0.00833333 s" out.txt || fail "--dt 1/120 not taken"
grep -q "without libpng" err.txt || check_png small/frame_000010.png 200 150

# 5. Usage errors: exit 2 and a message.
for bad in "--spheres 0" "--dt 0" "--dt x" "--restitution 1.5" "--layers 9" "--bogus" \
    "--screenshot shot.png" "--cycles 0" "--size 10x10" "--backend nope" "--every" \
    "--threads 0" "--seed -1" "--table2 --window"; do
    # shellcheck disable=SC2086
    run $bad
    [[ $rc -eq 2 ]] || fail "'bpx demo $bad' exited $rc, want 2"
    [[ -s err.txt ]] || fail "'bpx demo $bad' printed no message"
done

# 6. Runtime errors: exit 1 and a message naming the problem.
run --spheres 10 --cycles 5 --every 0 --record no-such-dir/x.trace
[[ $rc -eq 1 ]] && grep -q "no-such-dir/x.trace" err.txt || fail "bad --record path: exit $rc"
touch a-file
run --spheres 10 --cycles 5 --every 5 --out a-file
[[ $rc -eq 1 ]] && grep -q "a-file" err.txt || fail "--out onto a file: exit $rc"

# 7. Help.
run --help
[[ $rc -eq 0 ]] && grep -q "1/60" out.txt || fail "--help"

if [[ $failures -gt 0 ]]; then
    echo "demo_cli: $failures failure(s)" >&2
    exit 1
fi
echo "demo_cli: ok"
