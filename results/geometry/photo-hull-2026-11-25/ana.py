import sys, numpy as np, trimesh, re
pref, gt = sys.argv[1], sys.argv[2]
vis = np.fromfile(pref + '.visual', dtype=np.uint8).astype(bool)
car = np.fromfile(pref + '.carved', dtype=np.uint8).astype(bool)
res = round(len(vis) ** (1/3)); r = 1.0; h = 2*r/res
nums = [float(x) for x in re.findall(r'-?[\d.]+(?:e-?\d+)?', open(pref + '.norm').read())]
c, s = np.array(nums[:3]), nums[3]
idx = np.arange(res**3)
i, j, k = idx % res, (idx // res) % res, idx // (res*res)
x = np.stack([-r + (i+.5)*h, -r + (j+.5)*h, -r + (k+.5)*h], 1)
w = c + s * x
m = trimesh.load(gt)
sel = vis & (np.random.default_rng(0).random(len(vis)) < float(sys.argv[3]) if len(sys.argv)>3 else vis)
from trimesh.proximity import signed_distance
pts = w[sel]
# signed distance: positive inside (trimesh convention)
sd = np.concatenate([signed_distance(m, pts[a:a+5000]) for a in range(0, len(pts), 5000)])
vox_mm = h * s
inside_gt = sd > 0
carved = ~car[sel]
print(f"{pref}: voxel {vox_mm:.2f} mm; hull {sel.sum()}, gt-inside voxels {inside_gt.sum()}, carved {carved.sum()}")
deep = sd > 1.0 * vox_mm
print(f"  carved voxels inside truth by > 1 voxel: {(carved & deep).sum()} of {deep.sum()} ({100*(carved&deep).sum()/max(deep.sum(),1):.1f} %)")
out = sd < -1.0 * vox_mm
print(f"  voxels outside truth by > 1 voxel: {out.sum()}, carved {(carved&out).sum()} ({100*(carved&out).sum()/max(out.sum(),1):.1f} %)")
for lo, hi in [(-1e9,-20),(-20,-8),(-8,-3),(-3,0),(0,3),(3,1e9)]:
    b = (sd >= lo) & (sd < hi)
    print(f"  sd [{lo},{hi}) mm: {b.sum()} voxels, kept {(b & ~carved).sum()}")
