import json, os
base = '/work/main/results/geometry/visible-2026-11-25/runs'
b = {'blob': 'blob-vis-s1', 'torus': 'torus-baseline-s1-v2', 'double-torus': 'double-torus-baseline-s1-v2',
     'plate': 'plate-vis-s1', 'thin': 'thin-hull-s1-v2', 'relief': 'relief-vis-s1', 'blocks': 'blocks-vis-s1',
     'rods': 'rods-soh-s1-v2'}
ra, rb = [], []
for sc, bd in b.items():
    d = f'/work/exp14/fd/f4s1_{sc}/metrics.json'
    if not os.path.exists(d): print(sc, 'pending'); continue
    m = json.load(open(d)); o = json.load(open(f'{base}/{bd}/metrics.json'))
    c, co = m['chamfer']['chamfer_sum'], o['chamfer']['chamfer_sum']
    yn = lambda v: 'yes' if v else 'no'
    print(f"| `{sc}` | {c:.3f} ({m['ratio_to_floor']:.2f}×) | {co:.3f} ({o['ratio_to_floor']:.2f}×) | {100*(c/co-1):+.0f} % | {m['normal_error_deg']:.2f}° / {o['normal_error_deg']:.2f}° | {yn(m['genus_matches'])} / {yn(o['genus_matches'])} |")
    ra.append(m['ratio_to_floor']); rb.append(o['ratio_to_floor'])
if ra: print('mean ratio', sum(ra)/len(ra), sum(rb)/len(rb), len(ra))
