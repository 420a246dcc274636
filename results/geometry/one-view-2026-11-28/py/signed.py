import sys, os, numpy as np, trimesh
from scipy.spatial import cKDTree
sc = sys.argv[1]
g = trimesh.load(sc + '/gt_mesh.ply')
pts = np.asarray(trimesh.load(sc + '/Points/stl/' + os.listdir(sc + '/Points/stl')[0]).vertices)
P = pts[np.random.default_rng(0).choice(len(pts), 200000, replace=False)]
V = g.vertices; c = V.mean(0)
w, U = np.linalg.eigh(np.cov((V - c).T))
i = np.argmax([abs(w[k] - np.delete(w, k).mean()) for k in range(3)]); a = U[:, i]
_, _, tri = trimesh.proximity.closest_point(g, P)
N = g.face_normals[tri]
d = P - c; ax = d @ a; r = d - ax[:, None] * a; rn = np.linalg.norm(r, axis=1); rh = r / rn[:, None]
nr = (N * rh).sum(1); na = N @ a
cls = np.full(len(P), 'rim', dtype=object)
cls[nr > 0.7] = 'outer'; cls[nr < -0.7] = 'inner'
cls[(np.abs(na) > 0.7) & (rn < 50)] = 'bottom'
for name in sys.argv[2:]:
    m = trimesh.load(name); s, _ = trimesh.sample.sample_surface(m, 600000, seed=0)
    dd, j = cKDTree(s).query(P); keep = dd < 20
    sg = ((s[j] - P) * N).sum(1)
    print(name, 'comp', dd[keep].mean().round(3))
    for k in ['outer', 'inner', 'bottom', 'rim']:
        b = (cls == k) & keep
        q = np.percentile(sg[b], [10, 25, 50, 75, 90])
        print(f"  {k:7s} n {b.sum():6d} mean|d| {dd[b].mean():.3f} signed mean {sg[b].mean():+.3f} q10..90 " + ' '.join(f'{x:+.2f}' for x in q), f" >1mm out {(sg[b]>1).mean():.3f} in {(sg[b]<-1).mean():.3f}")
    for k in ['outer', 'inner', 'bottom', 'rim']:
        b = (cls == k) & keep
        tot = dd[keep].sum()
        print(f"  {k:7s} share of comp sum: all {dd[b].sum()/tot:.3f}  from d>2mm {dd[b&(dd>2)].sum()/tot:.3f} (n {(b&(dd>2)).sum()})  d>5 {dd[b&(dd>5)].sum()/tot:.3f}")
    # where are d>2mm points: axial position and azimuth
    b = keep & (dd > 2)
    print('  d>2mm points by class/axial:', {k: int(((cls==k)&b).sum()) for k in ['outer','inner','bottom','rim']})
    np.save(name.replace('/','_')+'_far.npy', np.c_[P[b], dd[b], ax[b], rn[b]])
