import json, os
base = '/work/main/results/geometry/visible-2026-11-25/runs'
b = {'blob': 'blob-vis-s0', 'torus': 'torus-baseline-s0-v2', 'double-torus': 'double-torus-baseline-s0-v2',
     'plate': 'plate-vis-s0', 'thin': 'thin-hull-s0-v2', 'relief': 'relief-vis-s0', 'blocks': 'blocks-vis-s0',
     'rods': 'rods-soh-s0-v2', 'cup': 'cup-vis-s0'}
ra, rb = [], []
for sc, bd in b.items():
    d = f'/work/exp14/fd/f4_{sc}/metrics.json'
    if not os.path.exists(d): print(sc, 'pending'); continue
    m = json.load(open(d)); o = json.load(open(f'{base}/{bd}/metrics.json'))
    c, co = m['chamfer']['chamfer_sum'], o['chamfer']['chamfer_sum']
    g = lambda x: f"{x['mesh'].get('genus_largest', x['mesh'].get('genus','?'))}" if 'mesh' in x else '?'
    tr = m['timings_s']['train']; tro = o['timings_s']['train']
    print(f"| `{sc}` | {c:.3f} ({m['ratio_to_floor']:.2f}×) | {co:.3f} ({o['ratio_to_floor']:.2f}×) | {100*(c/co-1):+.0f} % | {m['normal_error_deg']:.2f} / {o['normal_error_deg']:.2f} | {m['genus_matches']} / {o['genus_matches']} | {tr:.0f} / {tro:.0f} |")
    if sc != 'cup': ra.append(m['ratio_to_floor']); rb.append(o['ratio_to_floor'])
if ra: print('mean ratio w/o cup', sum(ra)/len(ra), sum(rb)/len(rb), len(ra))
