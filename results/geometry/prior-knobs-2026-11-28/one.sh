#!/bin/bash
# one NAME BIN args... ; env passes through
name=$1; bin=$2; shift 2
/usr/bin/time -f "%e s" $bin reconstruct sc/cup400 --preset fast --seed ${SEED:-0} --quiet --out r/$name --force "$@" > r/$name.log 2>&1
python3 - r/$name <<'PY'
import json,sys
m=json.load(open(sys.argv[1]+'/metrics.json'))
c=m['chamfer']; t=m.get('topology') or {}
print(sys.argv[1], 'chamfer %.3f acc %.3f comp %.3f'%(c['chamfer_sum'],c['mean_d2s'],c['mean_s2d']), 'nerr %.1f'%m['normal_error_deg'], 'genus', m.get('genus_matches'), 'psnr %.2f'%m['psnr_heldout'])
PY
tail -1 r/$name.log
