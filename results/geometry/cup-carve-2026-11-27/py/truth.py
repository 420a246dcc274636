"""Scores the depth sweep's decisions against the true depth (issue 13, cup-carve record).

Input: the lines `view x y t t_b c0 c_b` that the scratch patch `../carve-dump-scratch.patch`
appends to `$NEUS_CARVE_DUMP` for every swept ray (training-view index, pixel, the surface
point's and the best hypothesis's distance along the unit ray in the normalised frame, their
costs). The true depth is the first hit of the ray on the scene's `gt_mesh.ply` (trimesh).
Usage: truth.py SCENE DUMP [HELDOUT=8,24,40] [MAX_COST=0.3]   (min_gain 0.3, as the default)."""
import sys, numpy as np, trimesh
scene, dump = sys.argv[1], sys.argv[2]
held = [int(v) for v in sys.argv[3].split(',')] if len(sys.argv) > 3 else [8, 24, 40]
cams = np.load(f'{scene}/cameras_sphere.npz')
n = len([k for k in cams.files if k.startswith('world_mat_') and 'inv' not in k])
train = [i for i in range(n) if i not in held]
mesh = trimesh.load(f'{scene}/gt_mesh.ply')
S = cams['scale_mat_0']; sc = S[0, 0]
def ok(l):
    try:
        return [float(v) for v in l.split()] if len(l.split()) == 7 else None
    except ValueError:
        return None
rows = np.array(
    [r for r in map(ok, open(dump)) if r is not None and
     0 <= r[0] < 46 and 0 <= r[1] < 400 and 0 <= r[2] < 300 and r[3] > 0])
O, D, T, TB, C0, CB = [], [], [], [], [], []
for v, x, y, t, tb, c0, cb in rows:
    P = (cams[f'world_mat_{train[int(v)]}'] @ S)[:3]
    M = P[:, :3]
    C = -np.linalg.solve(M, P[:, 3])
    d = np.linalg.solve(M, np.array([x + 0.5, y + 0.5, 1.0])); d /= np.linalg.norm(d)
    O.append(S[:3, :3] @ C + S[:3, 3]); D.append(d); T.append(t); TB.append(tb); C0.append(c0); CB.append(cb)
O, D = np.array(O), np.array(D)
truth = np.full(len(O), np.inf)
for a in range(0, len(O), 1000):
    loc, ri, ti = mesh.ray.intersects_location(O[a:a+1000], D[a:a+1000], multiple_hits=False)
    truth[a + ri] = np.linalg.norm(loc - O[a + ri], axis=1) / sc
T, TB, C0, CB = map(np.array, (T, TB, C0, CB))
carved = (CB < (float(sys.argv[4]) if len(sys.argv) > 4 else 0.3)) & (C0 - CB >= 0.3)
err0 = (T - truth) * sc; errb = (TB - truth) * sc
for name, sel in [('all swept', np.ones(len(T), bool)), ('carved', carved)]:
    s = sel
    print(f'{name}: {s.sum()} rays; surface point vs truth (mm): median {np.median(err0[s]):.2f}, '
          f'|err|>2mm {np.mean(np.abs(err0[s])>2)*100:.0f}%; best hypothesis vs truth: median {np.median(errb[s]):.2f}, '
          f'within 2 mm {np.mean(np.abs(errb[s])<2)*100:.0f}%, beyond truth by >2 mm {np.mean(errb[s]>2)*100:.0f}%')
s = carved
print('carved rays: t* in front of truth by >2 mm:', np.mean(err0[s] < -2) * 100, '%')

# by run phase (dump order is step order)
k = len(T); carved_idx = np.where(carved)[0]
for q in range(4):
    sel = carved_idx[(carved_idx >= q * k // 4) & (carved_idx < (q + 1) * k // 4)]
    if len(sel):
        print(f'quarter {q}: carved {len(sel)}; t_b within 2 mm of truth {np.mean(np.abs(errb[sel])<2)*100:.0f}%, beyond by >2 mm {np.mean(errb[sel]>2)*100:.0f}%, t* in front by >2 mm {np.mean(err0[sel]<-2)*100:.0f}%')
