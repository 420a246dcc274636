"""The pre-fill depths a hole-filled floor pixel found along 8 directions, against the truth. Usage: fillinspect.py DUMP VIEW; DUMP from the scratch build with NEUS_DD=1 NEUS_DD_DUMP=DUMP (scratch.patch)."""
import numpy as np, sys
d = sys.argv[1]; v = int(sys.argv[2]); W, H = 400, 300
sc = float(open(d + '/scale.txt').read())
t = np.fromfile(f'{d}/t{v:02d}.f32', np.float32).reshape(H, W)
f = np.fromfile(f'{d}/f{v:02d}.u8', np.uint8).reshape(H, W)
g = np.fromfile(f'{d}/g{v:02d}.f32', np.float32).reshape(H, W)
p = np.fromfile(f'{d}/p{v:02d}.u8', np.uint8).reshape(H, W)
e = (t - g) * sc
bad = (p == 0) & (f >= 2) & (e > 2)
ys, xs = np.nonzero(bad)
print('bottom hole-filled behind:', bad.sum(), 'x range', xs.min() if len(xs) else None, xs.max() if len(xs) else None, 'y', ys.min() if len(ys) else None, ys.max() if len(ys) else None)
base = np.where(f < 2, t, np.nan)  # depths before the hole fill (t along the ray; fine for comparisons)
dirs = [(1,0),(-1,0),(0,1),(0,-1),(1,1),(-1,-1),(1,-1),(-1,1)]
rng = np.random.default_rng(0)
for i in rng.choice(len(xs), min(6, len(xs)), replace=False):
    x, y = xs[i], ys[i]
    print(f'pixel ({x},{y}) truth {g[y,x]*sc:.1f} fill {t[y,x]*sc:.1f} err {e[y,x]:.1f} mm')
    for dx, dy in dirs:
        for s in range(1, 21):
            xx, yy = x + dx*s, y + dy*s
            if not (0 <= xx < W and 0 <= yy < H): break
            if np.isfinite(base[yy, xx]):
                print(f'   dir ({dx:2d},{dy:2d}) step {s:2d}: depth {base[yy,xx]*sc:.1f} (truth there {g[yy,xx]*sc:.1f}, part {p[yy,xx]})')
                break
            if np.isfinite(t[yy,xx]) and s == 1:
                pass
