# Where the GT points are that the visible cut loses: far from mesh.ply, near mesh_closed.ply.
import sys, numpy as np, trimesh
from scipy.spatial import cKDTree
run, gt = sys.argv[1], sys.argv[2]
import glob
stl = glob.glob(gt + '/Points/stl/*.ply')[0]
P = np.asarray(trimesh.load(stl).vertices)
vis = trimesh.load(run + '/mesh.ply'); clo = trimesh.load(run + '/mesh_closed.ply')
def dist(m):
    pts, _ = trimesh.sample.sample_surface_even(m, 400000, seed=0) if False else (trimesh.sample.sample_surface(m, 1500000, seed=0)[0], None)
    return cKDTree(pts).query(P)[0]
dv, dc = dist(vis), dist(clo)
lost = (dv > 1.0) & (dc < 0.6)
print('gt points', len(P), 'lost', lost.sum(), f'{lost.mean()*100:.1f}%', 'mean dv', dv.mean().round(3), 'dc', dc.mean().round(3))
# camera centres
cams = np.load(gt + '/cameras_sphere.npz')
C = []
for i in range(64):
    k = f'world_mat_{i}'
    if k not in cams: break
    Pm = cams[k][:3]
    K, R, t = None, None, None
    import numpy.linalg as la
    M = Pm[:, :3]; c = -la.solve(M, Pm[:, 3]); C.append(c)
C = np.array(C)
print('cams', len(C))
# normals of the GT mesh at lost points
gm = trimesh.load(gt + '/gt_mesh.ply')
tri = cKDTree(gm.triangles_center).query(P[lost][:3000])[1]
N = gm.face_normals[tri]
Q = P[lost][:3000]
# for each lost point: number of cameras in front of the face (n·(c-p) > 0) and the max cos
cosv = np.einsum('mk,mnk->mn', N, (C[None] - Q[:, None]) / np.linalg.norm(C[None] - Q[:, None], axis=2, keepdims=True))
front = (cosv > 0).sum(1)
print('cameras facing the lost points: median', np.median(front), 'hist', np.bincount(np.minimum(front, 10)))
print('max cos (1 = head-on): quartiles', np.percentile(cosv.max(1), [10, 25, 50, 75, 90]).round(3))
print('dv of lost: quartiles', np.percentile(dv[lost],[25,50,75,95]).round(2), 'share of comp sum from lost', (dv[lost].sum()/dv.sum()).round(3))
print('lost z/y ranges', Q.min(0).round(0), Q.max(0).round(0), 'all', P.min(0).round(0), P.max(0).round(0))
