#!/bin/bash
# hard suite, fast preset, s0, one-sided differences (render.fd_central_every = 4), committed recipe otherwise
cd /work/exp14/fd
for sc in blob torus double-torus plate thin relief blocks rods cup; do
  ../neus-aug-fd3 reconstruct $sc --preset fast --seed 0 --quiet --out f4_$sc --force \
    --set model.render.fd_central_every=4 > f4_$sc.log 2>&1
done
