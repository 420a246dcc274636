# Outside-style test meshes built with manifold3d (not from the project's shape code): a mug with a
# handle (genus 1, a cavity) and a chair with thin legs and stretchers (genus 4). Units mm, +z up.
import numpy as np, trimesh, manifold3d as mf
def tm(m):
    me = m.to_mesh()
    return trimesh.Trimesh(np.asarray(me.vert_properties)[:, :3], np.asarray(me.tri_verts), process=True)
# mug
outer = mf.Manifold.cylinder(90, 40, 40, 96)
inner = mf.Manifold.cylinder(90, 35, 35, 96).translate([0, 0, 6])
handle = mf.Manifold.cylinder(8, 22, 22, 64) - mf.Manifold.cylinder(10, 15, 15, 64).translate([0, 0, -1])
handle = handle.translate([0, 0, -4]).rotate([90, 0, 0]).translate([40, 0, 48])
handle = handle - mf.Manifold.cylinder(90, 38, 38, 96)
mug = (outer - inner) + handle
t = tm(mug); print('mug', t.is_watertight, t.euler_number, len(t.faces)); t.export('mug.ply')
# chair
def box(sx, sy, sz, x, y, z):
    return mf.Manifold.cube([sx, sy, sz]).translate([x, y, z])
parts = [box(80, 80, 6, 0, 0, 80)]
for (x, y) in [(0, 0), (75, 0), (0, 75), (75, 75)]:
    parts.append(box(5, 5, 80, x, y, 0))
parts += [box(80, 4, 4, 0, 0.5, 30), box(80, 4, 4, 0, 75.5, 30), box(4, 80, 4, 0.5, 0, 34), box(4, 80, 4, 75.5, 0, 34)]
parts.append(box(80, 6, 70, 0, 74, 86))
ch = parts[0]
for p in parts[1:]:
    ch = ch + p
t = tm(ch); print('chair', t.is_watertight, t.euler_number, len(t.faces)); t.export('chair.ply')
