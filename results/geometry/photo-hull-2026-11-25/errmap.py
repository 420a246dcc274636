import sys, numpy as np, trimesh
from scipy.spatial import cKDTree
m = trimesh.load(sys.argv[1]); g = trimesh.load(sys.argv[2])
gp = trimesh.load(sys.argv[3]).vertices  # stl points (visible GT)
p, _ = trimesh.sample.sample_surface(m, 200000, seed=0)
d, _ = cKDTree(gp).query(p)
d = np.minimum(d, 20)
print("mean capped dist", d.mean(), "share >5mm", (d>5).mean(), "their share of the sum", d[d>5].sum()/d.sum())
lo = g.bounds[0]-30; hi = g.bounds[1]+30; W,H=100,50
for axes,name in [((1,2),'y-z (all x)'),((0,1),'x-y (all z)')]:
    grid=[[' ']*W for _ in range(H)]
    acc=np.zeros((H,W)); cnt=np.zeros((H,W))
    a,b=axes
    j=((p[:,a]-lo[a])/(hi[a]-lo[a])*W).astype(int); k=((p[:,b]-lo[b])/(hi[b]-lo[b])*H).astype(int)
    ok=(j>=0)&(j<W)&(k>=0)&(k<H)
    np.add.at(acc,(k[ok],j[ok]),d[ok]); np.add.at(cnt,(k[ok],j[ok]),1)
    print(name, "cells: mean capped distance: . <1, o <3, O <8, # >=8")
    for kk in range(H-1,-1,-1):
        row=''
        for jj in range(W):
            if cnt[kk,jj]==0: row+=' '; continue
            v=acc[kk,jj]/cnt[kk,jj]; row+= '.' if v<1 else 'o' if v<3 else 'O' if v<8 else '#'
        print(row)
