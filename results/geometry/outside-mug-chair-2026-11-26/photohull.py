# photohull.py SCENE_DIR OUT.ply [voxel_mm]
# The photo hull of the true mesh under the scene's rig: the true solid plus all space that no
# camera sees (every line of sight to it crosses the true surface first). It renders the same
# images and masks as the true mesh in every view, so no image-based method can tell the two
# apart. Meshed by marching cubes of the (lightly smoothed) occupancy, written in world mm.
import sys, json, numpy as np, trimesh
from scipy.ndimage import gaussian_filter
from skimage.measure import marching_cubes
sd, out = sys.argv[1], sys.argv[2]
vox = float(sys.argv[3]) if len(sys.argv) > 3 else 0.6
meta = json.load(open(sd + '/meta.json'))
W, H = meta['resolution']
gt = trimesh.load(sd + '/gt_mesh.ply', process=False)
cams = np.load(sd + '/cameras_sphere.npz')
n = meta['views']
P = [cams['world_mat_%d' % i][:3] for i in range(n)]
ray = trimesh.ray.ray_pyembree.RayMeshIntersector(gt)
# depth maps of the true mesh (camera z, mm) at pixel centres
us, vs = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
pix = np.stack([us.ravel(), vs.ravel(), np.ones(W * H)], 1)
depth = []
for i in range(n):
    M = P[i][:, :3]; t = P[i][:, 3]
    Minv = np.linalg.inv(M)
    c = -Minv @ t                      # camera centre, world mm
    d = pix @ Minv.T                   # directions with z (depth) = 1 per unit
    dn = d / np.linalg.norm(d, axis=1, keepdims=True)
    loc, idx, _ = ray.intersects_location(np.repeat(c[None], len(d), 0), dn, multiple_hits=False)
    z = np.full(W * H, np.inf)
    # camera depth of the hit = (M x + t)_z
    z[idx] = (loc @ M[2] + t[2])
    depth.append(z.reshape(H, W))
lo = gt.bounds[0] - 8; hi = gt.bounds[1] + 8
ax = [np.arange(lo[a], hi[a] + vox, vox) for a in range(3)]
shape = tuple(len(a) for a in ax)
print('grid', shape, 'voxels', np.prod(shape))
X, Y, Z = np.meshgrid(*ax, indexing='ij')
pts = np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1)
free = np.zeros(len(pts), bool)
margin = 0.5 * vox
for i in range(n):
    q = pts @ P[i][:, :3].T + P[i][:, 3]
    z = q[:, 2]
    u = np.floor(q[:, 0] / z).astype(np.int64); v = np.floor(q[:, 1] / z).astype(np.int64)
    ok = (z > 0) & (u >= 0) & (u < W) & (v >= 0) & (v < H)
    dz = np.full(len(pts), -np.inf)
    dz[ok] = depth[i][v[ok], u[ok]]
    free |= ok & (z < dz - margin)
occ = (~free).reshape(shape).astype(np.float32)
print('occupied share', occ.mean())
f = gaussian_filter(occ, 0.7)
vs_, fs, _, _ = marching_cubes(f, 0.5, spacing=(vox, vox, vox))
m = trimesh.Trimesh(vs_ + lo, fs, process=True)
# keep what lies inside the padded box minus a voxel (the grid border closes the unseen space)
m.export(out)
print('faces', len(m.faces), 'euler', m.euler_number)
