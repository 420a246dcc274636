#!/bin/bash
# cup at 400x300 (the catalogue's) and 800x600 (`synth cup --resolution 800x600`), fast preset, seed 0:
# truth start + the best schedule of results/geometry/cup-truth-start-2026-11-26 (combo), and plain fast.
cd "$(dirname "$0")"
TRUTH=(--set 'train.init.kind="visual_hull"' --set train.init.photo_tau=0.07 --set train.init.resolution=192)
COMBO=(--set model.render.variance_init=0.6 --set model.render.cos_anneal_end=0 --set model.render.view_dependence=0.0)
one() { # name scene occ extra...
  local name=$1 scene=$2 occ=$3; shift 3
  [ -f r/$name/metrics.json ] && return
  mkdir -p r
  if [ -n "$occ" ]; then export NEUS_TRUTH_OCC=$occ; else unset NEUS_TRUTH_OCC; fi
  /usr/bin/time -f "%e" -o r/$name.time ./nc reconstruct sc/$scene --preset fast --seed 0 --quiet --out r/$name --force "$@" > r/$name.log 2>&1
  python3 -c "
import json;m=json.load(open('r/$name/metrics.json'));c=m['chamfer'];me=m['mesh']
print('$name', round(c['chamfer_sum'],3), 'acc', round(c['mean_d2s'],3), 'comp', round(c['mean_s2d'],3), 'x floor', round(m.get('ratio_to_floor') or -1,1), 'genus', me.get('largest_genus'), 'nerr', round(m.get('normal_error_deg') or -1,1), 'wall', open('r/$name.time').read().strip())"
}
one t400-combo cup400 cup400.occ "${TRUTH[@]}" "${COMBO[@]}"
one t800-combo cup800 cup400.occ "${TRUTH[@]}" "${COMBO[@]}"
one p800 cup800 ""
one t800 cup800 cup400.occ "${TRUTH[@]}"
