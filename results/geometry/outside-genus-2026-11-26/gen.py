# Outside-style genus test meshes (trimesh / manifold3d, not the project's shape code). Units mm, +z up.
import numpy as np, trimesh, manifold3d as mf
def tm(m):
    me = m.to_mesh()
    return trimesh.Trimesh(np.asarray(me.vert_properties)[:, :3], np.asarray(me.tri_verts), process=True)
def save(name, t):
    print(name, t.is_watertight, 'genus', (2 - t.euler_number) // 2, len(t.faces), t.bounds.round(1).tolist()); t.export(name + '.ply')
# 1. standing ring: torus R=32 r=9, axis along +y (hole faces the y direction), resting on z=0
t = trimesh.creation.torus(major_radius=32, minor_radius=9, major_sections=96, minor_sections=32)
t.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
t.apply_translation([0, 0, 41]); save('ring', t)
# 2. trefoil knot tube (genus 1)
s = np.linspace(0, 2 * np.pi, 400, endpoint=False)
c = np.stack([np.sin(s) + 2 * np.sin(2 * s), np.cos(s) - 2 * np.cos(2 * s), -np.sin(3 * s)], 1) * 14
n, mseg, r = len(c), 24, 5.0
T = np.roll(c, -1, 0) - np.roll(c, 1, 0); T /= np.linalg.norm(T, axis=1)[:, None]
N = np.zeros_like(T); v = np.cross(T[0], [0, 0, 1.0]); N[0] = v / np.linalg.norm(v)
for i in range(1, n):
    v = N[i - 1] - T[i] * np.dot(N[i - 1], T[i]); N[i] = v / np.linalg.norm(v)
B = np.cross(T, N)
# close the frame twist: rotate progressively so N[n] matches N[0]
ang = np.arctan2(np.dot(np.cross(N[-1], N[0]), T[0]), np.dot(N[-1], N[0]))
V = []
for i in range(n):
    th = ang * i / n; Ni = np.cos(th) * N[i] + np.sin(th) * B[i]; Bi = np.cross(T[i], Ni)
    for j in range(mseg):
        phi = 2 * np.pi * j / mseg; V.append(c[i] + r * (np.cos(phi) * Ni + np.sin(phi) * Bi))
F = []
for i in range(n):
    for j in range(mseg):
        a, b = i * mseg + j, i * mseg + (j + 1) % mseg
        a2, b2 = ((i + 1) % n) * mseg + j, ((i + 1) % n) * mseg + (j + 1) % mseg
        F += [[a, a2, b], [b, a2, b2]]
k = trimesh.Trimesh(np.array(V), np.array(F), process=True)
if k.volume < 0: k.invert()
k.apply_translation([0, 0, -k.bounds[0, 2]]); save('knot', k)
# 3. perforated plate 90x60x8 with three round holes of 16 mm (genus 3), flat on the ground
p = mf.Manifold.cube([90, 60, 8])
for x in (20, 45, 70):
    p = p - mf.Manifold.cylinder(20, 8, 8, 64).translate([x, 30, -5])
save('plate3', tm(p))
# 4. the same ring turned edge-on to the rig (hole axis along x: azimuth 0 looks along +y, so the
#    cameras at azimuth ±45° see the hole obliquely and the central ones not at all)
t = trimesh.load('ring.ply'); t.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 0, 1])); save('ringx', t)
