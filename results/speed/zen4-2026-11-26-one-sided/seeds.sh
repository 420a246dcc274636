#!/bin/bash
cd /work/exp14/fd
for s in 2 3; do for k in 1 2 4; do
  ../neus-aug-fd2 reconstruct blob --preset quick --seed $s --quiet --out q_s${s}_k$k --force --set model.render.fd_central_every=$k > q_s${s}_k$k.log 2>&1
done; done
