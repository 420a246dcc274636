#!/usr/bin/env bash
# usage: rexe.sh SRC_RUN_DIR K TAG  (env VIS_EPS, VIS_MODE passed through) -> runs/<name>-<TAG>
src=$1; k=$2; tag=$3; name=$(basename $src)-$tag; out=/work/exp11/rx/$name
mkdir -p /work/exp11/rx
if [ ! -f $out/metrics.json ]; then
  rm -rf $out; mkdir -p $out
  cp $src/checkpoint.safetensors $out/
  python3 - "$src/config.toml" "$out/config.toml" "$k" <<'PY'
import sys,re
s=open(sys.argv[1]).read()
s=re.sub(r'clean_min_visible_views = \d+\n','',s)
import os
s=re.sub(r'clean_visible_margin_mm = .*\n','',s)
s=re.sub(r'(\[mesh\]\n)', r'\1clean_min_visible_views = '+sys.argv[3]+'\nclean_visible_margin_mm = '+os.environ.get('MARGIN','0.0')+'\n', s)
s=re.sub(r'out = ".*"', 'out = "'+sys.argv[2].rsplit('/',1)[0]+'"', s)
open(sys.argv[2],'w').write(s)
PY
  /work/exp11/nexp2 reconstruct --out $out --resume --quiet > $out.log 2>&1
fi
python3 -c "
import json;m=json.load(open('$out/metrics.json'));c=m['chamfer'];me=m['mesh'];cc=m.get('chamfer_closed') or {}
print('$name'.ljust(30), round(c['chamfer_sum'],3), 'acc',round(c['mean_d2s'],3),'comp',round(c['mean_s2d'],3),'ratio', round(m.get('ratio_to_floor') or -1,2), 'closed', round(cc.get('chamfer_sum',-1),3), 'genus', me.get('largest_genus'), 'unseen', me['clean'].get('faces_unseen'), 'of', me['closed_faces'])" 2>&1 | tail -1
