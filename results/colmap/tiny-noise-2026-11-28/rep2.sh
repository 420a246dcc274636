#!/bin/bash
# rep2.sh TAG N synth-args... : base_TAG then N repetitions reusing its true scene/run
cd /work/rt
tag=$1; n=$2; shift 2
export NEUS_AUG=/work/main/target/release/neus-aug RAYON_NUM_THREADS=2
args=(--gt-spacing 1.0 --intrinsics known --bound 1.6 --config /work/rt/tiny.toml "$@")
b=base_$tag
if [ ! -d $b ]; then SECONDS=0; bash /work/main/scripts/colmap_roundtrip.sh $b "${args[@]}" > $b.log 2>&1; echo "$b wall $SECONDS" >> res_$tag.txt
python3 -c "import json;d=json.load(open('$b/summary-known-auto.json'));print('$b',d['ratio'],d['ratio_poses'],d['centre_residual_rms_mm'],d['chamfer_true_mm'],d['chamfer_colmap_poses_mm'])" >> res_$tag.txt; fi
for i in $(seq 1 $n); do
  d=${tag}_r$i; rm -rf $d; mkdir -p $d/runs $d/logs
  cp -r $b/true $d/; cp -r $b/runs/true $d/runs/; cp $b/params $d/
  SECONDS=0; bash /work/main/scripts/colmap_roundtrip.sh $d "${args[@]}" > $d.log 2>&1
  python3 -c "import json;d=json.load(open('$d/summary-known-auto.json'));print('$d',d['ratio'],d['ratio_poses'],d['centre_residual_rms_mm'],d['chamfer_true_mm'],d['chamfer_colmap_poses_mm'],$SECONDS)" >> res_$tag.txt
done
