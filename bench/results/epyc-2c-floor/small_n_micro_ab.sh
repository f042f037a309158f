#!/bin/sh
# A/B: before and after libbpx, same micro, alternating; prints the median of each run.
reps=${1:-5}; shift
for n in 50 200 500; do
  for r in $(seq $reps); do
    for v in before after; do
      printf "%s " $v; /tmp/wtf-micro-$v $n auto 5000 1 avx512 1
    done
  done
done
