# Scratch: signed distance (normalised units) at the hull grid's voxel centres, index
# (k*res+j)*res+i. Within 4 voxels of the surface: the distance to the nearest of 8 M points
# sampled on gt_mesh.ply (KD-tree); farther: the voxel distance transform (scipy). Sign from the
# crossing-parity occupancy of occ2.py.
import sys, numpy as np, trimesh
from scipy.spatial import cKDTree
from scipy.ndimage import distance_transform_edt
scene, res, occf, out = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
m = trimesh.load(f"{scene}/gt_mesh.ply")
S = np.load(f"{scene}/cameras_sphere.npz")["scale_mat_0"]
scale = np.linalg.norm(S[:3, 0])
h = 2.0 / res
occ = np.fromfile(occf, np.uint8).reshape(res, res, res) > 0
far = np.where(occ, distance_transform_edt(occ), distance_transform_edt(~occ)) - 0.5
sdf = far * h
band = np.argwhere(far < 4.0)
pts, _ = trimesh.sample.sample_surface(m, 8_000_000, seed=0)
tree = cKDTree(pts)
pn = -1 + (band[:, ::-1] + 0.5) * h  # (k, j, i) -> (x, y, z)
pw = pn @ S[:3, :3].T + S[:3, 3]
d, _ = tree.query(pw, workers=2)
sdf[band[:, 0], band[:, 1], band[:, 2]] = d / scale
sdf = np.where(occ, -sdf, sdf)
sdf.astype("<f4").ravel().tofile(out)
print(res, scale, len(band), float(np.abs(sdf).min()), int((sdf < 0).sum()))
