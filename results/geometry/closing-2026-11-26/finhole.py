"""Holes through a thin ground-truth part: casts a 90 x 90 grid of rays along the part's thinnest
axis (its oriented bounding box) through a reconstruction and lists the rays inside the part's
outline (5 % in from its edges) that hit no surface.

Usage: finhole.py GT_MESH MESH   (the part is the ground-truth component with the thinnest box;
on `thin` that is the 2.2 mm fin). Needs numpy, trimesh, rtree.
"""
import sys
import numpy as np
import trimesh

gt = trimesh.load(sys.argv[1])
parts = gt.split(only_watertight=False)
part = min(parts, key=lambda p: p.bounding_box_oriented.primitive.extents.min())
box = part.bounding_box_oriented.primitive
T, ext = box.transform, box.extents
ax = int(np.argmin(ext))
n = T[:3, ax]
u, v = [a for a in range(3) if a != ax]
mesh = trimesh.load(sys.argv[2])
grid = np.linspace(-0.5, 0.5, 90)
uv = np.array([(a, b) for a in grid for b in grid])
centres = T[:3, 3] + uv[:, :1] * ext[u] * T[:3, u] + uv[:, 1:] * ext[v] * T[:3, v]
origins = centres - 10.0 * n
_, ray, _ = mesh.ray.intersects_location(origins, np.tile(n, (len(origins), 1)),
                                         multiple_hits=True)
hits = np.bincount(ray, minlength=len(origins))
inner = (np.abs(uv) < 0.47).all(1) & (hits == 0)
print(f'part extents {np.round(ext, 2)} mm; rays {len(origins)}, '
      f'inside the outline with no hit: {inner.sum()}')
for c in centres[inner]:
    print('  no surface at', np.round(c, 1))
