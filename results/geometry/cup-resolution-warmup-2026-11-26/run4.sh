#!/bin/bash
# Detached colour features (scratch: NEUS_DETACH_FEAT=1 zeroes the colour loss's gradient into the
# SDF network's feature outputs; alpha and normal paths unchanged), cup 400x300, fast, seed 0.
cd "$(dirname "$0")"
TRUTH=(--set 'train.init.kind="visual_hull"' --set train.init.photo_tau=0.07 --set train.init.resolution=192)
COMBO=(--set model.render.variance_init=0.6 --set model.render.cos_anneal_end=0 --set model.render.view_dependence=0.0)
one() { # name truth(0/1) extra...
  local name=$1 tr=$2; shift 2
  [ -f r/$name/metrics.json ] && return
  if [ "$tr" = 1 ]; then export NEUS_TRUTH_OCC=cup400.occ; else unset NEUS_TRUTH_OCC; fi
  NEUS_DETACH_FEAT=1 /usr/bin/time -f "%e" -o r/$name.time ./nc3 reconstruct sc/cup400 --preset fast --seed 0 --quiet --out r/$name --force "$@" > r/$name.log 2>&1
  python3 -c "
import json;m=json.load(open('r/$name/metrics.json'));c=m['chamfer'] or {};me=m['mesh'];t=m['train']
print('$name', round(c.get('chamfer_sum',-1),3), 'acc', round(c.get('mean_d2s',-1),3), 'comp', round(c.get('mean_s2d',-1),3), 'x floor', round(m.get('ratio_to_floor') or -1,1), 'genus', me.get('largest_genus'), 'nerr', round(m.get('normal_error_deg') or -1,1), 'psnr', round(m['psnr_heldout'],2), 'inv_s', round(t['final_inv_s']), 'wall', open('r/$name.time').read().strip())"
}
one d-t-combo 1 "${TRUTH[@]}" "${COMBO[@]}"
one d-plain 0
