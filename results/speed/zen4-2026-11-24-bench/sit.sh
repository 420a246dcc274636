#!/bin/bash
# Field bench sitting on Zen 4: old (7524d2f) against new (HEAD), x86-64-v3 and native builds,
# interleaved (ABBA), three rounds each, machine otherwise idle (other jobs SIGSTOPped).
cd /work/exp7
exe() { ls /work/exp7/$1/release/deps/field-* | grep -v '\.d$' | head -1; }
declare -A B=([new-v3]=$(exe t-new-v3) [old-v3]=$(exe t-old-v3) [new-n]=$(exe t-new-n) [old-n]=$(exe t-old-n))
bench() { tag=$1; name=$2; ( cd /tmp && NEUS_AUG_BENCH_QUICK=1 ${B[$tag]} --bench ) > bench/$name.log 2>&1; echo "$(date +%T) bench $name $(grep -E 'train_step alone' bench/$name.log | tr -s ' ')" >> sit.out; }
echo "$(date +%T) start $(cat /proc/loadavg)" >> sit.out
bench old-v3 old-v3-1; bench new-v3 new-v3-1; bench new-v3 new-v3-2; bench old-v3 old-v3-2
bench old-n old-n-1; bench new-n new-n-1; bench new-n new-n-2; bench old-n old-n-2
bench old-v3 old-v3-3; bench new-v3 new-v3-3; bench old-n old-n-3; bench new-n new-n-3
echo "$(date +%T) done $(cat /proc/loadavg)" >> sit.out
