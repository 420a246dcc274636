# Scratch: truth occupancy on the hull grid (index (k*res+j)*res+i, centres -1+(i+.5)h in
# normalised space), by crossing parity along one world-space ray per grid column: the grid's
# z axis mapped through scale_mat_0 (a uniform scale + translation, so columns stay straight).
import sys, numpy as np, trimesh
scene, res, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
m = trimesh.load(f"{scene}/gt_mesh.ply")
S = np.load(f"{scene}/cameras_sphere.npz")["scale_mat_0"]
h = 2.0 / res
c = -1 + (np.arange(res) + 0.5) * h
occ = np.zeros((res, res, res), np.uint8)  # [k][j][i]
y, x = np.meshgrid(c, c, indexing="ij")
orig_n = np.stack([x.ravel(), y.ravel(), np.full(x.size, -1.5)], 1)
orig = orig_n @ S[:3, :3].T + S[:3, 3]
d = np.array([0, 0, 1.0]) @ S[:3, :3].T
d = d / np.linalg.norm(d)
dirs = np.tile(d, (len(orig), 1))
loc, ri, _ = m.ray.intersects_location(orig, dirs, multiple_hits=True)
scale = np.linalg.norm(S[:3, 0])
tn = ((loc - orig[ri]) @ d) / scale - 1.5  # normalised z of each hit (origin at z = -1.5)
for r in np.unique(ri):
    zs = np.sort(tn[ri == r])
    # drop duplicate hits on shared edges
    keep = np.concatenate([[True], np.diff(zs) > 1e-7])
    zs = zs[keep]
    if len(zs) % 2:
        continue
    j, i = divmod(r, res)
    for a, b in zip(zs[::2], zs[1::2]):
        occ[(c > a) & (c < b), j, i] = 1
occ.tofile(out)
print(res, int(occ.sum()), occ.mean())
