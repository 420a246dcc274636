import sys, numpy as np, re, trimesh
from trimesh.proximity import signed_distance
pref, gt = sys.argv[1], sys.argv[2]
vis = np.fromfile(pref + '.visual', dtype=np.uint8).astype(bool)
car = np.fromfile(pref + '.carved', dtype=np.uint8).astype(bool)
res = round(len(vis) ** (1/3)); h = 2/res
nums = [float(x) for x in re.findall(r'-?[\d.]+(?:e-?\d+)?', open(pref + '.norm').read())]
c, s = np.array(nums[:3]), nums[3]
V = vis.reshape(res,res,res); C = car.reshape(res,res,res)
ii = np.where(V.any(axis=(0,1)))[0]; i0 = int(sys.argv[3]) if len(sys.argv)>3 else (ii[0]+ii[-1])//2
kk, jj = np.meshgrid(np.arange(res), np.arange(res), indexing='ij')
x = np.stack([np.full(kk.size, -1 + (i0+.5)*h), -1 + (jj.ravel()+.5)*h, -1 + (kk.ravel()+.5)*h], 1)
m = trimesh.load(gt)
sd = signed_distance(m, c + s*x).reshape(res,res)
print("slice i =", i0, "(x); rows z (camera at the bottom), columns y (cup rim left)")
for k in range(res-1, -1, -1):
    row = ''
    for j in range(res):
        v, cc, ins = V[k,j,i0], C[k,j,i0], sd[k,j] > 0
        row += ('O' if cc else 'X') if ins else ('#' if cc else ('.' if v else ' '))
    if row.strip(): print(f"{k:3d} {row}")
