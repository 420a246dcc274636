#!/bin/bash
# One cup run per argument 'NAME SCENE SEED [flags...]' (flags may use the arrays below), with the
# binary $BIN; with TRUTH_OCC set, the scratch binary starts from that truth occupancy
# (NEUS_TRUTH_OCC of ../cup-resolution-warmup-2026-11-26/scratch.patch), and NEUS_GEOM_FREEZE
# passes through. Prints one summary line per run. The invocations of this record:
# († = the faulty build `cg`, see README)
#   BIN=./cg  run.sh 'cg-s0 sc/cup400 0 "${CG[@]}"' (and s1, s2) †
#   BIN=./cg  run.sh 'cgs-s0 sc/cup400 0 "${CG[@]}" --set model.field.color_grid.grid.n_levels=12
#                     --set model.field.color_grid.grid.log2_hashmap_size=15
#                     --set model.field.color_grid.grid.base_resolution=16.0' †
#   BIN=./cg  run.sh 'cg-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}"' †
#   BIN=./cgx TRUTH_OCC=cup400.occ run.sh 'cgt-combo sc/cup400 0 "${TRUTH[@]}" "${COMBO[@]}" "${CG[@]}"'
#   BIN=./cgx TRUTH_OCC=cup400.occ NEUS_GEOM_FREEZE=2000 run.sh 'cgg2000 ...same flags...'
#   BIN=./cgx TRUTH_OCC=cup400.occ NEUS_GEOM_FREEZE=1000 run.sh 'cgg1000 ...same flags...'
#   BIN=./cg2 run.sh 'cg2-cav-s0 sc/cup400 0 "${CG[@]}" "${CAV[@]}"' (and s1, s2)
#   BIN=./cg2 run.sh 'plain-s0 sc/cup400 0'
#   BIN=./cg2 run.sh 'cg2-s1 sc/cup400 1 "${CG[@]}"' (and s2)
cd "$(dirname "$0")"
TRUTH=(--set 'train.init.kind="visual_hull"' --set train.init.photo_tau=0.07 --set train.init.resolution=192)
COMBO=(--set model.render.variance_init=0.6 --set model.render.cos_anneal_end=0 --set model.render.view_dependence=0.0)
CAV=(--set 'train.init.kind="visual_hull"' --set train.init.photo_tau=0.07 --set model.render.variance_init=0.6 --set model.render.cos_anneal_end=0)
CG=(--set model.field.color_grid.enabled=true)
one() { # name scene seed extra...
  local name=$1 scene=$2 seed=$3; shift 3
  [ -f r/$name/metrics.json ] && return
  if [ -n "$TRUTH_OCC" ]; then export NEUS_TRUTH_OCC=$TRUTH_OCC; fi
  /usr/bin/time -f "%e" -o r/$name.time $BIN reconstruct $scene --preset fast --seed $seed --quiet --out r/$name --force "$@" > r/$name.log 2>&1
  python3 -c "
import json;m=json.load(open('r/$name/metrics.json'));c=m['chamfer'] or {};me=m['mesh'];t=m['train']
print('$name', round(c.get('chamfer_sum',-1),3), 'acc', round(c.get('mean_d2s',-1),3), 'comp', round(c.get('mean_s2d',-1),3), 'x floor', round(m.get('ratio_to_floor') or -1,1), 'genus', me.get('largest_genus'), 'nerr', round(m.get('normal_error_deg') or -1,1), 'psnr', round(m['psnr_heldout'],2), 'inv_s', round(t['final_inv_s']), 'wall', open('r/$name.time').read().strip())"
}
for spec in "$@"; do eval "one $spec"; done
