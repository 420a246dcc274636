#!/bin/bash
# rex.sh RUN NAME R: re-extract the trained run folder RUN (checkpoint + config.toml) into a new
# folder NAME with mesh.close_radius = R, and print its Chamfer, ratio and genus. Training is not
# repeated (`reconstruct --resume` on a finished run only extracts and scores).
set -e
src=$1; name=$2; r=$3
bin=${NEUS_AUG:-neus-aug}
rm -rf "$name" && mkdir "$name" && cp "$src"/{checkpoint.safetensors,config.toml} "$name"/
sed -i "s|^out = .*|out = \"$(pwd)/$name\"|" "$name"/config.toml
sed -i "s/^\[mesh\]$/[mesh]\nclose_radius = $r/" "$name"/config.toml
"$bin" reconstruct --out "$name" --resume --quiet > "$name.log" 2>&1 || { tail -3 "$name.log"; exit 1; }
python3 - "$name" <<'PY'
import json, sys
m = json.load(open(sys.argv[1] + '/metrics.json'))
print(sys.argv[1], 'chamfer %.4f closed %.4f ratio %.2f genus %s (truth %s) components %s'
      % (m['chamfer']['chamfer_sum'], m['chamfer_closed']['chamfer_sum'], m['ratio_to_floor'],
         m['mesh']['largest_genus'], m['gt_genus'], m['mesh']['clean']['components_after']))
PY
rm -f "$name"/checkpoint.safetensors
