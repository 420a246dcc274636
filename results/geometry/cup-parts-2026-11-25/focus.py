"""Oracle pixel masks for the sampling experiment (README section 3): per training view, the pixels
inside the projection of the cup's rim circle (the mouth), as raw u8 files OUT/{v:03d}.u8 (400x300,
row-major), `v` the training-view index: the 49 cameras minus the 3 held out by `data.holdout = 3`
(cameras 8, 24, 40). Usage: focus.py SCENE_FOLDER OUT (numpy, trimesh, matplotlib)."""
import sys, numpy as np, trimesh
sc = sys.argv[1]; out = sys.argv[2]
g = trimesh.load(sc + '/gt_mesh.ply'); V = g.vertices; c = V.mean(0)
w, U = np.linalg.eigh(np.cov((V - c).T))
i = np.argmax([abs(w[k] - np.delete(w, k).mean()) for k in range(3)]); a = U[:, i]
ax = (V - c) @ a; rad = np.linalg.norm((V - c) - ax[:, None] * a, axis=1)
# the bottom end holds the outer pole (radius ~0 at the extreme)
if rad[np.argmax(ax)] < 1.0: a = -a; ax = -ax
top = c + a * ax.max()
u = np.cross(a, [1, 0, 0]); u /= np.linalg.norm(u); v = np.cross(a, u)
t = np.linspace(0, 2 * np.pi, 256, endpoint=False)
rim = top[None] + 57.5 * (np.cos(t)[:, None] * u + np.sin(t)[:, None] * v)
cams = np.load(sc + '/cameras_sphere.npz')
from matplotlib.path import Path
W, H = 400, 300
yy, xx = np.mgrid[0:H, 0:W]; pix = np.c_[xx.ravel() + 0.5, yy.ravel() + 0.5]
n = sum(1 for key in cams if key.startswith('world_mat_') and not key.startswith('world_mat_inv'))
held = {int((i + 0.5) * n / 3) for i in range(3)}
train = [i for i in range(n) if i not in held]
k = 0; tot = 0
while f'world_mat_{k}' in cams:
    M = cams[f'world_mat_{k}'][:3]
    x = np.c_[rim, np.ones(len(rim))] @ M.T; uv = x[:, :2] / x[:, 2:]
    m = Path(uv).contains_points(pix).reshape(H, W).astype(np.uint8)
    if k in train:
        m.tofile(f'{out}/{train.index(k):03d}.u8')
    tot += m.mean(); k += 1
print(k, 'views; mean mouth share of the image', tot / k)
