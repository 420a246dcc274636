#!/bin/bash
# Field bench sitting on Zen 4 (issue 14, PANEL_KC = 64): old (7524d2f), base (ccf1141) and new
# (this change), x86-64-v3 interleaved old/base/new/new/base/old, then native old/new/new/old.
cd /work/exp15/sit
mkdir -p bench
declare -A B=([old-v3]=/work/tgt-old-v3/release/deps/field-888ad52637d5f02a [base-v3]=/work/tgt-v3-base/release/deps/field-888ad52637d5f02a [new-v3]=/work/tgt-v3/release/deps/field-888ad52637d5f02a [old-n]=/work/tgt-old-n/release/deps/field-4bfe497daf268df4 [new-n]=/work/tgt-native/release/deps/field-4bfe497daf268df4)
bench() { tag=$1; name=$2; ( cd /tmp && NEUS_AUG_BENCH_QUICK=1 ${B[$tag]} --bench ) > bench/$name.log 2>&1; echo "$(date +%T) $name $(grep -E 'train_step alone' bench/$name.log | tr -s ' ' | tr '\n' '|')" >> sit.out; }
echo "$(date +%T) start $(cat /proc/loadavg)" >> sit.out
bench old-v3 old-v3-1; bench base-v3 base-v3-1; bench new-v3 new-v3-1; bench new-v3 new-v3-2; bench base-v3 base-v3-2; bench old-v3 old-v3-2
bench old-n old-n-1; bench new-n new-n-1; bench new-n new-n-2; bench old-n old-n-2
echo "$(date +%T) done $(cat /proc/loadavg)" >> sit.out
