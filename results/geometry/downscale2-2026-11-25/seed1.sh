#!/usr/bin/env bash
cd "$(dirname "$0")"   # beside a binary na9 (commit 7602d98, built with target-cpu=native)
while pgrep -f 'q-ds2[.]sh' >/dev/null; do sleep 5; done
for s in thin plate; do for v in ds1 ds2; do
  out=r/$s-$v-s1
  [ -f $out/metrics.json ] && continue
  extra=""; [ $v = ds2 ] && extra="--set data.downscale=2 --set data.render_downscale=1"
  ./na9 reconstruct $s --preset fast --seed 1 --quiet --out $out $extra > $out.log 2>&1
  python3 -c "
import json;m=json.load(open('$out/metrics.json'));c=m['chamfer'];me=m['mesh']
print('$s $v s1', round(c['chamfer_sum'],3), 'ratio', round(m.get('ratio_to_floor') or -1,2), 'genus', me.get('largest_genus'), 'gt', m.get('gt_genus'), 'comp', me.get('raw_components'), '->', me['components'], 'nerr', round(m.get('normal_error_deg'),2), 't', round(m['timings_s']['total']))"
done; done
