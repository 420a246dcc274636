#!/usr/bin/env bash
# Device-box session script: CPU facts, old/new field bench (x86-64-v3 builds, 2 threads,
# idle), then fast-preset runs in parallel (2 threads each) for the seed-2 suite gaps.
set -u
D=target-dev
mkdir -p $OUT/runs
{ lscpu; grep -o -w 'avx512f\|avx2\|fma' /proc/cpuinfo | sort | uniq -c; nproc; } > $OUT/cpu.txt 2>&1
export RAYON_NUM_THREADS=2
for who in old new new old; do
  echo "== $who $(date +%T)" >> $OUT/bench.out
  NEUS_AUG_BENCH_QUICK=1 taskset -c 0,1 $D/bench-$who-v3 --bench >> $OUT/bench.out 2>&1
done
run() { s=$1; seed=$2; o=$OUT/runs/$s-vis-s$seed
  mkdir -p $o; $D/neus-aug-v3 reconstruct $s --preset fast --seed $seed --quiet --out /tmp/r-$s-$seed > $o/log 2>&1
  cp /tmp/r-$s-$seed/metrics.json /tmp/r-$s-$seed/config.toml $o/ 2>/dev/null; }
i=2
for job in "blob 2" "plate 2" "relief 2" "blocks 2" "thin 2" "blob 0"; do
  set -- $job
  ( taskset -c $i,$((i+1)) bash -c "$(declare -f run); OUT=$OUT D=$D run $1 $2" ) &
  i=$((i+2))
done
wait
echo done >> $OUT/bench.out
