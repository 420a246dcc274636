# One-sided span-2 runs (k = 4) against the committed central runs of the current fast recipe.
import json, os, sys
G = '/work/main/results/geometry/'
base = {
 ('blob',0): 'closing-2026-11-26/runs/em50-blob-s0-r1', ('torus',0): 'closing-2026-11-26/runs/em50-torus-s0-r1',
 ('double-torus',0): 'closing-2026-11-26/runs/em50-double-torus-s0-r1', ('relief',0): 'closing-2026-11-26/runs/em50-relief-s0-r1',
 ('rods',0): 'closing-2026-11-26/runs/em50-rods-s0-r1', ('thin',0): 'closing-2026-11-26/runs/em50-thin-s0-r1',
 ('plate',0): 'error-map-2026-11-25/runs/sh50_plate', ('blocks',0): 'error-map-2026-11-25/runs/sh50_blocks',
 ('blob',1): 'error-map-2026-11-25/runs/sh50_blob_s1', ('torus',1): 'closing-2026-11-26/runs/em50-torus-s1-r1',
 ('double-torus',1): 'closing-2026-11-26/runs/em50-double-torus-s1-r1', ('relief',1): 'closing-2026-11-26/runs/em50-relief-s1-r1',
 ('thin',1): 'closing-2026-11-26/runs/em50-thin-s1-r1', ('plate',1): 'error-map-fast-2026-11-26/runs/em50-plate-s1',
 ('blocks',1): 'error-map-fast-2026-11-26/runs/em50-blocks-s1', ('rods',1): 'error-map-fast-2026-11-26/runs/em50-rods-s1',
}
def load(p):
    m = json.load(open(p + '/metrics.json'))
    return m['chamfer']['chamfer_sum'], m['ratio_to_floor'], m['normal_error_deg'], m['mesh']['largest_genus'], m['gt_genus']
print('| scene | seed | span 2, k = 4: Chamfer (× floor) | central, committed (× floor) | change | normal error span 2 / central | genus span 2 / central (truth) |')
print('|---|---|---|---|---|---|---|')
rs = {0: [[], []], 1: [[], []]}
for seed in (0, 1):
    for s in ['blob', 'torus', 'double-torus', 'plate', 'thin', 'relief', 'blocks', 'rods']:
        d = f'runs/sp2-{s}-s{seed}'
        if not os.path.exists(d + '/metrics.json'): continue
        a = load(d); b = load(G + base[(s, seed)])
        rs[seed][0].append(a[1]); rs[seed][1].append(b[1])
        print(f'| `{s}` | {seed} | {a[0]:.3f} ({a[1]:.2f}×) | {b[0]:.3f} ({b[1]:.2f}×) | {100*(a[0]/b[0]-1):+.0f} % | {a[2]:.2f}° / {b[2]:.2f}° | {a[3]} / {b[3]} ({a[4]}) |')
for seed in (0, 1):
    a, b = rs[seed]
    if a: print(f'seed {seed}: {len(a)} scenes, mean ratio span 2 {sum(a)/len(a):.3f}, central {sum(b)/len(b):.3f}')
