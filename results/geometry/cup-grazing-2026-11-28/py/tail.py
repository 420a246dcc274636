import sys, os, numpy as np, trimesh
from scipy.spatial import cKDTree
sc = sys.argv[1]; seen = trimesh.load(sys.argv[2])
g = trimesh.load(sc + '/gt_mesh.ply')
pts = np.asarray(trimesh.load(sc + '/Points/stl/' + os.listdir(sc + '/Points/stl')[0]).vertices)
P = pts[np.random.default_rng(0).choice(len(pts), 200000, replace=False)]
ss,_ = trimesh.sample.sample_surface(seen, 1500000, seed=0)
ds,_ = cKDTree(ss).query(P); isseen = ds < 0.3
V = g.vertices; c = V.mean(0)
w, U = np.linalg.eigh(np.cov((V - c).T))
i = np.argmax([abs(w[k] - np.delete(w, k).mean()) for k in range(3)]); a = U[:, i]
_, _, tri = trimesh.proximity.closest_point(g, P)
N = g.face_normals[tri]
d = P - c; ax = d @ a; r = d - ax[:, None] * a; rn = np.linalg.norm(r, axis=1); rh = r / rn[:, None]
nr = (N * rh).sum(1); na = N @ a
cls = np.full(len(P), 'rim/fillet', dtype=object)
cls[nr > 0.7] = 'outer'; cls[nr < -0.7] = 'inner'
cls[(np.abs(na) > 0.7) & (rn < 50)] = 'bottom'
cams = np.load(sc + '/cameras_sphere.npz'); Cs=[]; k=0
while f'world_mat_{k}' in cams:
    M = cams[f'world_mat_{k}'][:3]; Cs.append(-np.linalg.inv(M[:, :3]) @ M[:, 3]); k += 1
Cs=np.array(Cs); cd = Cs.mean(0)-c; cd -= (cd@a)*a; cd/=np.linalg.norm(cd)
az = np.degrees(np.arccos(np.clip(rh@cd,-1,1)))
print('axis', a, 'ax range', ax.min().round(1), ax.max().round(1), 'cam side along axis', ((Cs.mean(0)-c)@a).round(1))
for name in sys.argv[3:]:
    m = trimesh.load(name); s,_ = trimesh.sample.sample_surface(m, 600000, seed=0)
    dd,_ = cKDTree(s).query(P); keep=dd<20; tot=dd[keep].sum()
    t = isseen & keep
    print(name)
    for k in ['outer','inner','bottom','rim/fillet']:
        for lo,hi in [(0,45),(45,90),(90,135),(135,180)]:
            b = t & (cls==k) & (az>=lo)&(az<hi)
            if b.sum()<50: continue
            excess = (dd[b]-0.19).clip(0).sum()/tot
            print(f'  {k:10s} az {lo:3d}-{hi:3d} n {b.sum():6d} mean {dd[b].mean():.2f} p90 {np.quantile(dd[b],0.9):.2f} excess share {excess:.3f}')
    b = t & (cls=='inner')
    q = np.linspace(ax[b].min(), ax[b].max(), 7)
    print('  inner by axial:', ' '.join(f'{dd[b&(ax>=q[j])&(ax<q[j+1])].mean():.2f}' for j in range(6)), 'bins', q.round(0))
    b = t & (cls=='outer')
    q = np.linspace(ax[b].min(), ax[b].max(), 7)
    print('  outer by axial:', ' '.join(f'{dd[b&(ax>=q[j])&(ax<q[j+1])].mean():.2f}' for j in range(6)))
    idx = cKDTree(s).query(P)[1]
    off = ((s[idx]-P)*N).sum(1)
    for k,(lo,hi) in [('outer',(45,90)),('outer',(90,135)),('inner',(45,90)),('inner',(90,135))]:
        b = t&(cls==k)&(az>=lo)&(az<hi)&(dd>1)
        print(f'  signed offset along GT normal for {k} {lo}-{hi} with d>1: n {b.sum()} median {np.median(off[b]):.2f} share positive {(off[b]>0).mean():.2f}; height bins', np.histogram(ax[b], bins=6, range=(-58,92))[0])
