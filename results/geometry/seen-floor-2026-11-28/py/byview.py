# completeness of meshes split by how many training views see the GT point (via rule-4 cuts of the GT)
import sys, os, numpy as np, trimesh
from scipy.spatial import cKDTree
sc=sys.argv[1]; pre=sys.argv[2]
pts=np.asarray(trimesh.load(sc+'/Points/stl/'+os.listdir(sc+'/Points/stl')[0]).vertices)
P=pts[np.random.default_rng(0).choice(len(pts),200000,replace=False)]
def dist(mesh, n=1500000):
    s,_=trimesh.sample.sample_surface(mesh,n,seed=0); return cKDTree(s).query(P)[0]
cls=np.zeros(len(P),int)
for k in (1,2,3):
    d=dist(trimesh.load(f'{pre}_min{k}.ply')); cls[d<0.25]=k
print('GT points by views seen (0,1,2,>=3):',np.bincount(cls,minlength=4)/len(P))
for name in sys.argv[3:]:
    d=dist(trimesh.load(name),800000); d=np.minimum(d,20); tot=d.sum()
    print(name,'comp(py) %.3f'%d.mean(),' '.join(f'v{k}: mean {d[cls==k].mean():.3f} share {d[cls==k].sum()/tot:.3f} (>2mm {d[(cls==k)&(d>2)].sum()/tot:.3f})' for k in range(4)))
    np.save(name.replace('/','_')+'_byview.npy', np.c_[P, d, cls])
