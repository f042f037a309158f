#!/bin/sh
# Table 2: 95ee184 as it was (library and bench: centres read from the recording inside the timed cycle) against this branch, alternating.
out=$1; runs=${2:-2}
for r in $(seq $runs); do
  for v in before new; do
    mkdir -p $out/$v-$r
    echo "=== $v run $r: BPX_PEERS_MODULE=/tmp/wtf-$v/bpx_peers.so /tmp/wtf-$v/bpx bench --table2 --threads 1 --backend brute,prune,auto,bullet-sap,bullet-sap32 --cycles 10000 --out $out/$v-$r"
    BPX_PEERS_MODULE=/tmp/wtf-$v/bpx_peers.so /tmp/wtf-$v/bpx bench --table2 --threads 1 --backend brute,prune,auto,bullet-sap,bullet-sap32 --cycles 10000 --out $out/$v-$r > /dev/null 2>&1
  done
done
