import sys, json, numpy as np, trimesh, scipy.io as sio
from scipy.spatial import cKDTree
from scipy import ndimage
sc, hd, mesh, out = sys.argv[1:5]
M = sio.loadmat(sc + '/ObsMask/ObsMask105_10.mat'); BB = M['BB']; Res = float(np.ravel(M['Res'])[0]); O = M['ObsMask'].astype(bool)
stl = np.asarray(trimesh.load(sc + '/Points/stl/stl105_total.ply').vertices)
m = trimesh.load(mesh); s = trimesh.sample.sample_surface(m, 200000, seed=0)[0]
idx = np.round((s - BB[0]) / Res).astype(int); ok = np.all((idx >= 0) & (idx < np.array(O.shape)), axis=1)
inm = np.zeros(len(s), bool); inm[ok] = O[idx[ok, 0], idx[ok, 1], idx[ok, 2]]
dd, _ = cKDTree(stl).query(s, workers=2); keep = inm & (dd < 20) & (dd > 1.0)
np.save(out + '.dist.npy', dd[keep]); trimesh.PointCloud(s[keep]).export(out)
good = inm & (dd < 0.3); trimesh.PointCloud(s[good]).export(out.replace('.ply', '-good.ply')); np.save(out.replace('.ply', '-good.ply') + '.dist.npy', dd[good])
print('points with error > 1 mm under the DTU rule:', keep.sum(), 'of', (inm & (dd < 20)).sum())
