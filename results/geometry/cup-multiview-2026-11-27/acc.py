"""Accuracy of cup meshes split by where the reconstructed points lie (cavity / wall / outside,
and by axial position), DTU rule (>= 20 mm left out). Usage: acc.py SCENE MESH..."""
import sys, os, numpy as np, trimesh
from scipy.spatial import cKDTree
sc = sys.argv[1]
g = trimesh.load(sc + '/gt_mesh.ply')
pts = np.asarray(trimesh.load(sc + '/Points/stl/' + os.listdir(sc + '/Points/stl')[0]).vertices)
V = g.vertices; c = V.mean(0)
w, U = np.linalg.eigh(np.cov((V - c).T))
i = np.argmax([abs(w[k] - np.delete(w, k).mean()) for k in range(3)]); a = U[:, i]
axg = (V - c) @ a
tree = cKDTree(pts)
for name in sys.argv[2:]:
    m = trimesh.load(name); s, _ = trimesh.sample.sample_surface(m, 400000, seed=0)
    dd, _ = tree.query(s); keep = dd < 20
    d = s - c; ax = d @ a; rn = np.linalg.norm(d - ax[:, None] * a, axis=1)
    print(name, 'accuracy (mean, <20mm)', dd[keep].mean().round(3), 'far share', (~keep).mean().round(4))
    for lab, b in [('cavity r<50', rn < 50), ('wall 50-66', (rn >= 50) & (rn <= 66)), ('outside r>66', rn > 66)]:
        kb = b & keep
        if kb.any():
            print(f"   {lab:14s} {b.mean()*100:5.1f}% of points, mean {dd[kb].mean():5.2f} mm, median {np.median(dd[b]):5.2f}, share of sum {dd[kb].sum()/dd[keep].sum()*100:5.1f}%")
    b = rn < 50
    q = np.linspace(axg.min(), axg.max(), 7)
    print('   cavity points by axial position (share of sum):', ' '.join(f"{dd[b & keep & (ax>=q[j]) & (ax<q[j+1])].sum()/dd[keep].sum()*100:.1f}%" for j in range(6)), ' axis sign: bins go from', 'low' , 'to high')
