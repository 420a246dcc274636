import sys, numpy as np, trimesh
from scipy.spatial import cKDTree
m = trimesh.load(sys.argv[1]); g = trimesh.load(sys.argv[2])
gp = np.asarray(trimesh.load(sys.argv[3]).vertices)
p, _ = trimesh.sample.sample_surface(m, 400000, seed=0)
d, _ = cKDTree(p).query(gp); d=np.minimum(d,20)
print("completeness mean capped", d.mean())
lo = g.bounds[0]-30; hi = g.bounds[1]+30; W,H=100,50
for axes,name in [((1,2),'y-z (all x)'),((0,1),'x-y (all z)')]:
    acc=np.zeros((H,W)); cnt=np.zeros((H,W)); a,b=axes
    j=((gp[:,a]-lo[a])/(hi[a]-lo[a])*W).astype(int); k=((gp[:,b]-lo[b])/(hi[b]-lo[b])*H).astype(int)
    ok=(j>=0)&(j<W)&(k>=0)&(k<H)
    np.add.at(acc,(k[ok],j[ok]),d[ok]); np.add.at(cnt,(k[ok],j[ok]),1)
    print(name)
    for kk in range(H-1,-1,-1):
        print(''.join(' ' if cnt[kk,jj]==0 else ('.' if (v:=acc[kk,jj]/cnt[kk,jj])<1 else 'o' if v<3 else 'O' if v<8 else '#') for jj in range(W)))
