#!/usr/bin/env bash
# Same 400x300 training resolution as fast, but from 800x600 renders area-averaged by 2 (soft
# masks and colours at edges): separates "half resolution" from "averaged edge pixels".
cd "$(dirname "$0")"   # beside a binary na9 one folder up (commit 7602d98, native build)
for s in thin relief plate; do
  [ -f sc/$s/meta.json ] || ../na9 synth $s --resolution 800x600 --out sc/$s --quiet | grep '^floor' | sed "s/^/$s /"
done
for r in thin:0 relief:0 plate:0 thin:1; do s=${r%:*}; seed=${r#*:}
  out=r/$s-hr-s$seed; mkdir -p r
  [ -f $out/metrics.json ] && continue
  ../na9 reconstruct sc/$s --preset fast --seed $seed --quiet --out $out --set data.downscale=2 > $out.log 2>&1
  python3 -c "
import json;m=json.load(open('$out/metrics.json'));c=m['chamfer'];me=m['mesh']
print('$s hr s$seed', round(c['chamfer_sum'],3), 'ratio', round(m.get('ratio_to_floor') or -1,2), 'genus', me.get('largest_genus'), 'gt', m.get('gt_genus'), 'comp', me.get('raw_components'), '->', me['components'], 'nerr', round(m.get('normal_error_deg'),2), 't', round(m['timings_s']['total']))"
done
