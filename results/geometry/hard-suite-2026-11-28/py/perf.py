# Perforation census: rays across the true wall, hits on a reconstruction.
import sys, numpy as np, trimesh
sc=sys.argv[1]
g=trimesh.load(sc+'/gt_mesh.ply'); V=g.vertices; c=V.mean(0)
w,U=np.linalg.eigh(np.cov((V-c).T)); i=np.argmax([abs(w[k]-np.delete(w,k).mean()) for k in range(3)]); a=U[:,i]
e1=np.cross(a,[1,0,0]); e1/=np.linalg.norm(e1); e2=np.cross(a,e1)
P,fi=trimesh.sample.sample_surface_even(g,30000,seed=1)
N=g.face_normals[fi]
q=P-c; ax=q@a; r=q-ax[:,None]*a; rn=np.linalg.norm(r,axis=1); rh=r/rn[:,None]
nr=(N*rh).sum(1)
outer=nr>0.9
P=P[outer]; N=N[outer]; ax=ax[outer]; q=q[outer]
az=np.degrees(np.arctan2(q@e2,q@e1))
# wall thickness along -n on the truth
L=14.0
o=P+3*N; d=-N
def hits(m):
    loc,ri,_=m.ray.intersects_location(o,d,multiple_hits=True)
    t=((loc-o[ri])*d[ri]).sum(1)
    ok=t<L
    cnt=np.bincount(ri[ok],minlength=len(o))
    tmin=np.full(len(o),np.nan); tmax=np.full(len(o),np.nan)
    for k,tt in zip(ri[ok],t[ok]):
        tmin[k]=tt if np.isnan(tmin[k]) else min(tmin[k],tt); tmax[k]=tt if np.isnan(tmax[k]) else max(tmax[k],tt)
    return cnt,tmin,tmax
cg,tg0,tg1=hits(g)
print('truth hits hist',np.bincount(cg)[:6], 'thickness median',np.nanmedian(tg1-tg0))
wall=cg==2
print('outer-wall points with a 2-hit truth wall:',wall.sum(), 'axial range', np.percentile(ax[wall],[0,100]).round(1))
for name in sys.argv[2:]:
    m=trimesh.load(name)
    cm,t0,t1=hits(m)
    W=wall
    h=np.bincount(cm[W],minlength=6)[:6]/W.sum()
    thick=(t1-t0)[W&(cm>=2)]
    print(name,'hits share 0/1/2/3/4/5:',h.round(4),' recon thickness median %.2f p10 %.2f (truth %.2f)'%(np.median(thick),np.percentile(thick,10),np.nanmedian(tg1-tg0)))
    z=W&(cm==0)
    if z.sum():
        print('   perforated: az hist',np.histogram(az[z],bins=12,range=(-180,180))[0],' axial q',np.percentile(ax[z],[10,50,90]).round(1))
    print('   outer-surface offset (t0-3) median %.2f p90 %.2f ; inner offset (truth t1 - recon t1) median %.2f p90 %.2f'%(np.nanmedian(t0[W]-3),np.nanpercentile(t0[W]-3,90),np.nanmedian((tg1-t1)[W&(cm>=2)]),np.nanpercentile((tg1-t1)[W&(cm>=2)],90)))
    one=W&(cm==1)
    H,_,_=np.histogram2d(az[W],ax[W],bins=[12,7],range=[[-180,180],[-50,90]])
    H1,_,_=np.histogram2d(az[one],ax[one],bins=[12,7],range=[[-180,180],[-50,90]])
    print('   share of 1-hit by az (rows, -180..180 step 30) x axial (cols, -50..90 step 20):')
    print((H1/np.maximum(H,1)).round(2))
    if len(sys.argv)>3: pass
    oo=one&(t0<5.8); io=one&(t0>=5.8)
    print('   1-hit: outer-only %.3f inner-only %.3f of wall rays'%(oo.sum()/W.sum(), io.sum()/W.sum()))
    Ho,_,_=np.histogram2d(az[oo],ax[oo],bins=[12,7],range=[[-180,180],[-50,90]])
    print('   outer-only share by cell:'); print((Ho/np.maximum(H,1)).round(2))
    # the mesh.ply (after rule 4): does it keep those areas?
