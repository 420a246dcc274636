#!/bin/bash
# Device: 8 fast runs at once, two threads each on disjoint core pairs, span 2 k = 4, x86-64-v3 binary.
set -u
B=$PWD/devrun/neus-aug
lscpu > $OUT/cpu.txt 2>&1
F="--set model.render.fd_central_every=4 --set model.render.fd_one_sided_span=2.0"
i=0
for spec in blob:2:none plate:2:none thin:2:none relief:2:none blocks:2:none rods:2:none torus:0:sia blob:0:none; do
  IFS=: read sc s a <<< "$spec"
  n=sp2-$sc-$([ $a = none ] || echo $a-)s$s
  c0=$((2*i)); c1=$((2*i+1))
  ( RAYON_NUM_THREADS=2 taskset -c $c0,$c1 /usr/bin/time -f "%e s" $B reconstruct $sc --preset fast --seed $s --aug $a --quiet --out /tmp/r/$n $F > $OUT/$n.log 2>&1
    mkdir -p $OUT/runs/$n && cp /tmp/r/$n/config.toml /tmp/r/$n/metrics.json $OUT/runs/$n/ ) &
  i=$((i+1))
done
wait
echo all done
