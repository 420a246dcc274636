# Prints the runs of this record and the same-sitting ratios: python3 table.py
import json, glob, os, re, sys
HERE = os.path.dirname(os.path.abspath(__file__))
rows = []
for d in sorted(glob.glob(f'{HERE}/runs/*/metrics.json')):
    name = d.split('/')[-2]
    m = json.load(open(d)); t = m['timings_s']
    tm = t['load'] + t['prepare'] + t['train'] + t['mesh']
    tr = m['train']
    sps = round(tr.get('samples_per_second', 0))
    el = open(f'{HERE}/runs/{name}/time.txt').read()
    wall = re.search(r'Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)', el).group(1)
    rows.append((name, m['chamfer']['chamfer_sum'], tm, t['train'], wall, sps))
by = {r[0]: r for r in rows}
for r in rows:
    print(f"{r[0]:12s} chamfer {r[1]:.4f} to-mesh {r[2]:7.1f} s train {r[3]:7.1f} wall {r[4]} sps {r[5]}")
for s in ('1', '2'):
    for isa in ('n', 'v3'):
        o, n = by.get(f'old-{isa}-{s}'), by.get(f'new-{isa}-{s}')
        if o and n:
            print(f"sitting {s} {isa}: new quick / old fast to-mesh = {n[2]/o[2]:.3f}")
