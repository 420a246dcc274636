import numpy as np, trimesh, os
from scipy.spatial import cKDTree
sc='sc/cup400'; dump='dumps/cur'; s=float(open(dump+'/scale.txt').read())
k2=trimesh.load('r/v1w10/mesh.ply',process=False)
rng=np.random.default_rng(0); sel=rng.choice(len(k2.faces),20000,replace=False)
Q=k2.triangles_center[sel]; N=k2.face_normals[sel]
cams=np.load(sc+'/cameras_sphere.npz'); Ps=[cams[f'world_mat_{k}'][:3] for k in range(49)]
Cs=np.array([-np.linalg.inv(P[:,:3])@P[:,3] for P in Ps]); held={8,24,40}
train=[k for k in range(49) if k not in held]
best=np.full(len(Q),np.inf)
for vi,k in enumerate(train):
    h=(Ps[k]@np.c_[Q,np.ones(len(Q))].T).T; u=h[:,0]/h[:,2]; v=h[:,1]/h[:,2]
    tc=Q-Cs[k]; L=np.linalg.norm(tc,axis=1); cosv=(tc*N).sum(1)/L
    ok=(h[:,2]>0)&(u>=0)&(u<400)&(v>=0)&(v<300)&(cosv<0)
    t=np.fromfile(f'{dump}/t{vi:02}.f32',np.float32).reshape(300,400)
    ii=np.where(ok)[0]
    e=t[np.floor(v[ii]).astype(int),np.floor(u[ii]).astype(int)]*s-L[ii]
    f=np.isfinite(e); best[ii[f]]=np.minimum(best[ii[f]],np.abs(e[f]))
print('k2 faces best |e|<1',(best<1).mean(),'<2',(best<2).mean(),'<5',(best<5).mean())
