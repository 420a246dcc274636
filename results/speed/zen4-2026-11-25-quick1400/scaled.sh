#!/bin/bash
# usage: scaled.sh BIN N TAG [extra --set...]   quick preset scaled to N iterations
BIN=$1; N=$2; TAG=$3; shift 3
k=$(python3 -c "print($N/2000)")
r(){ python3 -c "print(round($1*$k))"; }
dec=$(python3 -c "print(0.95**(20000/$N))")
$BIN reconstruct ${SCENE:-} --preset quick --seed ${SEED:-0} --out /work/exp9/runs/$TAG --force \
  --set train.iterations=$N --set model.render.cos_anneal_end=$N \
  --set train.lr.constant_steps=$(r 500) --set train.lr.warmup_steps=$(r 100) \
  --set model.render.occupancy.ema_decay=$dec \
  --set model.field.hash_grid.progressive.update_steps=$(r 100) \
  --set "model.loss.curvature=[$((N/2)), 0, 0.0005, $((N*3/5))]" "$@"
