#!/bin/bash
# Triangulation of the cup's training images with the known poses (Debian colmap 3.8, CPU SIFT).
set -e
neus-aug synth cup --out scene --export colmap --quiet      # same images as sc/cup400
mkdir -p known tri
cp scene/colmap/sparse/0/cameras.txt known/
# poses only: every second line (the POINTS2D line) emptied, no points
awk 'BEGIN{n=0} /^#/{print; next} {n++; if (n%2==1) print; else print ""}' scene/colmap/sparse/0/images.txt > known/images.txt
printf '# 3D point list\n' > known/points3D.txt
P=$(awk '!/^#/{print $5","$6","$7","$8; exit}' known/cameras.txt)
colmap feature_extractor --database_path db.db --image_path scene/image --ImageReader.camera_model PINHOLE \
  --ImageReader.single_camera 1 --ImageReader.camera_params "$P" --SiftExtraction.use_gpu 0
colmap exhaustive_matcher --database_path db.db --SiftMatching.use_gpu 0
# the database numbers images in its own order: renumber the known model to match it
python3 - <<'PY'
import sqlite3
ids = {n: i for i, n in sqlite3.connect('db.db').execute('select image_id, name from images')}
out = []
for line in open('known/images.txt'):
    if line.startswith('#') or not line.strip():
        out.append(line); continue
    f = line.split(); f[0] = str(ids[f[9]]); out.append(' '.join(f) + '\n')
open('known/images.txt', 'w').writelines(out)
PY
colmap point_triangulator --database_path db.db --image_path scene/image --input_path known --output_path tri
colmap model_converter --input_path tri --output_path tri --output_type TXT
python3 pts.py                  # where the points lie, how far from the truth (needs trimesh, scipy)
python3 prep.py 1.0 3 obs.txt   # segments for NEUS_SFM (reprojection error <= 1 px, track >= 3)
