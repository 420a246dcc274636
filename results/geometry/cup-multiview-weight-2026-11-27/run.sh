#!/bin/bash
# One cup run per argument 'NAME SCENE SEED [flags...]' (flags may use the arrays below) with the
# binary $BIN (default ./mvr, a release build of this record's commit); prints one summary line
# per run. Scene: neus-aug synth cup --out sc/cup400. The invocations of this record:
#   BIN=./mvh run.sh 'mv5-cav-s1 sc/cup400 1 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=5.0'
#   BIN=./mvh run.sh 'mv2-cav-s1 sc/cup400 1 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=2.0'
#   run.sh 'mv5-cav-s2 sc/cup400 2 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=5.0'
#   run.sh 'mv5-cav-s0-rerun sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=5.0'
#   run.sh 'mv10-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=10.0'
#   run.sh 'mvramp5-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=5.0 --set train.multiview.final_weight=0.5'
#   run.sh 'mvramp10-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=10.0 --set train.multiview.final_weight=1.0'
#   run.sh 'mvramp10-cav-s1 sc/cup400 1 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=10.0 --set train.multiview.final_weight=1.0'
#   run.sh 'mvramp20-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=20.0 --set train.multiview.final_weight=2.0'
#   run.sh 'mvramp10r512-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=10.0 --set train.multiview.final_weight=1.0 --set train.multiview.rays=512'
#   run.sh 'mvramp10mc3-cav-s1 sc/cup400 1 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=10.0 --set train.multiview.final_weight=1.0 --set train.multiview.min_cos=0.3'
#   run.sh 'mv5r160-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=5.0 --set train.init.resolution=160'
#   run.sh 'mv5k2-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=5.0 --set train.multiview.top_k=2'
#   BIN=./mvs05.sh run.sh 'mvramp10g05-cav-s1 sc/cup400 1 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=10.0 --set train.multiview.final_weight=1.0'
#   BIN=./mvs05.sh run.sh 'mvramp10g05mc3-cav-s1 sc/cup400 1 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=10.0 --set train.multiview.final_weight=1.0 --set train.multiview.min_cos=0.3'
#   BIN=./mvs05.sh run.sh 'mvramp10g05mc3-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=10.0 --set train.multiview.final_weight=1.0 --set train.multiview.min_cos=0.3'
#   BIN=./mvs05.sh run.sh 'mv5g05-cav-s1 sc/cup400 1 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=5.0'
#   BIN=./mvs05.sh run.sh 'mv5g05-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}" --set train.multiview.weight=5.0'
#   BIN=./mvtruth.sh run.sh 'mv5-truth sc/cup400 0 "${CG[@]}" "${TRUTH[@]}" --set model.render.variance_init=0.6 --set model.render.cos_anneal_end=0 --set train.multiview.weight=5.0'
#   BIN=./mvtruth.sh run.sh 'mvramp10-truth sc/cup400 0 "${CG[@]}" "${TRUTH[@]}" --set model.render.variance_init=0.6 --set model.render.cos_anneal_end=0 --set train.multiview.weight=10.0 --set train.multiview.final_weight=1.0'
# mvs05.sh:   NEUS_MV_MIN_GRAD=0.5 exec ./mvs "$@"   (mvs = mvr + min-grad-scratch.patch)
# mvtruth.sh: NEUS_TRUTH_OCC=cup400.occ exec ./mvtruth "$@"   (mvtruth = mvr + the truth-start
#             patch of ../cup-truth-start-2026-11-26; cup400.occ from its occ.py at 192³)
cd "$(dirname "$0")"
BIN=${BIN:-./mvr}
CAV=(--set 'train.init.kind="visual_hull"' --set train.init.photo_tau=0.07 --set model.render.variance_init=0.6 --set model.render.cos_anneal_end=0)
TRUTH=(--set 'train.init.kind="visual_hull"' --set train.init.photo_tau=0.07 --set train.init.resolution=192)
CG=(--set model.field.color_grid.enabled=true)
one() { # name scene seed extra...
  local name=$1 scene=$2 seed=$3; shift 3
  [ -f r/$name/metrics.json ] && return
  /usr/bin/time -f "%e" -o r/$name.time $BIN reconstruct $scene --preset fast --seed $seed --quiet --out r/$name --force "$@" > r/$name.log 2>&1
  python3 -c "
import json;m=json.load(open('r/$name/metrics.json'));c=m['chamfer'] or {};me=m['mesh'];t=m['train']
print('$name', round(c.get('chamfer_sum',-1),3), 'acc', round(c.get('mean_d2s',-1),3), 'comp', round(c.get('mean_s2d',-1),3), 'x floor', round(m.get('ratio_to_floor') or -1,1), 'genus', me.get('largest_genus'), 'nerr', round(m.get('normal_error_deg') or -1,1), 'psnr', round(m['psnr_heldout'],2), 'inv_s', round(t['final_inv_s']), 'mv', (t.get('multiview_last') or {}).get('mean_cost'), (t.get('multiview_last') or {}).get('used'), 'wall', open('r/$name.time').read().strip())"
}
mkdir -p r
for spec in "$@"; do eval "one $spec"; done
