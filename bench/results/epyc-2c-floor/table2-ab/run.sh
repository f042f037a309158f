#!/bin/sh
# Table 2 A/B: base = commit 95ee184's library with this branch's bench (centres copied untimed),
# new = this branch; alternating runs, one thread, Bullet's sweep and prunes beside.
out=$1; runs=${2:-3}
for r in $(seq $runs); do
  for v in base new; do
    mkdir -p $out/$v-$r
    echo "=== $v run $r: BPX_PEERS_MODULE=/tmp/wtf-$v/bpx_peers.so /tmp/wtf-$v/bpx bench --table2 --threads 1 --backend brute,prune,auto,bullet-sap,bullet-sap32 --cycles 10000 --out $out/$v-$r"
    BPX_PEERS_MODULE=/tmp/wtf-$v/bpx_peers.so /tmp/wtf-$v/bpx bench --table2 --threads 1 --backend brute,prune,auto,bullet-sap,bullet-sap32 --cycles 10000 --out $out/$v-$r > /dev/null 2>&1
  done
done
