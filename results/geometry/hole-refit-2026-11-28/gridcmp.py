"""Inner-bottom cells of a cup mesh (5 mm error map) against the views that see each cell and what their depth maps hold there.
Usage: gridcmp.py SCENE GRID.txt MESH OUT.png; GRID.txt from the scratch build with NEUS_DD=1 NEUS_DD_GRID=GRID.txt (scratch.patch)."""
import os, sys, numpy as np, trimesh
from scipy.spatial import cKDTree
from PIL import Image
sc, grid, mesh = sys.argv[1], sys.argv[2], sys.argv[3]
G = np.loadtxt(grid, dtype=np.int64)
nv = np.zeros((48, 48), int); st = np.zeros((48, 48, 5), int)
for gx, gz, n, m0, m1, m2, fb, *_ in G:
    nv[gz, gx] = n; st[gz, gx] = [m0, m1, m2, fb // 1000, fb % 1000]
cams = np.load(sc + '/cameras_sphere.npz'); S = cams['scale_mat_0']; s0 = S[0, 0]; ctr = S[:3, 3]
stl = np.asarray(trimesh.load(sc + '/Points/stl/' + os.listdir(sc + '/Points/stl')[0]).vertices)
pn = (stl - ctr) / s0
g = trimesh.load(sc + '/gt_mesh.ply')
yb = np.median(pn[:, 1][pn[:, 1] > 0.3])
m = trimesh.load(mesh); s, _ = trimesh.sample.sample_surface(m, 800000, seed=0)
# inner bottom: the level of the highest-count horizontal layer inside (y in normalised)
ys = np.round(pn[:, 1], 3); vals, cnt = np.unique(ys, return_counts=True)
lvl = vals[np.argmax(cnt * (np.abs(vals) < 0.9))]
B = (np.abs(pn[:, 1] - lvl) < 0.004) & (np.hypot(pn[:, 0], pn[:, 2]) < 0.40)
print('inner bottom level', lvl, B.sum())
err, _ = cKDTree(s).query(stl[B])
gx = np.floor((pn[B, 0] + 0.48) / 0.02).astype(int); gz = np.floor((pn[B, 2] + 0.48) / 0.02).astype(int)
E = np.full((48, 48), np.nan); 
for x in range(48):
    for z in range(48):
        b = (gx == x) & (gz == z)
        if b.sum() > 3: E[z, x] = np.mean(err[b])
ok = ~np.isnan(E)
print('cells with GT', ok.sum())
for lab, b in [('err<1', ok & (E < 1)), ('1-3', ok & (E >= 1) & (E < 3)), ('>3', ok & (E >= 3))]:
    t = st[b].sum(0)
    print(f"{lab:6s} cells {b.sum():4d} views mean {nv[b].mean():.2f} (1:{(nv[b]==1).sum()} 2:{(nv[b]==2).sum()} 3:{(nv[b]==3).sum()} 4+:{(nv[b]>=4).sum()}); px missing/stereo/fill-good/front/behind {t} shares {np.round(t/t.sum(),2)}")
im = np.zeros((48, 48, 3), np.uint8) + 255
t = np.clip(np.nan_to_num(E, nan=0) / 5, 0, 1)
im[ok] = np.stack([255 * t, 255 * (1 - t), 0 * t], -1)[ok]
im2 = np.zeros((48, 48, 3), np.uint8) + 255
q = np.clip(nv / 6, 0, 1); im2[nv > 0] = np.stack([255 * (1 - q), 255 * (1 - q), 255 * q], -1)[nv > 0].astype(np.uint8)
Image.fromarray(np.concatenate([im, im2], 1)).resize((96 * 6, 48 * 6), Image.NEAREST).save(sys.argv[4])
