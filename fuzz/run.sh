#!/bin/sh
# Long fuzzing runs: fuzz/run.sh SECONDS [HARNESS...] builds the `fuzz` preset (clang), then
# runs each harness (default: csv trace api) for SECONDS, all at once, at the lowest priority.
# New inputs collect in build/fuzz/long/<harness>/ (the committed seeds are only read), crash
# inputs in build/fuzz/long/crash-<harness>-*, logs in build/fuzz/long/<harness>.log; at the end
# each harness's executions and the crashes are printed. A crash input belongs in
# fuzz/regressions/<harness>/ once fixed: the replay tests run it in every build.
set -eu
cd "$(dirname "$0")/.."
if [ $# -lt 1 ]; then
    echo "usage: fuzz/run.sh SECONDS [csv|trace|api ...]" >&2
    exit 2
fi
seconds=$1
shift
harnesses=${*:-csv trace api}
cmake --preset fuzz >/dev/null
nice -n 19 cmake --build --preset fuzz
out=build/fuzz/long
# The trace harness writes each input to a file: memory is faster than a disk.
if [ -z "${TMPDIR:-}" ] && [ -d /dev/shm ] && [ -w /dev/shm ]; then
    export TMPDIR=/dev/shm
fi
mkdir -p "$out"
pids=""
for h in $harnesses; do
    mkdir -p "$out/$h"
    nice -n 19 build/fuzz/fuzz/fuzz_$h -max_total_time="$seconds" -timeout=30 \
        -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$out/crash-$h-" \
        "$out/$h" "fuzz/corpus/$h" >"$out/$h.log" 2>&1 &
    pids="$pids $!"
done
status=0
for pid in $pids; do
    wait "$pid" || status=1
done
for h in $harnesses; do
    runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$out/$h.log" | tail -n 1)
    echo "$h: ${runs:-?} executions in ${seconds} s (log: $out/$h.log)"
done
ls "$out"/crash-* 2>/dev/null && status=1
exit $status
