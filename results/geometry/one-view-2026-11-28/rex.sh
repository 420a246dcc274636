#!/bin/bash
# rex.sh SRC DST key=value... : re-extract a finished run with config edits (resume from its checkpoint)
src=$1; dst=$2; shift 2
rm -rf r/$dst; cp -r r/$src r/$dst; rm -f r/$dst/metrics.json
sed -i "s#^out = .*#out = \"r/$dst\"#" r/$dst/config.toml
for kv in "$@"; do k=${kv%%=*}; v=${kv#*=}; sed -i "s/^$k = .*/$k = $v/" r/$dst/config.toml; done
${BIN:-./v3} reconstruct --out r/$dst --resume --quiet > r/$dst.log 2>&1
python3 -c "
import json;m=json.load(open('r/$dst/metrics.json'));c=m['chamfer'];print('$dst', '%.3f acc %.3f comp %.3f'%(c['chamfer_sum'],c['mean_d2s'],c['mean_s2d']), 'genus',m['mesh']['largest_genus'],'/',m['gt_genus'],'faces_unseen',m['mesh']['clean']['faces_unseen'])"
