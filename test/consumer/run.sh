#!/bin/sh
# Installs bpx from the build tree into a scratch prefix, builds the example against it with
# find_package and with pkg-config, and runs the three programs.
# usage: run.sh SOURCE_DIR BUILD_DIR SCRATCH_DIR
set -eu
src=$1 build=$2 scratch=$3
rm -rf "$scratch"
cmake --install "$build" --prefix "$scratch/prefix" >/dev/null
export PKG_CONFIG_PATH="$scratch/prefix/lib/pkgconfig:$scratch/prefix/lib64/pkgconfig"
cmake -S "$src/test/consumer" -B "$scratch/build" -DCMAKE_PREFIX_PATH="$scratch/prefix" \
      -DEXAMPLE="$src/examples/frame_loop.c" >/dev/null
cmake --build "$scratch/build" >/dev/null
for exe in with_cmake with_cmake_static with_pkgconfig; do
    LD_LIBRARY_PATH="$scratch/prefix/lib:$scratch/prefix/lib64" "$scratch/build/$exe" \
        > "$scratch/$exe.txt"
    if ! cmp -s "$scratch/$exe.txt" "$src/test/consumer/expected.txt"; then
        echo "FAIL: $exe printed:"; cat "$scratch/$exe.txt"; exit 1
    fi
    echo "$exe: ok"
done
