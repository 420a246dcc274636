# sections.py SCENE_DIR RUN_DIR OUT.png: eight sections across the scene's up axis (the normal of
# ObsMask/Plane*.mat), the truth (black) against the run's closed mesh (red), world mm.
import sys, glob, numpy as np, trimesh, scipy.io as sio, matplotlib
matplotlib.use('Agg'); import matplotlib.pyplot as plt
sd, rd, out = sys.argv[1], sys.argv[2], sys.argv[3]
P = sio.loadmat(glob.glob(sd + '/ObsMask/Plane*.mat')[0])['P'].ravel()
n = P[:3] / np.linalg.norm(P[:3])
u = np.cross(n, [1, 0, 0]); u /= np.linalg.norm(u); v = np.cross(n, u)
gt = trimesh.load(sd + '/gt_mesh.ply'); m = trimesh.load(rd + '/mesh_closed.ply')
h = gt.vertices @ n; lo, hi = h.min(), h.max()
fig, axs = plt.subplots(2, 4, figsize=(16, 8))
for a, t in zip(axs.ravel(), np.linspace(0.05, 0.97, 8)):
    o = n * (lo + t * (hi - lo))
    for mesh, col in [(gt, 'k'), (m, 'r')]:
        s = mesh.section(plane_origin=o, plane_normal=n)
        for e in ([] if s is None else s.discrete):
            a.plot(e @ u, e @ v, col, lw=0.7)
    a.set_title('%.0f %% height' % (100 * t)); a.set_aspect('equal')
plt.tight_layout(); plt.savefig(out, dpi=60)
