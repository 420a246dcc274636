#!/bin/bash
# device screen: cup at fast, 8 configs x 3 seeds, 8 jobs at a time, 2 threads each
D=$(cd "$(dirname "$0")" && pwd); B=${B:-$D/neus-aug}; S=$D/cup
lscpu | grep -E 'Model name|^CPU\(s\)|Flags' | cut -c1-200 > $OUT/cpu.txt
declare -A K=( [base]="" [eik05]="--set model.loss.eikonal=0.05" [eik20]="--set model.loss.eikonal=0.2" [mask3]="--set model.loss.mask=0.3" [win3]="--set train.depth.mvs.window_half=3" [pl256]="--set train.depth.mvs.planes=256" [rel1]="--set train.depth.mvs.rel_tol=0.001" [sw5]="--set train.depth.surface_weight=0.5" )
jobs=()
for s in 0 1 2; do for k in base eik05 eik20 mask3 win3 pl256 rel1 sw5; do jobs+=("$k $s"); done; done
run() { k=$1; s=$2; o=/tmp/r/$k-s$s; mkdir -p $OUT/$k-s$s
  t0=$(date +%s); RAYON_NUM_THREADS=2 $B reconstruct $S --preset fast --seed $s --quiet --out $o --force ${K[$k]} > $OUT/$k-s$s/log 2>&1
  echo "rc=$? secs=$(( $(date +%s)-t0 ))" >> $OUT/$k-s$s/log
  cp $o/metrics.json $o/config.toml $o/depth_auto.json $OUT/$k-s$s/ 2>/dev/null; }
export -f run; export B S OUT; export K_DEF="$(declare -p K)"
printf '%s\n' "${jobs[@]}" | xargs -P 8 -L 1 bash -c 'eval "$K_DEF"; run $0 $1'
