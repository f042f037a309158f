#!/bin/sh
# Weak (100k boxes per rank) and strong (1M boxes) scaling of libbpx_mpi over 1..8 ranks on
# this machine, oversubscribed where there are fewer cores. Usage: mpi/bench/run.sh [BUILD_DIR]
set -eu
build=${1:-build/release}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl=self,vader
bench="$build/mpi/bench/bpx_mpibench"
header=--header
for scene in "" --heavy; do
    for n in 1 2 3 4 8; do
        mpiexec -n $n --oversubscribe "$bench" --weak 100000 --cycles 8 $scene $header
        header=
    done
done
for n in 1 2 4 8; do
    mpiexec -n $n --oversubscribe "$bench" --strong 1000000 --cycles 6
done
