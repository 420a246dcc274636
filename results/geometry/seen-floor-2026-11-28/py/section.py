import os, sys, numpy as np, trimesh
from PIL import Image, ImageDraw
sc, far, out = sys.argv[1], sys.argv[2], sys.argv[3]
g = trimesh.load(sc + '/gt_mesh.ply'); V = g.vertices; c = V.mean(0)
w, U = np.linalg.eigh(np.cov((V - c).T)); i = np.argmax([abs(w[k] - np.delete(w, k).mean()) for k in range(3)]); a = U[:, i]
e1 = np.cross(a, [1, 0, 0]); e1 /= np.linalg.norm(e1); e2 = np.cross(a, e1)
X = np.load(far); P = X[:, :3]; dd = X[:, 3]
import os as _o
if _o.environ.get('V3'): dd = np.where(X[:,4]==3, dd, 0)
d = P - c; az = np.degrees(np.arctan2(d @ e2, d @ e1))
sel = dd > float(os.environ.get('TH',5))
h, ed = np.histogram(az[sel], bins=36, range=(-180, 180)); print('far>5 az hist', list(zip(ed[:-1].astype(int), h)))
cams = np.load(sc + '/cameras_sphere.npz')
Ps = [cams[f'world_mat_{k}'][:3] for k in range(49)]
Cs = np.array([-np.linalg.inv(P[:, :3]) @ P[:, 3] for P in Ps])
sm = cams['scale_mat_0']; Cw = Cs  # world coords
dc = Cw - c; caz = np.degrees(np.arctan2(dc @ e2, dc @ e1)); print('camera az range', caz.min(), caz.max(), 'elev', np.degrees(np.arcsin((dc @ a) / np.linalg.norm(dc, axis=1))).min(), np.degrees(np.arcsin((dc @ a) / np.linalg.norm(dc, axis=1))).max())
AZ = float(os.environ.get('AZ', np.median(az[sel])))
print('section azimuth', AZ)
r = np.cos(np.radians(AZ)) * e1 + np.sin(np.radians(AZ)) * e2
n = np.cross(a, r)
OX=float(os.environ.get('OX',0)); OY=float(os.environ.get('OY',0)); W = 1100; S = float(os.environ.get('S', 5)); im = Image.new('RGB', (W, W), 'white'); dr = ImageDraw.Draw(im)
cols = [(0, 0, 0), (220, 0, 0), (0, 120, 220), (0, 160, 0)]
for q, name in enumerate([sc + '/gt_mesh.ply'] + sys.argv[4:]):
    m = g if q == 0 else trimesh.load(name)
    for seg in trimesh.intersections.mesh_plane(m, n, c):
        p = [(((x - c) @ r - OX) * S + W / 2, ((x - c) @ a - OY) * S + W / 2) for x in seg]
        dr.line(p, fill=cols[q % 4], width=3 if q == 0 else 1)
# far points near the plane
near = sel & (np.abs(d @ n) < 2)
for p in P[near]:
    x, y = ((p - c) @ r - OX) * S + W / 2, ((p - c) @ a - OY) * S + W / 2
    dr.ellipse([x - 2, y - 2, x + 2, y + 2], outline=(255, 140, 0))
im.save(out)
