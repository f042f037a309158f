#!/usr/bin/env bash
# bpx without its optional libraries: `pairs`, `query`, `model` and `demo` run, and what needs a
# missing library says which one. The program links none of them (cli_deps.sh); they are opened
# at run time. Twice over:
#   hook:   the test hook BPX_NO_DLOPEN=1 (apps/dynload/dynload.h) fails every run-time load as if
#           libpng, SDL2 and the peers' module (Bullet, Box2D) were not installed;
#   hidden: where unprivileged user and mount namespaces are allowed (unshare -rm), each run sees
#           those libraries' files replaced by empty ones, as on a machine without them (skipped
#           with a note where unshare is refused, as in many containers).
# usage: cli_no_dlopen.sh PATH/TO/bpx SCRATCH_DIR MODEL(ON/OFF) PNG(ON/OFF)
#   MODEL: the build has the FPGA model (BPX_MODEL); PNG: the build found png.h
set -uo pipefail
if [[ $# -ne 4 ]]; then
    echo "usage: $0 PATH/TO/bpx SCRATCH_DIR ON|OFF ON|OFF" >&2
    exit 2
fi
bpx=$(realpath "$1")
tmp=$2
model=$3
png=$4
rm -rf "$tmp" && mkdir -p "$tmp" && cd "$tmp" || exit 2

failures=0
fail() {
    failures=$((failures + 1))
    echo "FAIL ($mode): $*" >&2
    [[ -f err.txt ]] && sed 's/^/  stderr| /' err.txt >&2
}

# The optional libraries' files, for the hidden mode: Bullet, Box2D, SDL2, libpng.
hidden_files() {
    ldconfig -p 2>/dev/null | sed -n 's/.* => //p' |
        grep -E '/lib(BulletCollision|LinearMath|box2d|fcl|SDL2-2\.0|png16)\.so' |
        while read -r lib; do readlink -f "$lib"; done | sort -u
}
masks=""
for lib in $(hidden_files); do
    masks+="mount --bind /dev/null '$lib' || exit 125; "
done

# run ARGS...: bpx ARGS with every optional library out of reach; stdout out.txt, stderr err.txt.
run() {
    rc=0
    if [[ $mode == hook ]]; then
        BPX_NO_DLOPEN=1 "$bpx" "$@" >out.txt 2>err.txt || rc=$?
    else
        # shellcheck disable=SC2016 # "$0" "$@" are the inner shell's: bpx and its arguments
        unshare -rm bash -c "$masks"'exec "$0" "$@"' "$bpx" "$@" >out.txt 2>err.txt || rc=$?
    fi
}

checks() {
    # pairs and query: the library alone.
    printf '0,0,0,1,1,1\n0.5,0.5,0.5,2,2,2\n5,5,5,6,6,6\n' >boxes.csv
    run pairs boxes.csv
    [[ $rc -eq 0 && $(cat out.txt) == "0 1" ]] || fail "pairs: exit $rc, printed '$(cat out.txt)'"
    run query boxes.csv --ray 0.5,0.5,-5,0,0,1
    [[ $rc -eq 0 && $(head -n 1 out.txt) == 0* ]] ||
        fail "query: exit $rc, printed '$(cat out.txt)'"

    # model: the paper's FPGA, or a clear "not in this build".
    run model --boxes 50 --cycles 2
    if [[ $model == ON ]]; then
        [[ $rc -eq 0 ]] || fail "model: exit $rc"
        [[ -s out.txt ]] || fail "model printed nothing"
    else
        if [[ $rc -ne 1 ]] || ! grep -q "not in this build" err.txt; then
            fail "model without BPX_MODEL: exit $rc"
        fi
    fi

    # demo, as README command 1 runs it: statistics and stats.json, no pictures, libpng named.
    rm -rf readme && mkdir readme && pushd readme >/dev/null || exit 2
    run demo
    [[ $rc -eq 0 ]] || fail "demo: exit $rc"
    grep -q "| 1. broad phase (bpx) |" out.txt || fail "demo: no stage table"
    [[ -s bpx-demo/stats.json ]] || fail "demo: no bpx-demo/stats.json"
    ls bpx-demo/*.png >/dev/null 2>&1 && fail "demo wrote pictures without libpng"
    if [[ $png == ON ]]; then
        grep -q "libpng16.so.16 cannot be loaded" err.txt ||
            fail "demo does not name libpng16.so.16"
    else
        grep -q "without libpng" err.txt || fail "demo does not say it runs without libpng"
    fi
    popd >/dev/null || exit 2

    # demo --window: an error that names SDL2's library.
    run demo --window --cycles 1
    [[ $rc -eq 1 ]] || fail "demo --window without SDL2: exit $rc"
    grep -Eq "libSDL2-2.0.so.0 cannot be loaded|without SDL2" err.txt ||
        fail "demo --window does not name SDL2"

    # bench: bpx's backends run with no peers; a peer asked for by name is an error saying why.
    run bench --sizes 300 --scene uniform --backend prune --seconds 0.01 --cycles 3
    [[ $rc -eq 0 ]] || fail "bench without peers: exit $rc"
    grep -q "peers: none: no peers" out.txt || fail "bench does not say there are no peers"
    run bench --sizes 300 --scene uniform --backend bullet-sap --seconds 0.01 --cycles 3
    if [[ $rc -ne 1 ]] || ! grep -q "no peers" err.txt; then
        fail "bench --backend bullet-sap: exit $rc"
    fi
}

mode=hook
checks
# One library refused by name: the others still load (pictures, when this build has libpng).
rc=0
BPX_NO_DLOPEN=libSDL2-2.0.so.0 "$bpx" demo --spheres 30 --cycles 20 --every 10 --out one \
    >out.txt 2>err.txt || rc=$?
[[ $rc -eq 0 ]] || fail "demo with SDL2 alone refused: exit $rc"
if [[ $png == ON ]] && ! grep -q "without libpng" err.txt; then
    [[ -s one/frame_000010.png && -s one/frame_000020.png ]] ||
        fail "demo with SDL2 alone refused wrote no pictures"
fi

mode=hidden
if [[ -z $masks ]]; then
    echo "note: none of the optional libraries is installed: the hidden mode is the hook mode's"
elif unshare -rm bash -c "$masks"'true' 2>/dev/null; then
    checks
else
    echo "note: unshare -rm is refused here: the libraries were hidden by the test hook only"
fi

if [[ $failures -eq 0 ]]; then
    echo "pairs, query, model, demo and bench run without libpng, SDL2, Bullet and Box2D"
    exit 0
fi
echo "$failures failure(s)" >&2
exit 1
