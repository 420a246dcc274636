"""Accuracy of cup meshes under the DTU rule (reconstruction points inside the scene's ObsMask,
distances >= 20 mm left out), split by where the points lie: cavity (r < 50 mm from the cup's
axis), wall (50-66), outside (> 66); cavity points by axial position; wall points by azimuth from
the cameras' mean direction (0 = camera side) and axial position. Usage: obs.py SCENE MESH...
Needs trimesh, scipy, numpy. The mean it prints agrees with `neus-aug`'s accuracy to 0.01 mm."""
import sys, os, numpy as np, trimesh, scipy.io as sio
from scipy.spatial import cKDTree
sc=sys.argv[1]
M=sio.loadmat(sc+'/ObsMask/ObsMask105_10.mat')
BB=M['BB']; Res=float(np.ravel(M['Res'])[0]); O=M['ObsMask'].astype(bool)
print('BB',BB.ravel(),'Res',Res,'mask',O.shape,O.mean().round(3))
g = trimesh.load(sc + '/gt_mesh.ply'); V=g.vertices; c=V.mean(0)
w, U = np.linalg.eigh(np.cov((V - c).T))
i = np.argmax([abs(w[k] - np.delete(w, k).mean()) for k in range(3)]); a = U[:, i]
pts = np.asarray(trimesh.load(sc + '/Points/stl/stl105_total.ply').vertices)
gax=(pts-c)@a
tree=cKDTree(pts)
for name in sys.argv[2:]:
    m=trimesh.load(name); s,_=trimesh.sample.sample_surface(m,400000,seed=0)
    idx=np.round((s-BB[0])/Res).astype(int)
    ok=np.all((idx>=0)&(idx<np.array(O.shape)),axis=1)
    inm=np.zeros(len(s),bool); inm[ok]=O[idx[ok,0],idx[ok,1],idx[ok,2]]
    dd,_=tree.query(s); keep=inm&(dd<20)
    d=s-c; ax=d@a; rn=np.linalg.norm(d-ax[:,None]*a,axis=1)
    print(name,'in mask',inm.mean().round(3),'acc',dd[keep].mean().round(3))
    tot=dd[keep].sum()
    for lab,b in [('cavity r<50',rn<50),('wall',(rn>=50)&(rn<=66)),('out',rn>66)]:
        k=b&keep; print(f'  {lab:12s} {k.sum()/keep.sum()*100:5.1f}% pts mean {dd[k].mean():5.2f} share {dd[k].sum()/tot*100:5.1f}%')
    b=(rn<50)&keep
    h=np.linspace(gax.min(),gax.max(),13)
    for j in range(12):
        k=b&(ax>=h[j])&(ax<h[j+1])
        if k.sum(): print(f'   ax {h[j]:6.1f}: {k.sum():6d} mean {dd[k].mean():5.2f} share {dd[k].sum()/tot*100:4.1f}%')
    cams=np.load(sc+'/cameras_sphere.npz'); cs=[]
    for k in range(49):
        P=cams['world_mat_%d'%k][:3]; cs.append(-np.linalg.solve(P[:,:3],P[:,3]))
    cs=np.array(cs); md=cs.mean(0)-c; md-=md@a*a; md/=np.linalg.norm(md); e2=np.cross(a,md)
    az=np.degrees(np.abs(np.arctan2(d@e2,d@md)))
    b=(rn>=50)&(rn<=66)&keep
    for lo in range(0,180,45):
        for axl in [(-60,0),(0,50),(50,95)]:
            k=b&(az>=lo)&(az<lo+45)&(ax>=axl[0])&(ax<axl[1])
            if k.sum(): print(f'   wall az {lo:3d}-{lo+45:3d} ax {axl}: {k.sum():6d} mean {dd[k].mean():5.2f} med {np.median(dd[k]):5.2f} r med {np.median(rn[k]):5.1f} share {dd[k].sum()/tot*100:4.1f}%')
