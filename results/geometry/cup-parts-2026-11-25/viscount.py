"""Per ground-truth point of a scene: how many cameras see it (in the image, in front, not occluded)
and the smallest angle between a seeing camera's line of sight and the surface normal; then the
Chamfer completeness of a mesh split by that view count. Usage: viscount.py SCENE_FOLDER MESH [MESH...] (numpy, scipy, trimesh with rtree; images
assumed 400x300, the catalogue's size; 1 500 points take about 5 minutes)."""
import sys, numpy as np, trimesh
from scipy.spatial import cKDTree
scene = sys.argv[1]
g = trimesh.load(scene + '/gt_mesh.ply')
pts = np.asarray(trimesh.load(scene + '/Points/stl/' + __import__('os').listdir(scene + '/Points/stl')[0]).vertices)
rng = np.random.default_rng(0)
sel = rng.choice(len(pts), 1500, replace=False); P = pts[sel]
_, _, tri = trimesh.proximity.closest_point(g, P)
N = g.face_normals[tri]
cams = np.load(scene + '/cameras_sphere.npz')
W, H = 400, 300
ints = trimesh.ray.ray_triangle.RayMeshIntersector(g)
count = np.zeros(len(P), int); best = np.full(len(P), 90.0)
k = 0
while f'world_mat_{k}' in cams:
    M = cams[f'world_mat_{k}'][:3]
    C = -np.linalg.inv(M[:, :3]) @ M[:, 3]
    x = np.c_[P, np.ones(len(P))] @ M.T
    u, v, z = x[:, 0] / x[:, 2], x[:, 1] / x[:, 2], x[:, 2]
    d = P - C; dist = np.linalg.norm(d, axis=1); d /= dist[:, None]
    facing = (N * -d).sum(1)
    cand = (z > 0) & (u >= 0) & (u < W) & (v >= 0) & (v < H) & (facing > 0)
    idx = np.where(cand)[0]
    first = np.full(len(idx), np.inf)
    for s0 in range(0, len(idx), 1000):
        ii = idx[s0:s0 + 1000]
        loc, ri, _ = ints.intersects_location(np.repeat(C[None], len(ii), 0), d[ii], multiple_hits=False)
        first[s0 + ri] = np.linalg.norm(loc - C, axis=1)
    ok = first >= dist[idx] - 0.05
    vis = idx[ok]
    count[vis] += 1
    best[vis] = np.minimum(best[vis], np.degrees(np.arccos(np.clip(facing[vis], -1, 1))))
    k += 1
print(f"{k} cameras; GT sample {len(P)}; view count quantiles", np.percentile(count, [5, 25, 50, 75, 95]))
bins = [(0, 0), (1, 2), (3, 5), (6, 10), (11, 99)]
for mp in sys.argv[2:]:
    m = trimesh.load(mp); s, _ = trimesh.sample.sample_surface(m, 400000, seed=0)
    dd, _ = cKDTree(s).query(P)
    keep = dd < 20
    print(mp, "completeness (DTU rule: mean of distances < 20 mm)", dd[keep].mean().round(3))
    for lo, hi in bins:
        b = (count >= lo) & (count <= hi)
        kb = b & keep
        print(f"  seen by {lo}-{hi} cameras: {b.mean()*100:5.1f}% of GT points, mean {dd[kb].mean() if kb.any() else 0:6.2f} mm, share of the completeness sum {dd[kb].sum()/dd[keep].sum()*100:5.1f}%")
    for lo, hi in [(0, 60), (60, 75), (75, 90)]:
        b = (best >= lo) & (best < hi) & (count > 0); kb = b & keep
        print(f"  best view angle {lo}-{hi} deg: {b.mean()*100:5.1f}% of GT points, mean {dd[kb].mean() if kb.any() else 0:6.2f} mm, share {dd[kb].sum()/dd[keep].sum()*100:5.1f}%")
