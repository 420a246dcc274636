#!/usr/bin/env bash
# usage: run.sh BIN SCENE SEED TAG [--set k=v ...]; skips finished runs, prints one summary line
bin=$1; s=$2; seed=$3; tag=$4; shift 4
out=/work/exp11/runs/$s-$tag-s$seed
mkdir -p /work/exp11/runs
if [ ! -f $out/metrics.json ]; then
  /work/exp11/$bin reconstruct $s --preset fast --seed $seed --quiet --out $out "$@" > $out.log 2>&1
fi
python3 -c "
import json;m=json.load(open('$out/metrics.json'));c=m['chamfer'];me=m['mesh']
print('$s-$tag-s$seed'.ljust(28), round(c['chamfer_sum'],3), 'acc',round(c['mean_d2s'],3),'comp',round(c['mean_s2d'],3),'ratio', round(m.get('ratio_to_floor') or -1,2), 'genus', me.get('largest_genus'), 'gt', m.get('gt_genus'), 'comp', me.get('raw_components'), '->', me['components'], 'nerr', round(m.get('normal_error_deg') or -1,2), 't', round(m['timings_s']['total']))" 2>&1 | tail -1
