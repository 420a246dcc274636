"""Completeness of cup meshes split by part of the cup (outer wall, inner wall by azimuth and by
axial position, bottoms, rim and fillets), under the DTU rule (distances >= 20 mm left out of
the mean). Usage: parts.py SCENE_FOLDER MESH... (numpy, scipy, trimesh)."""
import sys, os, numpy as np, trimesh
from scipy.spatial import cKDTree
sc = sys.argv[1]
g = trimesh.load(sc + '/gt_mesh.ply')
pts = np.asarray(trimesh.load(sc + '/Points/stl/' + os.listdir(sc + '/Points/stl')[0]).vertices)
P = pts[np.random.default_rng(0).choice(len(pts), 200000, replace=False)]
V = g.vertices; c = V.mean(0)
w, U = np.linalg.eigh(np.cov((V - c).T))
# the axis: the eigenvector whose eigenvalue differs from the other two
i = np.argmax([abs(w[k] - np.delete(w, k).mean()) for k in range(3)]); a = U[:, i]
_, _, tri = trimesh.proximity.closest_point(g, P)
N = g.face_normals[tri]
d = P - c; ax = d @ a; r = d - ax[:, None] * a; rn = np.linalg.norm(r, axis=1); rh = r / rn[:, None]
nr = (N * rh).sum(1); na = N @ a
cls = np.full(len(P), 'rim/fillet', dtype=object)
cls[nr > 0.7] = 'outer wall'; cls[nr < -0.7] = 'inner wall'
cls[(np.abs(na) > 0.7) & (rn < 50)] = 'bottom (in/out)'
for name in sys.argv[2:]:
    m = trimesh.load(name); s, _ = trimesh.sample.sample_surface(m, 600000, seed=0)
    dd, _ = cKDTree(s).query(P); keep = dd < 20
    print(name, 'completeness', dd[keep].mean().round(3))
    for k in ['outer wall', 'inner wall', 'bottom (in/out)', 'rim/fillet']:
        b = cls == k; kb = b & keep
        print(f"   {k:16s} {b.mean()*100:5.1f}% of GT, mean {dd[kb].mean():5.2f} mm, median {np.median(dd[b]):5.2f}, share {dd[kb].sum()/dd[keep].sum()*100:5.1f}%")
    # inner wall by depth along the axis (10 bins)
    b = cls == 'inner wall'
    if b.any():
        q = np.linspace(ax[b].min(), ax[b].max(), 7)
        print('   inner wall by axial position (bins from one end to the other): ' + ' '.join(f"{np.median(dd[b & (ax>=q[j]) & (ax<q[j+1])]):.2f}" for j in range(6)))
# inner wall by azimuth: angle between the radial direction and the mean camera direction
cams = np.load(sc + '/cameras_sphere.npz'); Cs = []
k = 0
while f'world_mat_{k}' in cams:
    M = cams[f'world_mat_{k}'][:3]; Cs.append(-np.linalg.inv(M[:, :3]) @ M[:, 3]); k += 1
Cs = np.array(Cs); cd = Cs.mean(0) - c; cd -= (cd @ a) * a; cd /= np.linalg.norm(cd)
az = np.degrees(np.arccos(np.clip(rh @ cd, -1, 1)))  # 0 = towards the cameras (near side), 180 = far side
camaz = [np.degrees(np.arccos(np.clip(((x - c) - ((x - c) @ a) * a) @ cd / np.linalg.norm((x - c) - ((x - c) @ a) * a), -1, 1))) for x in Cs]
print('camera azimuths from their mean direction: max', np.round(max(camaz), 1), '; camera elevation above the axis-normal plane (deg):', np.round(np.percentile([np.degrees(np.arcsin(((x - c) @ a) / np.linalg.norm(x - c))) for x in Cs], [0, 50, 100]), 1))
for name in sys.argv[2:]:
    m = trimesh.load(name); s, _ = trimesh.sample.sample_surface(m, 600000, seed=0)
    dd, _ = cKDTree(s).query(P)
    b = cls == 'inner wall'
    bins = [0, 45, 90, 135, 180]
    print(name, 'inner wall median distance by azimuth (0 = camera side):', ' '.join(f"{bins[j]}-{bins[j+1]}: {np.median(dd[b & (az>=bins[j]) & (az<bins[j+1])]):.2f} ({(b & (az>=bins[j]) & (az<bins[j+1])).sum()/b.sum()*100:.0f}%)" for j in range(4)))
