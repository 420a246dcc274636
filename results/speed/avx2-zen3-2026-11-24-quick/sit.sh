#!/bin/bash
# Two interleaved sittings: old fast preset against new quick preset, native and x86-64-v3 builds,
# then the field bench (quick mode: FMA peak + the default network's iteration) old/new per ISA.
cd /work/exp6
while pgrep -f 'build2.sh' >/dev/null || pgrep -f 'bash build.sh' >/dev/null; do sleep 5; done
mapfile -t EXES < <(grep -o '(/[^)]*field-[0-9a-f]*)' build2.log | tr -d '()')
# order in build2: new-v3, old-v3, new-native, old-native
declare -A B=([new-v3]=${EXES[0]} [old-v3]=${EXES[1]} [new-n]=/work/main/${EXES[2]} [old-n]=/work/wt-old/${EXES[3]})
run() { bin=$1; name=$2; preset=$3; mkdir -p r; /usr/bin/time -v ./$bin reconstruct --preset $preset --seed 0 --quiet --out r/$name > r/$name.log 2> r/$name.time; echo "$(date +%T) $name $(grep chamfer_sum r/$name.log) $(grep Elapsed r/$name.time)" >> sit.out; }
bench() { tag=$1; name=$2; mkdir -p b; ( cd /tmp && NEUS_AUG_BENCH_QUICK=1 ${B[$tag]} --bench ) > b/$name.log 2>&1; echo "$(date +%T) bench $name $(grep -i 'train_step' b/$name.log | head -2 | tr '\n' ' ')" >> sit.out; }
echo "$(date +%T) sitting 1 $(cat /proc/loadavg)" >> sit.out
run na-old old-n-1 fast
run na new-n-1 quick
run na-old-v3 old-v3-1 fast
run na-v3 new-v3-1 quick
bench old-v3 old-v3-1; bench new-v3 new-v3-1; bench old-n old-n-1; bench new-n new-n-1
echo "$(date +%T) sitting 2 $(cat /proc/loadavg)" >> sit.out
bench new-n new-n-2; bench old-n old-n-2; bench new-v3 new-v3-2; bench old-v3 old-v3-2
run na-v3 new-v3-2 quick
run na-old-v3 old-v3-2 fast
run na new-n-2 quick
run na-old old-n-2 fast
echo "$(date +%T) done" >> sit.out
