#!/bin/bash
# seed 1 on the rest of the suite (fast preset, render.fd_central_every = 4), after suite_s1.sh
cd /work/exp14/fd
while pgrep -f suite_s1.sh > /dev/null; do sleep 5; done
for sc in double-torus plate relief blocks rods; do
  ../neus-aug-fd3 reconstruct $sc --preset fast --seed 1 --quiet --out f4s1_$sc --force \
    --set model.render.fd_central_every=4 > f4s1_$sc.log 2>&1
done
