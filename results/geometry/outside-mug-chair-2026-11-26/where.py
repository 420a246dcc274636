# where.py SCENE_DIR RUN_DIR: clusters of closed-mesh vertices far from the true mesh
import sys, numpy as np, trimesh
from scipy.spatial import cKDTree
sd, rd = sys.argv[1], sys.argv[2]
thr = float(sys.argv[3]) if len(sys.argv) > 3 else 1.5
gt = trimesh.load(sd + '/gt_mesh.ply', process=False)
mc = trimesh.load(rd + '/mesh_closed.ply', process=False)
ms = trimesh.load(rd + '/mesh.ply', process=False)
gpts, _ = trimesh.sample.sample_surface(gt, 400000, seed=0)
d, _ = cKDTree(gpts).query(mc.vertices)
seen = cKDTree(ms.vertices).query(mc.vertices)[0] < 1e-4
far = d > thr
print('closed verts', len(mc.vertices), 'far', far.sum(), 'far&seen', (far & seen).sum())
# cluster far vertices by mesh connectivity
import networkx as nx
e = mc.edges_unique
g = nx.Graph(); g.add_nodes_from(np.where(far)[0].tolist())
g.add_edges_from(e[far[e[:, 0]] & far[e[:, 1]]].tolist())
cs = sorted(nx.connected_components(g), key=len, reverse=True)
for c in cs[:12]:
    c = np.array(list(c))
    v = mc.vertices[c]
    print(len(c), 'seen %.2f' % seen[c].mean(), 'maxd %.1f' % d[c].max(), 'bbox', v.min(0).round(1), v.max(0).round(1))
