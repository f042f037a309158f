#!/bin/sh
# The backend contract (src/core/backend.h) holds: no backend file includes the world's private
# header or names its struct. SPDX-License-Identifier: MIT
set -eu
root="${1:-$(dirname "$0")/..}"
found=$(grep -rlE '#include "(core/)?world\.h"|struct bpx_world \{|->backend_state' \
    "$root/src/cpu" "$root/src/opencl" "$root/src/cuda" "$root/src/hw" "$root/src/hybrid" || true)
if [ -n "$found" ]; then
    echo "backend files that reach the world's internals:" >&2
    echo "$found" >&2
    exit 1
fi
echo "no backend file includes core/world.h"
