#!/bin/bash
# rep.sh N : run the tiny round trip, reusing the true scene/run from base
cd /work/rt
export NEUS_AUG=/work/main/target/release/neus-aug RAYON_NUM_THREADS=2
args=(--views 16 --spp 1 --gt-spacing 1.0 --intrinsics known --bound 1.6 --config /work/rt/tiny.toml)
if [ ! -d base ]; then bash /work/main/scripts/colmap_roundtrip.sh base "${args[@]}" > base.log 2>&1; fi
for i in $(seq 1 $1); do
  d=r$i; rm -rf $d; mkdir -p $d/runs $d/logs
  cp -r base/true $d/; cp -r base/runs/true $d/runs/; cp base/params $d/
  bash /work/main/scripts/colmap_roundtrip.sh $d "${args[@]}" > $d.log 2>&1
  python3 -c "import json;d=json.load(open('$d/summary-known-auto.json'));print('$d',d['ratio'],d['ratio_poses'],d['centre_residual_rms_mm'],d['chamfer_true_mm'],d['chamfer_colmap_poses_mm'],d['wall_s'])" >> res.txt
done
