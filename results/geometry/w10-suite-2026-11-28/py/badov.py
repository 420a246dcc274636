import numpy as np, trimesh, os
from scipy.spatial import cKDTree
sc='sc/cup400'
g=trimesh.load(sc+'/gt_mesh.ply'); V=g.vertices; c=V.mean(0)
w,U=np.linalg.eigh(np.cov((V-c).T)); i=np.argmax([abs(w[k]-np.delete(w,k).mean()) for k in range(3)]); a=U[:,i]
k1=trimesh.load('r/v1w10_k1/mesh.ply',process=False); k2=trimesh.load('r/v1w10/mesh.ply',process=False)
c1=k1.triangles_center; d,_=cKDTree(k2.triangles_center).query(c1); new=np.where(d>1e-4)[0]
Q=c1[new]; A=k1.area_faces[new]; N=k1.face_normals[new]
cp,dist,tri=trimesh.proximity.closest_point(g,Q)
sg=((Q-cp)*g.face_normals[tri]).sum(1)
dd=Q-c; ax=dd@a; r=np.linalg.norm(dd-ax[:,None]*a,axis=1)
print('GT axial range', ((V-c)@a).min(), ((V-c)@a).max(), 'radius max', np.linalg.norm((V-c)-((V-c)@a)[:,None]*a,axis=1).max())
for lo,hi in [(0,2),(2,5),(5,1e9)]:
    b=(dist>=lo)&(dist<hi)
    print(f'dist {lo}-{hi}: area {A[b].sum()/A.sum():.2f}; outside(sg>0) {A[b&(sg>0)].sum()/max(A[b].sum(),1e-9):.2f}; axial q10/50/90',np.percentile(ax[b],[10,50,90]).round(1),'radius q10/50/90',np.percentile(r[b],[10,50,90]).round(1))
# components of new faces
sub=trimesh.Trimesh(k1.vertices,k1.faces[new],process=False)
lab=trimesh.graph.connected_component_labels(sub.face_adjacency,node_count=len(new))
ncomp=lab.max()+1; ar=np.bincount(lab,weights=A); md=np.bincount(lab,weights=A*dist)/ar
o=np.argsort(-ar)[:15]
for j in o: print('comp',j,'area %.1f mean dist %.2f faces %d'%(ar[j],md[j],(lab==j).sum()), 'axial %.1f radius %.1f'%(np.mean(ax[lab==j]),np.mean(r[lab==j])))
print('n comps',ncomp)
dump='dumps/cur'; s=float(open(dump+'/scale.txt').read())
cams=np.load(sc+'/cameras_sphere.npz'); Ps=[cams[f'world_mat_{k}'][:3] for k in range(49)]
Cs=np.array([-np.linalg.inv(P[:,:3])@P[:,3] for P in Ps]); held={8,24,40}
train=[k for k in range(49) if k not in held]
best=np.full(len(Q),np.inf); sgn=np.zeros(len(Q)); nfront=np.zeros(len(Q),int)
for vi,k in enumerate(train):
    h=(Ps[k]@np.c_[Q,np.ones(len(Q))].T).T; u=h[:,0]/h[:,2]; v=h[:,1]/h[:,2]
    tc=Q-Cs[k]; L=np.linalg.norm(tc,axis=1); cosv=(tc*N).sum(1)/L
    ok=(h[:,2]>0)&(u>=0)&(u<400)&(v>=0)&(v<300)&(cosv<-0.3)
    t=np.fromfile(f'{dump}/t{vi:02}.f32',np.float32).reshape(300,400)
    ii=np.where(ok)[0]; nfront[ii]+=1
    e=t[np.floor(v[ii]).astype(int),np.floor(u[ii]).astype(int)]*s-L[ii]
    f=np.isfinite(e); jj=ii[f]; upd=np.abs(e[f])<best[jj]; best[jj[upd]]=np.abs(e[f])[upd]; sgn[jj[upd]]=e[f][upd]
for j in o[:10]:
    b=lab==j; print('comp',j,'mean dist %.2f'%md[j],'front-facing cams median',np.median(nfront[b]),' best|e|<3: %.2f'%(best[b]<3).mean(),' median best e %.1f'%np.median(sgn[b]))
print('---- comp 259 per camera (all in-image, facing any way)')
b=np.where(lab==o[0])[0]; Qb=Q[b]
inter=trimesh.ray.ray_triangle.RayMeshIntersector(trimesh.load('r/v1w10/mesh_raw.ply',process=False))
sel=b[np.random.default_rng(0).choice(len(b),60,replace=False)]
for vi,k in enumerate(train):
    Qs=Q[sel]; h=(Ps[k]@np.c_[Qs,np.ones(len(Qs))].T).T; u=h[:,0]/h[:,2]; v=h[:,1]/h[:,2]
    ok=(h[:,2]>0)&(u>=0)&(u<400)&(v>=0)&(v<300)
    if not ok.any(): continue
    tc=Qs-Cs[k]; L=np.linalg.norm(tc,axis=1); dd_=tc/L[:,None]
    locs,ri,_=inter.intersects_location(np.repeat(Cs[k][None],ok.sum(),0),dd_[ok],multiple_hits=False)
    first=np.full(ok.sum(),np.inf)
    for l,rr in zip(locs,ri): first[rr]=min(first[rr],np.linalg.norm(l-Cs[k]))
    vis=first>=L[ok]-0.05
    if vis.sum()==0: continue
    t=np.fromfile(f'{dump}/t{vi:02}.f32',np.float32).reshape(300,400); gg=np.fromfile(f'{dump}/g{vi:02}.f32',np.float32).reshape(300,400); ff=np.fromfile(f'{dump}/f{vi:02}.u8',np.uint8).reshape(300,400)
    pu=np.floor(u[ok][vis]).astype(int); pv=np.floor(v[ok][vis]).astype(int)
    print('cam',k,'vis',vis.sum(),'of',ok.sum(),' prior-face mm', np.round(t[pv,pu]*s-L[ok][vis],1)[:12],' truth-face', np.round(gg[pv,pu]*s-L[ok][vis],1)[:12], 'flags', ff[pv,pu][:12])
