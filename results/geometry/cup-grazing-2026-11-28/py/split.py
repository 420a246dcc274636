import sys, os, numpy as np, trimesh
from scipy.spatial import cKDTree
sc = sys.argv[1]; seen = trimesh.load(sys.argv[2])
g = trimesh.load(sc + '/gt_mesh.ply')
pts = np.asarray(trimesh.load(sc + '/Points/stl/' + os.listdir(sc + '/Points/stl')[0]).vertices)
P = pts[np.random.default_rng(0).choice(len(pts), 200000, replace=False)]
ss,_ = trimesh.sample.sample_surface(seen, 1500000, seed=0)
ds,_ = cKDTree(ss).query(P); isseen = ds < 0.3
print('seen share', isseen.mean())
gs,_ = trimesh.sample.sample_surface(g, 1500000, seed=1); gt = cKDTree(gs)
for name in sys.argv[3:]:
    m = trimesh.load(name); s,_ = trimesh.sample.sample_surface(m, 600000, seed=0)
    dd,_ = cKDTree(s).query(P); keep = dd < 20
    tot = dd[keep].sum()
    print(name, 'comp', dd[keep].mean().round(3), 'seen part mean', dd[keep&isseen].mean().round(3), 'unseen mean', dd[keep&~isseen].mean().round(3), 'share from unseen', (dd[keep&~isseen].sum()/tot).round(3))
    # tail of seen part
    q = np.quantile(dd[isseen], [0.5, 0.9, 0.95, 0.99]); print('  seen quantiles', q.round(2), 'sum share of seen>1mm', (dd[keep&isseen&(dd>1)].sum()/tot).round(3))
    da,_ = gt.query(s); ka = da < 20
    print('  acc', da[ka].mean().round(3), 'quantiles', np.quantile(da,[0.5,0.9,0.95,0.99]).round(2), 'share from >1mm', (da[ka&(da>1)].sum()/da[ka].sum()).round(3))
