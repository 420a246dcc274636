"""How many cameras see a reconstruction's points in the reconstructed scene itself (its raw mesh
as the occluder: `rviews`) against the true scene (`views`), for the points more than 1 mm off
and for those within 0.3 mm (files of errpts.py, counts of hull_floor's COUNT_PTS mode with and
without RECON_MESH). Usage: rviews.py BASE.ply"""
import sys, numpy as np
b = sys.argv[1]
for name, f in [('> 1 mm off', b), ('< 0.3 mm off', b.replace('.ply', '-good.ply'))]:
    r = np.fromfile(f + '.rviews.u8', np.uint8).astype(int); v = np.fromfile(f + '.views.u8', np.uint8).astype(int)
    w = np.load(f + '.dist.npy') if name.startswith('>') else np.ones(len(r))
    print(f'{f}: {name}, {len(r)} points' + (' (shares weighted by error)' if name.startswith('>') else ''))
    for lo, hi in [(0, 0), (1, 1), (2, 2), (3, 5), (6, 10), (11, 49)]:
        k = (r >= lo) & (r <= hi)
        print(f'  seen by {lo:2d}-{hi:2d} cameras in the reconstruction: {100*w[k].sum()/w.sum():5.1f}%   (those points in the truth: median {np.median(v[k]) if k.any() else 0:.0f} cameras see through / see them)')
