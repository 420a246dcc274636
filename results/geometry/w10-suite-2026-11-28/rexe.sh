#!/bin/bash
# rexe.sh SRC DST TOL [COS]: re-extract with the evidence rule for one-view faces
src=$1; dst=$2; tol=$3; cos=$4
rm -rf r/$dst; cp -r r/$src r/$dst; rm -f r/$dst/metrics.json r/$dst/mesh*.ply; rm -rf r/$dst/renders
sed -i "s#^out = .*#out = \"r/$dst\"#" r/$dst/config.toml
if [ -n "$cos" ]; then export ONEVIEW_COS=$cos; fi
ONEVIEW_DUMP=dumps/cur ONEVIEW_TOL=$tol ./w7 reconstruct --out r/$dst --resume --quiet > r/$dst.log 2>&1
python3 -c "
import json;m=json.load(open('r/$dst/metrics.json'));c=m['chamfer'];print('$dst', '%.3f acc %.3f comp %.3f'%(c['chamfer_sum'],c['mean_d2s'],c['mean_s2d']), 'genus',m['mesh']['largest_genus'],'/',m['gt_genus'],'faces_unseen',m['mesh']['clean']['faces_unseen'])"
