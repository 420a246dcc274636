#!/bin/bash
# usage: BIN=./d7 TAG=h W=5 SEED=0 ./suite_h.sh  -> the depth prior on every suite scene but cup
cd /work/cup
S=${SEED:-0}
for s in blob torus thin blocks relief double-torus plate rods; do
  ${BIN:-./d3} reconstruct sc/$s --preset fast --seed $S --quiet --out r/${s}_${TAG:-d}${W}_s$S --force --set train.depth.weight=$W > r/${s}_${TAG:-d}${W}_s$S.log 2>&1
  python3 -c "
import json;m=json.load(open('r/${s}_${TAG:-d}${W}_s$S/metrics.json'));print('${s}_${TAG:-d}${W}_s$S %.3f ratio %.2f genus %s/%s nerr %.1f t %.0f'%(m['chamfer']['chamfer_sum'],m['ratio_to_floor'],m['mesh']['largest_genus'],m['gt_genus'],m['normal_error_deg'],m['timings_s']['total']))"
done
