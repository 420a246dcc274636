#!/bin/bash
# Re-extract and re-clean every finished run of a study from its final checkpoint with the new
# binary (no training: the checkpoint is at the last step), keeping the original folder intact.
src=$1; dst=$2; bin=/work/main/target/release/neus-aug
mkdir -p $dst
for r in $src/runs/*/; do
  id=$(basename $r); [ -f $r/metrics.json ] || continue; [ -f $dst/$id/metrics.json ] && continue
  seed=${id##*-s}; rest=${id%-s*}; arm=${rest##*-}; scene=${rest%-*}
  aug=$arm; [ $arm = baseline ] && aug=none
  rm -rf $dst/$id; mkdir -p $dst/$id
  cp $r/config.toml $r/checkpoint.safetensors $dst/$id/
  (cd $dst && $bin reconstruct $scene --preset fast --aug $aug --seed $seed --out $id --resume --quiet $(grep -q visual_hull $r/config.toml && echo "--set train.init.kind=\"visual_hull\"") > $id.log 2>&1)
  echo "$id $(tail -1 $dst/$id.log)"
done
