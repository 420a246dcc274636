"""Splits a cup reconstruction's Chamfer by what the cameras determine. Accuracy: reconstruction
points under the DTU rule (in the ObsMask, distance < 20 mm), by the label of the 0.5 mm grid
point nearest to them: air seen by >= 2 cameras (`seen2`), air seen by < 2 cameras (`open`: the
images leave it free), inside the true solid (`solid`). Completeness: stl points by how many
cameras see them (1, 2, 3-5, 6+). Usage: bytwo.py SCENE HULLDIR MESH..."""
import sys, json, numpy as np, trimesh, scipy.io as sio
from scipy.spatial import cKDTree
sc, hd = sys.argv[1], sys.argv[2]
M = sio.loadmat(sc + '/ObsMask/ObsMask105_10.mat')
BB = M['BB']; Res = float(np.ravel(M['Res'])[0]); O = M['ObsMask'].astype(bool)
g = json.load(open(hd + '/grid.json')); gmin = np.array(g['min']); h = g['h']; res = g['res']
L = np.fromfile(hd + '/labels.u8', dtype=np.uint8).reshape(res[2], res[1], res[0])
from scipy import ndimage
ball = np.zeros((5, 5, 5), bool); zz, yy, xx = np.mgrid[-2:3, -2:3, -2:3]; ball[zz**2 + yy**2 + xx**2 <= 4] = True
deep2 = ndimage.binary_erosion(L == 0, structure=ball)  # >= 1 mm inside air that >= 2 cameras see
nearopen = ndimage.binary_dilation(L == 1, structure=ball)  # within 1 mm of air that < 2 see
stl = np.asarray(trimesh.load(sc + '/Points/stl/stl105_total.ply').vertices)
views = np.fromfile(hd + '/stl_views.u8', dtype=np.uint8)
assert len(views) == len(stl)
tree = cKDTree(stl)
cls = [('1 view', views == 1), ('2 views', views == 2), ('3-5', (views >= 3) & (views <= 5)), ('6+', views >= 6)]
print('stl points by views:', ', '.join(f'{n} {100*k.mean():.1f}%' for n, k in cls), f'(0 views: {(views==0).sum()})')
for name in sys.argv[3:]:
    m = trimesh.load(name)
    cloud = not hasattr(m, 'faces')
    rng = np.random.default_rng(0)
    s = np.asarray(m.vertices)[rng.choice(len(m.vertices), 1000000, replace=False)] if cloud else trimesh.sample.sample_surface(m, 1000000, seed=0)[0]
    idx = np.round((s - BB[0]) / Res).astype(int)
    ok = np.all((idx >= 0) & (idx < np.array(O.shape)), axis=1)
    inm = np.zeros(len(s), bool); inm[ok] = O[idx[ok, 0], idx[ok, 1], idx[ok, 2]]
    dd, _ = tree.query(s, workers=2); keep = inm & (dd < 20)
    gi = np.clip(np.round((s - gmin) / h).astype(int), 0, np.array(res) - 1)
    lab = np.where(deep2[gi[:, 2], gi[:, 1], gi[:, 0]], 0, np.where(nearopen[gi[:, 2], gi[:, 1], gi[:, 0]], 1, 2))
    acc = dd[keep].mean(); tot = dd[keep].sum()
    pts = np.asarray(m.vertices) if cloud else np.vstack([m.vertices, trimesh.sample.sample_surface(m, 4000000, seed=1)[0]])
    dc, _ = cKDTree(pts).query(stl, workers=2); dc = np.minimum(dc, 20)
    print(f'{name}: acc {acc:.3f} comp {dc.mean():.3f}')
    for nm, k in [('seen2 >1mm deep', lab == 0), ('open (+1mm)', lab == 1), ('near the true surface', lab == 2)]:
        kk = keep & k
        print(f'  acc {nm:22s} {100*kk.sum()/keep.sum():5.1f}% pts mean {dd[kk].mean():5.2f} -> {dd[kk].sum()/keep.sum():.3f} mm of the mean ({100*dd[kk].sum()/tot:4.1f}%)')
    for nm, k in cls:
        print(f'  comp {nm:7s} {100*k.mean():5.1f}% pts mean {dc[k].mean():5.2f} -> {dc[k].sum()/len(stl):.3f} mm of the mean ({100*dc[k].sum()/dc.sum():4.1f}%)')
