#!/usr/bin/env bash
# usage: rex.sh SRC_RUN_DIR K  -> re-extracts SRC with mesh.clean_min_visible_views=K into runs/<name>-vK
src=$1; k=$2; name=$(basename $src)-v$k; out=/work/exp11/runs/$name
mkdir -p /work/exp11/runs
if [ ! -f $out/metrics.json ]; then
  rm -rf $out; mkdir -p $out
  cp $src/checkpoint.safetensors $out/
  python3 - "$src/config.toml" "$out/config.toml" "$k" <<'PY'
import sys,re
s=open(sys.argv[1]).read()
s=re.sub(r'(\[mesh\]\n)', r'\1clean_min_visible_views = '+sys.argv[3]+'\n', s)
s=re.sub(r'out = ".*"', 'out = "'+sys.argv[2].rsplit('/',1)[0]+'"', s)
open(sys.argv[2],'w').write(s)
PY
  /work/exp11/nv2 reconstruct --out $out --resume --quiet > $out.log 2>&1
fi
python3 -c "
import json;m=json.load(open('$out/metrics.json'));c=m['chamfer'];me=m['mesh']
print('$name'.ljust(30), round(c['chamfer_sum'],3), 'acc',round(c['mean_d2s'],3),'comp',round(c['mean_s2d'],3),'ratio', round(m.get('ratio_to_floor') or -1,2), 'genus', me.get('largest_genus'), 'gt', m.get('gt_genus'), 'unseen', me['clean'].get('faces_unseen'), 'of', me['clean']['faces_before'], 't_mesh', round(m['timings_s']['mesh'],1))" 2>&1 | tail -1
