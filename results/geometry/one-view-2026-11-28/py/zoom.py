import os, sys, numpy as np, trimesh
from PIL import Image, ImageDraw
sc, out = sys.argv[1], sys.argv[2]
U0,A0,S,panel=[float(x) for x in os.environ.get('Z','-55,-45,12,0').split(',')]
g = trimesh.load(sc + '/gt_mesh.ply'); V = g.vertices; c = V.mean(0)
w, U = np.linalg.eigh(np.cov((V - c).T)); i = np.argmax([abs(w[k] - np.delete(w, k).mean()) for k in range(3)]); a = U[:, i]
e1 = np.cross(a, [1, 0, 0]); e1 /= np.linalg.norm(e1); e2 = np.cross(a, e1)
n=[e1,e2][int(panel)]
cols = [(0, 0, 0), (220, 0, 0), (0, 120, 220), (0, 160, 0)]
W=640; im = Image.new('RGB', (W, W), 'white'); dr = ImageDraw.Draw(im)
u = np.cross(n, a)
for q, name in enumerate([sc + '/gt_mesh.ply'] + sys.argv[3:]):
    m = g if q == 0 else trimesh.load(name)
    for seg in trimesh.intersections.mesh_plane(m, n, c):
        p = [(((x - c) @ u - U0) * S + W / 2, -((x - c) @ a - A0) * S + W / 2) for x in seg]
        dr.line(p, fill=cols[q % 4], width=1 if q else 3)
for k in range(-3,4):  # 5 mm grid ticks
    dr.line([(W/2+k*5*S,0),(W/2+k*5*S,8)],fill=(0,0,0))
im.save(out)
