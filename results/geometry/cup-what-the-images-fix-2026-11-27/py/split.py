import numpy as np, trimesh, sys, json
d=sys.argv[1]
P=np.array(json.load(open('/work/cup/sc/cup400/meta.json'))['gt']['plane'])
n=P[:3]/np.linalg.norm(P[:3])
m=trimesh.load('/work/cup/sc/cup400/gt_mesh.ply'); v=np.asarray(m.vertices)
h=v@n; base=h.min()
c=v.mean(0); c=c-n*(c@n)  # axis point (perp component)
def rad(p): q=p-np.outer(p@n,n)-c; return np.linalg.norm(q,axis=1)
r_out=rad(v).max(); s=r_out/60.0
print('height',h.max()-base,'r_out',r_out,'scale',s)
rd=lambda p: np.asarray(trimesh.load(p).vertices)
ramp=rd(f'{d}/ramp.ply'); kept=rd(f'{d}/gt_kept.ply')
cav=(rad(ramp)<55*s)&((ramp@n)-base>8*s*0.99)
print('ramp',len(ramp),'cavity',cav.sum())
trimesh.PointCloud(np.vstack([kept,ramp[cav]])).export(f'{d}/hull_cavity.ply')
trimesh.PointCloud(np.vstack([kept,ramp[~cav]])).export(f'{d}/hull_outside.ply')
