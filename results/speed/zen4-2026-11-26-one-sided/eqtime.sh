#!/bin/bash
# quick preset scaled to 1630 steps (every schedule scaled as scale_run_length does), one-sided k=4:
# about the training time of central differences at 1400 steps (0.86x per step, sitting of 2026-11-26)
cd /work/exp14/fd
for s in 0 1 2 3; do
  SEED=$s bash /work/main/results/speed/zen4-2026-11-25-quick1400/scaled.sh ../neus-aug-fd3 1630 eq1630_s$s \
    --quiet --set model.render.fd_central_every=4 > eq1630_s$s.log 2>&1
done
