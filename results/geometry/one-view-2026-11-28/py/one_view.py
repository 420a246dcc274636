import numpy as np, trimesh, sys
sc='sc/cup400'
g=trimesh.load(sc+'/gt_mesh.ply')
cams=np.load(sc+'/cameras_sphere.npz')
Ps=[cams[f'world_mat_{k}'][:3] for k in range(49)]
Cs=np.array([-np.linalg.inv(P[:,:3])@P[:,3] for P in Ps])
held={8,24,40}
X=np.load(sys.argv[1]); P=X[:,:3]; dd=X[:,3]
sel=np.where(dd>5)[0]
rng=np.random.default_rng(0); sel=rng.choice(sel,min(800,len(sel)),replace=False)
Q=P[sel]
_,_,tri=trimesh.proximity.closest_point(g,Q); N=g.face_normals[tri]
ntrain=np.zeros(len(Q),int); nheld=np.zeros(len(Q),int)
inter=trimesh.ray.ray_triangle.RayMeshIntersector(g)
for k in range(49):
    h=(Ps[k]@np.c_[Q,np.ones(len(Q))].T).T; u=h[:,0]/h[:,2]; v=h[:,1]/h[:,2]
    ok=(h[:,2]>0)&(u>=0)&(u<400)&(v>=0)&(v<300)&(((Cs[k]-Q)*N).sum(1)>0)
    idx=np.where(ok)[0]
    if len(idx)==0: continue
    d=Q[idx]-Cs[k]; L=np.linalg.norm(d,axis=1); d/=L[:,None]
    locs,ri,_=inter.intersects_location(np.repeat(Cs[k][None],len(idx),0),d,multiple_hits=False)
    first=np.full(len(idx),np.inf)
    for l,r in zip(locs,ri): first[r]=min(first[r],np.linalg.norm(l-Cs[k]))
    vis=first>=L-0.05
    if k in held: nheld[idx[vis]]+=1
    else: ntrain[idx[vis]]+=1
print(sys.argv[1],'far pts',len(Q),'train views seeing: hist',np.bincount(np.minimum(ntrain,10)),' held-only',((ntrain==0)&(nheld>0)).sum(),'none',((ntrain==0)&(nheld==0)).sum())
