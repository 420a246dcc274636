"""Suite runs with one-sided differences against the committed central runs of the same seed.
Usage: python3 cmp.py SEED   (reads /work/exp14/fd/f4_<scene> for seed 0, f4s1_<scene> for seed 1)"""
import json, os, sys
seed = int(sys.argv[1]) if len(sys.argv) > 1 else 0
base = '/work/main/results/geometry/visible-2026-11-25/runs'
committed = {'blob': 'blob-vis', 'torus': 'torus-baseline', 'double-torus': 'double-torus-baseline',
             'plate': 'plate-vis', 'thin': 'thin-hull', 'relief': 'relief-vis', 'blocks': 'blocks-vis',
             'rods': 'rods-soh', 'cup': 'cup-vis'}
v2 = {'torus', 'double-torus', 'thin', 'rods'}  # committed runs with the -v2 suffix
prefix = 'f4' if seed == 0 else f'f4s{seed}'
ra, rb = [], []
for sc, bd in committed.items():
    d = f'/work/exp14/fd/{prefix}_{sc}/metrics.json'
    o_path = f"{base}/{bd}-s{seed}{'-v2' if sc in v2 else ''}/metrics.json"
    if not (os.path.exists(d) and os.path.exists(o_path)):
        print(sc, 'missing'); continue
    m = json.load(open(d)); o = json.load(open(o_path))
    c, co = m['chamfer']['chamfer_sum'], o['chamfer']['chamfer_sum']
    yn = lambda v: 'yes' if v else 'no'
    print(f"| `{sc}` | {c:.3f} ({m['ratio_to_floor']:.2f}×) | {co:.3f} ({o['ratio_to_floor']:.2f}×) | {100*(c/co-1):+.0f} % | {m['normal_error_deg']:.2f}° / {o['normal_error_deg']:.2f}° | {yn(m['genus_matches'])} / {yn(o['genus_matches'])} |")
    if sc != 'cup': ra.append(m['ratio_to_floor']); rb.append(o['ratio_to_floor'])
if ra: print(f'mean ratio to the floor without cup: {sum(ra)/len(ra):.3f}x against {sum(rb)/len(rb):.3f}x ({len(ra)} scenes)')
