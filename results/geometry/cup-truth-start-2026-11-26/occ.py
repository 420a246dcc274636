# Scratch: truth occupancy of a synthetic scene on the hull grid (index (k*res+j)*res+i, centres
# -r+(i+.5)h in normalised space), written as res^3 bytes.
import sys, numpy as np, trimesh
scene, res, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
r = 1.0
m = trimesh.load(f"{scene}/gt_mesh.ply")
S = np.load(f"{scene}/cameras_sphere.npz")["scale_mat_0"]
h = 2*r/res
c = -r + (np.arange(res)+0.5)*h
z, y, x = np.meshgrid(c, c, c, indexing="ij")
pn = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
pw = pn @ S[:3,:3].T + S[:3,3]
inside = np.zeros(len(pw), bool)
lo, hi = m.bounds
sel = np.all((pw >= lo) & (pw <= hi), 1)
idx = np.nonzero(sel)[0]
for a in range(0, len(idx), 200000):
    b = idx[a:a+200000]
    inside[b] = m.contains(pw[b])
inside.astype(np.uint8).tofile(out)
print(res, inside.sum(), inside.mean())
