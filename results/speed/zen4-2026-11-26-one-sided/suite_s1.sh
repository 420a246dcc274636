#!/bin/bash
# seed 1 check of the one-sided cost on three scenes (fast preset, render.fd_central_every = 4)
cd /work/exp14/fd
for sc in blob torus thin; do
  ../neus-aug-fd3 reconstruct $sc --preset fast --seed 1 --quiet --out f4s1_$sc --force \
    --set model.render.fd_central_every=4 > f4s1_$sc.log 2>&1
done
