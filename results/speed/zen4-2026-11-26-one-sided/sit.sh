#!/bin/bash
# Field bench sitting on Zen 4 (issue 14, one-sided differences): old (7524d2f) against new
# (this change), x86-64-v3 and native builds, interleaved old/new/new/old, machine idle.
cd /work/exp14/sit
mkdir -p bench
declare -A B=([old-v3]=/work/tgt-old-v3/release/deps/field-888ad52637d5f02a [new-v3]=/work/tgt-v3/release/deps/field-888ad52637d5f02a [old-n]=/work/tgt-old-n/release/deps/field-4bfe497daf268df4 [new-n]=/work/tgt-native/release/deps/field-4bfe497daf268df4)
bench() { tag=$1; name=$2; ( cd /tmp && NEUS_AUG_BENCH_QUICK=1 ${B[$tag]} --bench ) > bench/$name.log 2>&1; echo "$(date +%T) $name $(grep -E 'train_step alone' bench/$name.log | tr -s ' ' | tr '\n' '|')" >> sit.out; }
echo "$(date +%T) start $(cat /proc/loadavg)" >> sit.out
bench old-v3 old-v3-1; bench new-v3 new-v3-1; bench new-v3 new-v3-2; bench old-v3 old-v3-2
bench old-n old-n-1; bench new-n new-n-1; bench new-n new-n-2; bench old-n old-n-2
echo "$(date +%T) done $(cat /proc/loadavg)" >> sit.out
# End to end: the quick preset on the default scene, central against one-sided (native build of this change)
run() { k=$1; name=$2; /work/exp14/neus-aug-fd3 reconstruct blob --preset quick --seed 0 --quiet --out runs/$name --force --set model.render.fd_central_every=$k > runs/$name.log 2>&1; echo "$(date +%T) $name $(python3 -c "import json;m=json.load(open('runs/$name/metrics.json'));print(round(m['chamfer']['chamfer_sum'],4), m['timings_s']['train'], m['timings_s']['total'])")" >> sit.out; }
mkdir -p runs
run 1 quick-k1-a; run 4 quick-k4-a; run 4 quick-k4-b; run 1 quick-k1-b
echo "$(date +%T) done e2e $(cat /proc/loadavg)" >> sit.out
