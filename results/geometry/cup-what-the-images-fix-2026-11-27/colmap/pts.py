import numpy as np, trimesh, json
from scipy.spatial import cKDTree
sc='/work/cup/sc/cup400'
rows=[l.split() for l in open('tri/points3D.txt') if not l.startswith('#')]
X=np.array([[float(v) for v in r[1:4]] for r in rows]); err=np.array([float(r[7]) for r in rows]); tl=np.array([(len(r)-8)//2 for r in rows])
stl=np.asarray(trimesh.load(f'{sc}/Points/stl/stl105_total.ply').vertices)
d,_=cKDTree(stl).query(X)
P=np.array(json.load(open(f'{sc}/meta.json'))['gt']['plane']); n=P[:3]/np.linalg.norm(P[:3])
v=np.asarray(trimesh.load(f'{sc}/gt_mesh.ply').vertices); base=(v@n).min(); c=v.mean(0); c=c-n*(c@n); s=1.1320287581835358
q=X-np.outer(X@n,n)-c; r=np.linalg.norm(q,axis=1)/s; z=((X@n)-base)/s
print('points',len(X),'track median',np.median(tl),'reproj err median',np.median(err).round(2))
print('dist to truth: median %.2f, p90 %.2f, share < 0.5 mm %.2f, < 1 mm %.2f'%(np.median(d),np.percentile(d,90),(d<0.5).mean(),(d<1).mean()))
for name,k in [('cavity bottom (z<20, r<55)',(r<55)&(z<20)),('inner wall lower half (r 45-56, 20<z<65)',(r>45)&(r<56.5)&(z>=20)&(z<65)),('inner wall upper half',(r>45)&(r<56.5)&(z>=65)&(z<128)),('outer wall',(r>58.5)&(z<128)),('rim',z>=128),('elsewhere inside the cavity air (r<50, z>20)',(r<50)&(z>=20))]:
    print(f'  {name:46s} {k.sum():5d} points, median dist {np.median(d[k]) if k.any() else 0:.2f} mm, median track {np.median(tl[k]) if k.any() else 0:.0f}')
