"""Where the handles of a closed mesh are: a discrete Reeb graph of the height along one axis.

Faces are binned by the height of their centroid (NBINS bins); the nodes are the connected
pieces of each bin, the edges join pieces of neighbouring bins that share a mesh edge. For a
closed surface the graph's independent cycles count its handles (the genus), and each cycle's
faces say where a handle is.

Usage: reeb.py MESH [AXIS (0/1/2, default 1)] [NBINS (default 200)]. Needs trimesh, networkx.
"""
import sys
import numpy as np
import trimesh
import networkx as nx

m = trimesh.load(sys.argv[1], process=True)
axis = int(sys.argv[2]) if len(sys.argv) > 2 else 1
nb = int(sys.argv[3]) if len(sys.argv) > 3 else 200
h = m.vertices[:, axis]
fh = h[m.faces].mean(1)
b = np.minimum(((fh - h.min()) / (h.max() - h.min()) * nb).astype(int), nb - 1)
adj = m.face_adjacency
same = b[adj[:, 0]] == b[adj[:, 1]]
fg = nx.Graph()
fg.add_nodes_from(range(len(m.faces)))
fg.add_edges_from(adj[same].tolist())
piece = np.zeros(len(m.faces), int)
for i, c in enumerate(nx.connected_components(fg)):
    piece[list(c)] = i
R = nx.Graph()
R.add_nodes_from(np.unique(piece).tolist())
cross = adj[~same]
R.add_edges_from(set(map(tuple, np.sort(np.stack([piece[cross[:, 0]], piece[cross[:, 1]]], 1),
                                        1).tolist())))
cycles = R.number_of_edges() - R.number_of_nodes() + nx.number_connected_components(R)
print(f'Reeb graph: {R.number_of_nodes()} nodes, {R.number_of_edges()} edges, {cycles} cycles')
for c in nx.cycle_basis(R):
    f = np.where(np.isin(piece, c))[0]
    ctr = m.triangles_center[f]
    print(f'cycle through {len(c)} pieces, {len(f)} faces, box {ctr.min(0).round(1)} '
          f'to {ctr.max(0).round(1)}')
