"""Where a reconstruction's DTU errors are (issue 13 diagnosis, 2026-11-25).

usage: error_map.py DUMP_DIR SCENE_DIR
  DUMP_DIR: `dtu-eval --mesh M.ply --scan N --gt-root SCENE_DIR --dump-dir DUMP_DIR`
  SCENE_DIR: a simulated scene (Points/stl, ObsMask)
Prints the share of accuracy (observed reconstruction points) and completeness (ground-truth
points) carried by distances above 1 mm, and the 10 mm cells that carry most of it (world mm).
Needs numpy, scipy, trimesh.
"""
import glob
import sys

import numpy as np
import trimesh
from scipy.io import loadmat
from scipy.spatial import cKDTree

dump, scene = sys.argv[1], sys.argv[2]
p = np.load(dump + "/data_down.npy")
om = loadmat(glob.glob(scene + "/ObsMask/ObsMask*.mat")[0])
mask, bb, res = om["ObsMask"], om["BB"], om["Res"]
idx = np.rint((p - bb[:1]) / res).astype(int)
inb = np.all((idx >= 0) & (idx < np.array(mask.shape)), 1)
obs = np.zeros(len(p), bool)
obs[inb] = mask[idx[inb, 0], idx[inb, 1], idx[inb, 2]].astype(bool)
stl = trimesh.load(glob.glob(scene + "/Points/stl/*.ply")[0], process=False).vertices
acc, _ = cKDTree(stl).query(p[obs])
comp, _ = cKDTree(p).query(stl)
for name, pts, d in [("accuracy", p[obs], acc), ("completeness", stl, comp)]:
    keep = d < 20
    far = keep & (d > 1.0)
    total = d[keep].sum()
    print(f"{name}: mean {d[keep].mean():.3f} mm; d > 1 mm: {far.mean():.1%} of points, "
          f"{d[far].sum() / total:.1%} of the mean")
    cells = np.floor(pts[far] / 10).astype(int)
    keys, inv, cnt = np.unique(cells, axis=0, return_inverse=True, return_counts=True)
    weight = np.bincount(inv.ravel(), weights=d[far])
    for o in np.argsort(-weight)[:8]:
        print(f"  cell {(keys[o] * 10 + 5).tolist()}: {cnt[o]} points, mean {d[far][inv.ravel() == o].mean():.2f} mm, "
              f"{weight[o] / total:.1%} of the mean")
