import numpy as np, trimesh, sys, os
from scipy.spatial import cKDTree
sc='sc/cup400'; dump='dumps/cur'; s=float(open(dump+'/scale.txt').read())
k1=trimesh.load('r/v1w10_k1/mesh.ply',process=False); k2=trimesh.load('r/v1w10/mesh.ply',process=False)
c1=k1.triangles_center; d,_=cKDTree(k2.triangles_center).query(c1); new=np.where(d>1e-4)[0]
Q=c1[new]; N=k1.face_normals[new]; A=k1.area_faces[new]
pts=np.asarray(trimesh.load(sc+'/Points/stl/'+os.listdir(sc+'/Points/stl')[0]).vertices)
dg,_=cKDTree(pts).query(Q)
cams=np.load(sc+'/cameras_sphere.npz'); Ps=[cams[f'world_mat_{k}'][:3] for k in range(49)]
Cs=np.array([-np.linalg.inv(P[:,:3])@P[:,3] for P in Ps]); held={8,24,40}
train=[k for k in range(49) if k not in held]
best=np.full(len(Q),np.inf); nfront=np.zeros(len(Q),int); nfin=np.zeros(len(Q),int)
for vi,k in enumerate(train):
    h=(Ps[k]@np.c_[Q,np.ones(len(Q))].T).T; u=h[:,0]/h[:,2]; v=h[:,1]/h[:,2]
    tc=Q-Cs[k]; L=np.linalg.norm(tc,axis=1); cosv=(tc*N).sum(1)/L
    ok=(h[:,2]>0)&(u>=0)&(u<400)&(v>=0)&(v<300)&(cosv<0)
    t=np.fromfile(f'{dump}/t{vi:02}.f32',np.float32).reshape(300,400)
    ii=np.where(ok)[0]; nfront[ii]+=1
    e=t[np.floor(v[ii]).astype(int),np.floor(u[ii]).astype(int)]*s-L[ii]
    f=np.isfinite(e); nfin[ii[f]]+=1
    best[ii[f]]=np.minimum(best[ii[f]],np.abs(e[f]))
print('new faces',len(new),'area',A.sum())
for lo,hi in [(0,0.5),(0.5,2),(2,5),(5,20),(20,1e9)]:
    b=(dg>=lo)&(dg<hi); print(f'GT dist {lo}-{hi} mm: area share {A[b].sum()/A.sum():.2f}; of them, best prior |e|<2: {(best[b]<2).mean():.2f} <5: {(best[b]<5).mean():.2f} none finite: {(nfin[b]==0).mean():.2f}')
b=best<2; print('faces with best|e|<2: area',A[b].sum()/A.sum(),'mean GT dist',np.sum(dg[b]*A[b])/A[b].sum(), ' others', np.sum(dg[~b]*A[~b])/A[~b].sum())
