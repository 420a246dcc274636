#!/bin/bash
# Colour warm-up / fixed-sharpness probe (scratch patch in nc2: NEUS_GEOM_FREEZE=N keeps hash grid,
# SDF MLP and variance fixed, gradients and all, for the first N of fast's 2000 steps;
# NEUS_VAR_FREEZE=1 keeps the variance at its start for the whole run), from the truth start,
# cup 400x300, seed 0, with the combo schedule (var06, no anneal, no view dependence).
cd "$(dirname "$0")"
TRUTH=(--set 'train.init.kind="visual_hull"' --set train.init.photo_tau=0.07 --set train.init.resolution=192)
COMBO=(--set model.render.variance_init=0.6 --set model.render.cos_anneal_end=0 --set model.render.view_dependence=0.0)
one() { # name geom-freeze var-freeze(0/1) extra...
  local name=$1 fr=$2 vf=$3; shift 3
  [ -f r/$name/metrics.json ] && return
  if [ "$vf" = 1 ]; then export NEUS_VAR_FREEZE=1; else unset NEUS_VAR_FREEZE; fi
  NEUS_TRUTH_OCC=cup400.occ NEUS_GEOM_FREEZE=$fr /usr/bin/time -f "%e" -o r/$name.time ./nc2 reconstruct sc/cup400 --preset fast --seed 0 --quiet --out r/$name --force "$@" > r/$name.log 2>&1
  python3 -c "
import json;m=json.load(open('r/$name/metrics.json'));c=m['chamfer'] or {};me=m['mesh'];t=m['train']
print('$name', round(c.get('chamfer_sum',-1),3), 'acc', round(c.get('mean_d2s',-1),3), 'comp', round(c.get('mean_s2d',-1),3), 'x floor', round(m.get('ratio_to_floor') or -1,1), 'genus', me.get('largest_genus'), 'nerr', round(m.get('normal_error_deg') or -1,1), 'psnr', round(m['psnr_heldout'],2), 'inv_s', round(t['final_inv_s']), 'wall', open('r/$name.time').read().strip())"
}
one g2000 2000 0 "${TRUTH[@]}" "${COMBO[@]}"
one g1000 1000 0 "${TRUTH[@]}" "${COMBO[@]}"
one v-combo 0 1 "${TRUTH[@]}" "${COMBO[@]}"
one g1000-v 1000 1 "${TRUTH[@]}" "${COMBO[@]}"
