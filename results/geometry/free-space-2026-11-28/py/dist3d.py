import numpy as np,sys,trimesh
from scipy.spatial import cKDTree
m=trimesh.load('sc/cup400/gt_mesh.ply')
pts,_=trimesh.sample.sample_surface_even(m,3000000,seed=0) if hasattr(trimesh.sample,'sample_surface_even') else trimesh.sample.sample_surface(m,3000000)
tree=cKDTree(pts)
for d in sys.argv[1:]:
    s=float(open(d+'/scale.txt').read()); agg={}
    for v in range(46):
        x=np.fromfile(f'{d}/x{v:02}.f32',np.float32).reshape(-1,4)
        k=x[:,0].astype(np.int64); X=x[:,1:]
        p=np.fromfile(f'{d}/p{v:02}.u8',np.uint8)[k]; f=np.fromfile(f'{d}/f{v:02}.u8',np.uint8)[k]
        t=np.fromfile(f'{d}/t{v:02}.f32',np.float32)[k]; g=np.fromfile(f'{d}/g{v:02}.f32',np.float32)[k]
        dist,_=tree.query(X)
        e=(t-g)*s
        for part in range(4):
            mm=(p==part); a=agg.setdefault(part,np.zeros(5))
            a+=[mm.sum(), (dist[mm]>2).sum(), (dist[mm]>5).sum(), np.minimum(dist[mm],20).sum(), (mm&(e>2)).sum()]
    print(d, ' | '.join('%s n %d off2 %d off5 %d meanclip %.2f behind2 %d'%(n,a[0],a[1],a[2],a[3]/max(a[0],1),a[4]) for n,a in zip(['bot','in','out','oth'],[agg[i] for i in range(4)])))
