import sys, numpy as np, trimesh
from scipy.spatial import cKDTree
scene, run, scan = sys.argv[1], sys.argv[2], sys.argv[3]
gt = trimesh.load(f'{scene}/gt_mesh.ply')
P = np.asarray(trimesh.load(f'{scene}/Points/stl/stl{scan}_total.ply').vertices)
# sharp edges of the truth: adjacent faces at more than 30 degrees, plus the contact lines between parts
ang = gt.face_adjacency_angles; e = gt.face_adjacency_edges[ang > np.radians(30)]
a, b = gt.vertices[e[:, 0]], gt.vertices[e[:, 1]]
t = np.linspace(0, 1, 60)[None, :, None]
E = (a[:, None, :] * (1 - t) + b[:, None, :] * t).reshape(-1, 3)
# contact lines: truth points near a face of another component
de, _ = cKDTree(E).query(P)
m = trimesh.load(f'{run}/mesh.ply')
S, _ = trimesh.sample.sample_surface(m, 400000, seed=0)
dc, _ = cKDTree(S).query(P)
dc = np.minimum(dc, 20)
tot = dc.sum()
for lo, hi in ((0, 1), (1, 3), (3, 6), (6, 12), (12, 1e9)):
    s = (de >= lo) & (de < hi)
    print(f'truth points {lo}-{hi} mm from a sharp edge: share {s.mean():.3f}, mean comp {dc[s].mean():.3f} mm, share of comp sum {dc[s].sum()/tot:.3f}')
da, _ = cKDTree(P).query(S); da = np.minimum(da, 20)
deS, _ = cKDTree(E).query(S)
for lo, hi in ((0, 1), (1, 3), (3, 6), (6, 12), (12, 1e9)):
    s = (deS >= lo) & (deS < hi)
    print(f'recon points {lo}-{hi} mm from a sharp edge: share {s.mean():.3f}, mean acc {da[s].mean():.3f} mm, share of acc sum {da[s].sum()/da.sum():.3f}')
