#!/bin/bash
# rexc.sh SRC DST COS MARGIN_MM: re-extract keeping one-view faces at |cos| >= COS, with clean-up margin
src=$1; dst=$2; cos=$3; mg=$4
rm -rf r/$dst; cp -r r/$src r/$dst; rm -f r/$dst/metrics.json r/$dst/mesh*.ply; rm -rf r/$dst/renders
sed -i "s#^out = .*#out = \"r/$dst\"#; s#^clean_visible_margin_mm = .*#clean_visible_margin_mm = $mg#" r/$dst/config.toml
ONEVIEW_COS=$cos ./w7 reconstruct --out r/$dst --resume --quiet > r/$dst.log 2>&1
python3 -c "
import json;m=json.load(open('r/$dst/metrics.json'));c=m['chamfer'];print('$dst', '%.3f acc %.3f comp %.3f'%(c['chamfer_sum'],c['mean_d2s'],c['mean_s2d']), 'genus',m['mesh']['largest_genus'],'/',m['gt_genus'],'faces_unseen',m['mesh']['clean']['faces_unseen'])"
