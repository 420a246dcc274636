"""Table of the closing's effect: each run of the batch at close radius 0 (as trained), 1 and 2."""
import json, glob, os, sys
root = sys.argv[1] if len(sys.argv) > 1 else 'rx'
runs = sorted({os.path.basename(d).rsplit('-r', 1)[0] for d in glob.glob(f'{root}/*-r[012]')})
print('| run | floor | r = 0: Chamfer (ratio), genus | r = 1 | r = 2 | truth genus |')
print('|---|---|---|---|---|---|')
for n in runs:
    cells = []; gt = floor = None
    for r in range(3):
        p = f'{root}/{n}-r{r}/metrics.json'
        if not os.path.exists(p):
            cells.append('–'); continue
        m = json.load(open(p))
        gt = m['gt_genus']; floor = m['floor_mm']
        g = m['mesh']['largest_genus']
        mark = '' if g == gt else ' ✗'
        cells.append(f"{m['chamfer']['chamfer_sum']:.4f} ({m['ratio_to_floor']:.2f}×), {g}{mark}")
    print(f"| {n.replace('em50-', '')} | {floor:.3f} | " + ' | '.join(cells) + f' | {gt} |')
