# signed offset of the reconstruction from the truth, binned by the best (largest) cos between
# the true normal and the direction to a camera that sees the point. usage: graze.py SCENE MESH...
import sys, os, numpy as np, trimesh
from scipy.spatial import cKDTree
sc = sys.argv[1]
g = trimesh.load(sc + '/gt_mesh.ply')
P, tri = trimesh.sample.sample_surface(g, 20000, seed=3); N = g.face_normals[tri]
cams = np.load(sc + '/cameras_sphere.npz'); Cs=[]; k=0
while f'world_mat_{k}' in cams:
    M = cams[f'world_mat_{k}'][:3]; Cs.append(-np.linalg.inv(M[:, :3]) @ M[:, 3]); k += 1
Cs = np.array(Cs)
best = np.full(len(P), -1.0); nvis = np.zeros(len(P), int)
ri = trimesh.ray.ray_triangle.RayMeshIntersector(g)
for C in Cs:
    dv = C - P; dist = np.linalg.norm(dv, axis=1); dv /= dist[:, None]
    cs = (dv*N).sum(1); front = cs > 0.02
    o = P[front] + dv[front]*0.05
    hit = ri.intersects_any(o, dv[front])
    vis = np.zeros(len(P), bool); vis[np.where(front)[0][~hit]] = True
    nvis += vis; best = np.where(vis, np.maximum(best, cs), best)
bins = [(-2,0.0),(0.0,0.3),(0.3,0.5),(0.5,0.7),(0.7,0.85),(0.85,1.01)]
for name in sys.argv[2:]:
    m = trimesh.load(name); s,_ = trimesh.sample.sample_surface(m, 800000, seed=0)
    dd, idx = cKDTree(s).query(P); off = ((s[idx]-P)*N).sum(1)
    print(name, 'mean', dd[dd<20].mean().round(3))
    for lo,hi in bins:
        b = (best>=lo)&(best<hi)&(nvis>=(1 if lo>=0 else 0))
        if b.sum()<30: continue
        print(f'  best cos {lo:4.2f}-{hi:4.2f}: n {b.sum():5d} ({b.mean()*100:4.1f}%)  mean dist {dd[b].mean():.2f}  median signed {np.median(off[b]):+.2f}  share signed<-0.5 {(off[b]<-0.5).mean():.2f} >0.5 {(off[b]>0.5).mean():.2f}')
