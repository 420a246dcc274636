#!/bin/bash
# One cup run per argument 'NAME SCENE SEED [flags...]' (flags may use the arrays below) with the
# binary ./mv (this record's working tree, release build); prints one summary line per run.
# The invocations of this record (scene: neus-aug synth cup --out sc/cup400):
#   run.sh 'mv-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" "${MV[@]}"'
#   run.sh 'mv2-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=2.0'
#   run.sh 'mvr-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=0.5 --set train.multiview.rays=1024'
#   run.sh 'mv-s0 sc/cup400 0 "${CG[@]}" "${MV[@]}"'
#   run.sh 'mvnocg-cav-s0 sc/cup400 0 "${CAV[@]}" "${MV[@]}"'
#   run.sh 'mv5-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=5.0'
#   run.sh 'mv2p5-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=2.0 --set train.multiview.patch_half=5'
#   run.sh 'mv2-s0 sc/cup400 0 "${CG[@]}" --set train.multiview.weight=2.0'
# The suite: ./mv study hard --seeds 1 --set train.multiview.weight=0.5 --out study-mv
#   run.sh 'mvs500-rods-s0 rods 0 --set train.multiview.weight=0.5 --set train.multiview.start_step=500'
# The rods failure with progress, first 60 s of each (rods-first-steps.txt):
#   ./mv reconstruct rods --preset fast --seed 0 --out tmp/rods-mv --force --set train.multiview.weight=0.5
#   ./mv reconstruct rods --preset fast --seed 0 --out tmp/rods-plain --force
# Parts and accuracy: python parts.py (../cup-parts-2026-11-25) and acc.py, sc/cup400 MESH...
cd "$(dirname "$0")"
CAV=(--set 'train.init.kind="visual_hull"' --set train.init.photo_tau=0.07 --set model.render.variance_init=0.6 --set model.render.cos_anneal_end=0)
MV=(--set train.multiview.weight=0.5)
CG=(--set model.field.color_grid.enabled=true)
one() { # name scene seed extra...
  local name=$1 scene=$2 seed=$3; shift 3
  [ -f r/$name/metrics.json ] && return
  /usr/bin/time -f "%e" -o r/$name.time ./mv reconstruct $scene --preset fast --seed $seed --quiet --out r/$name --force "$@" > r/$name.log 2>&1
  python3 -c "
import json;m=json.load(open('r/$name/metrics.json'));c=m['chamfer'] or {};me=m['mesh'];t=m['train']
print('$name', round(c.get('chamfer_sum',-1),3), 'acc', round(c.get('mean_d2s',-1),3), 'comp', round(c.get('mean_s2d',-1),3), 'x floor', round(m.get('ratio_to_floor') or -1,1), 'genus', me.get('largest_genus'), 'nerr', round(m.get('normal_error_deg') or -1,1), 'psnr', round(m['psnr_heldout'],2), 'inv_s', round(t['final_inv_s']), 'mv', (t.get('multiview_last') or {}).get('mean_cost'), (t.get('multiview_last') or {}).get('used'), 'wall', open('r/$name.time').read().strip())"
}
for spec in "$@"; do eval "one $spec"; done
