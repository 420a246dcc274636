#!/bin/bash
# recut.sh SRC TAG key=value...: copy the finished run folder SRC to tmp/rc/TAG, set [mesh] keys
# in its config.toml (added under [mesh] when absent), and `reconstruct --out DIR --resume`: the
# checkpoint is at its last step, so this re-extracts, cleans and scores the mesh only. BIN: the
# binary (a build of this commit with view-cos-scratch.patch for mesh.clean_min_view_cos).
src=$1; tag=$2; shift 2
d=tmp/rc/$tag; rm -rf $d; mkdir -p tmp/rc; cp -r $src $d; rm -f $d/metrics.json
for kv in "$@"; do k=${kv%%=*}; v=${kv#*=}
  if grep -q "^$k = " $d/config.toml; then sed -i "s/^$k = .*/$k = $v/" $d/config.toml; else sed -i "/^\[mesh\]/a $k = $v" $d/config.toml; fi; done
${BIN:-./mvc} reconstruct --out $d --resume --quiet > $d.log 2>&1 || { tail -3 $d.log; exit 1; }
python3 -c "
import json;m=json.load(open('$d/metrics.json'));c=m['chamfer'];print('$tag', round(c['chamfer_sum'],3), 'acc', round(c['mean_d2s'],3), 'comp', round(c['mean_s2d'],3), 'x', round(m.get('ratio_to_floor') or -1,2), 'genus', m['mesh'].get('largest_genus'))"
