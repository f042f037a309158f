#!/usr/bin/env bash
# The bpx program links none of the optional libraries: Bullet (libBulletCollision,
# libLinearMath), Box2D, SDL2 and libpng are opened at run time when a command needs them
# (apps/dynload), so bpx starts on a machine without them. Checks the program's own NEEDED
# entries (readelf -d) and, where ldd is installed, everything it loads at start.
# usage: cli_deps.sh PATH/TO/bpx
set -uo pipefail
if [[ $# -ne 1 ]]; then
    echo "usage: $0 PATH/TO/bpx" >&2
    exit 2
fi
bpx=$1
forbidden='libBullet|libLinearMath|libbox2d|libfcl|libSDL2|libpng'
failures=0

if ! command -v readelf >/dev/null 2>&1; then
    echo "SKIPPED: readelf is not installed (binutils)"
    exit 77
fi
needed=$(readelf -d "$bpx" | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p')
[[ -n $needed ]] || { echo "FAIL: readelf found no NEEDED entries in $bpx" >&2; exit 1; }
echo "NEEDED: $(tr '\n' ' ' <<<"$needed")"
bad=$(grep -E "$forbidden" <<<"$needed")
if [[ -n $bad ]]; then
    echo "FAIL: bpx links $(tr '\n' ' ' <<<"$bad")" >&2
    failures=$((failures + 1))
fi

if command -v ldd >/dev/null 2>&1; then
    loaded=$(ldd "$bpx" 2>&1) || { echo "FAIL: ldd $bpx: $loaded" >&2; exit 1; }
    bad=$(grep -E "$forbidden" <<<"$loaded")
    if [[ -n $bad ]]; then
        echo "FAIL: bpx loads at start:" >&2
        echo "$bad" >&2
        failures=$((failures + 1))
    fi
else
    echo "note: no ldd, the NEEDED entries only"
fi

if [[ $failures -eq 0 ]]; then
    echo "bpx links none of Bullet, Box2D, SDL2, libpng"
    exit 0
fi
exit 1
