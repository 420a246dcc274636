import numpy as np, trimesh, json
sc='/work/cup/sc/cup400'
P=np.array(json.load(open(f'{sc}/meta.json'))['gt']['plane']); n=P[:3]/np.linalg.norm(P[:3])
v=np.asarray(trimesh.load(f'{sc}/gt_mesh.ply').vertices); base=(v@n).min()
c=v.mean(0); c=c-n*(c@n); s=1.1320287581835358
def cav(p):
    q=p-np.outer(p@n,n)-c; r=np.linalg.norm(q,axis=1)/s; z=((p@n)-base)/s
    return (r<55.5)&(z>7.5)&(z<129)
rd=lambda p: np.asarray(trimesh.load(p).vertices)
k1=rd('h05/gt_kept.ply'); k2=rd('h05k2/gt_kept.ply'); r2=rd('h05k2/ramp.ply')
pts=np.vstack([k1[~cav(k1)], k2[cav(k2)], r2[cav(r2)]])
trimesh.PointCloud(pts).export('h05k2/hull_cavity_only.ply')
