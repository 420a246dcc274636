#!/usr/bin/env bash
# fast + half-size training images on the hard scenes, seed 0 (held-out renders at fast's size).
cd "$(dirname "$0")"   # beside a binary na9 (commit 7602d98, built with target-cpu=native)
for s in relief blocks thin plate double-torus cup; do
  out=r/$s-s0
  [ -f $out/metrics.json ] && continue
  ./na9 reconstruct $s --preset fast --seed 0 --quiet --out $out \
    --set data.downscale=2 --set data.render_downscale=1 > $out.log 2>&1
  python3 -c "
import json;m=json.load(open('$out/metrics.json'));c=m['chamfer'];me=m['mesh']
print('$s', round(c['chamfer_sum'],3), 'ratio', round(m.get('ratio_to_floor') or -1,2), 'genus', me.get('largest_genus'), 'gt', m.get('gt_genus'), 'comp', me.get('raw_components'), '->', me['components'], 'nerr', m.get('normal_error_deg'), 't', round(m['timings_s']['total']))"
done
