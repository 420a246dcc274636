#!/bin/bash
# thin1 SCENE NAME BIN args...
s=$1; name=$2; bin=$3; shift 3
$bin reconstruct sc/$s --preset fast --seed ${SEED:-0} --quiet --out r/$name --force "$@" > r/$name.log 2>&1
python3 -c "
import json;m=json.load(open('r/$name/metrics.json'));print('$name %.3f ratio %.2f genus %s/%s nerr %.1f t %.0f'%(m['chamfer']['chamfer_sum'],m['ratio_to_floor'],m['mesh']['largest_genus'],m['gt_genus'],m['normal_error_deg'],m['timings_s']['total']))"
