import sys, os, numpy as np, trimesh
sc = sys.argv[1]
g = trimesh.load(sc + '/gt_mesh.ply')
V = g.vertices; c = V.mean(0); a = np.array([0, -1.0, 0])
for mp in sys.argv[2:]:
    msh = trimesh.load(mp); P, _ = trimesh.sample.sample_surface(msh, 300000, seed=0)
    cp, dist, tri = trimesh.proximity.closest_point(g, P)
    N = g.face_normals[tri]; off = ((P - cp) * N).sum(1)
    d = cp - c; ax = d @ a; r = d - ax[:, None] * a; rn = np.linalg.norm(r, axis=1); rh = r / np.maximum(rn[:, None], 1e-9)
    nr = (N * rh).sum(1); na = N @ a
    cls = np.full(len(P), 'rim', dtype=object); cls[nr > 0.7] = 'outer'; cls[nr < -0.7] = 'inner'; cls[(np.abs(na) > 0.7) & (rn < 50)] = 'bottom'
    m = dist < 20; tot = dist[m].sum()
    print(mp, 'acc (unmasked)', dist[m].mean().round(3))
    for k in ['outer', 'inner', 'bottom', 'rim']:
        for sgn, nm in [(1, 'outside(+)'), (-1, 'inside(-)')]:
            b = m & (cls == k) & (np.sign(off) == sgn)
            print(f'  {k:7s} {nm:11s} n {b.sum():7d} mean {dist[b].mean():.2f} share {dist[b].sum()/tot:.3f} share>1mm {dist[b & (dist>1)].sum()/tot:.3f}')
