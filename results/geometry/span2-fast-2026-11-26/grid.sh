#!/bin/bash
# span 2, k = 4, fast preset: holes grid (the none s0/s1 runs are in /work/exp18) and suite seed 2
B=./neus-aug-span
F="--set model.render.fd_central_every=4 --set model.render.fd_one_sided_span=2.0"
run() { # name scene seed aug
  [ -f $1/metrics.json ] && return
  /usr/bin/time -f "%e s" $B reconstruct $2 --preset fast --seed $3 --aug $4 --quiet --out $1 $F > $1.log 2>&1
}
for s in 0 1 2; do
  for sc in torus double-torus; do
    for a in sia dia; do run sp2-$sc-$a-s$s $sc $s $a; done
  done
done
for sc in torus double-torus; do run sp2-$sc-s2 $sc 2 none; done
for sc in blob plate thin relief blocks rods; do run sp2-$sc-s2 $sc 2 none; done
echo done > grid.done
