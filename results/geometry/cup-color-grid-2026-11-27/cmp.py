# The suite at seed 0 with the colour grid (`study hard --seeds 1 --set
# model.field.color_grid.enabled=true`, runs/hard-*) against the committed `fast` at seed 0 (the
# span-2 record's runs, the same recipe). Run from the repository root:
#   python3 results/geometry/cup-color-grid-2026-11-27/cmp.py
# Other records compare their suite the same way: cmp.py RECORD LABEL COLUMN PHRASE (their own
# cmp.py calls this one).
import json, os, sys
G = 'results/geometry/'
RECORD, LABEL, COLUMN, PHRASE = (sys.argv[1:5] if len(sys.argv) > 4
                                 else ('cup-color-grid-2026-11-27', 'colour grid', 'grid', 'the grid'))
HERE = G + RECORD + '/runs/'
SP2 = G + 'span2-fast-2026-11-26/runs/'
PREV = 'results/speed/zen4-2026-11-26-one-sided-span2/runs/'
SCENES = ['blob', 'torus', 'double-torus', 'thin', 'blocks', 'cup', 'relief', 'plate', 'rods']


def committed(scene, aug):
    """The committed `fast` run at seed 0, where the span-2 record keeps one."""
    n = f'sp2-{scene}-' + ('' if aug == 'none' else aug + '-') + 's0'
    paths = [SP2 + n, SP2 + n + '-xeon']
    if scene not in ('blob', 'torus'):  # those two of PREV ran on an earlier build
        paths.append(PREV + n)
    return next((p for p in paths if os.path.exists(p + '/metrics.json')), None)


def load(p):
    m = json.load(open(p + '/metrics.json'))
    return (m['chamfer']['chamfer_sum'], m['ratio_to_floor'], m['normal_error_deg'],
            m['mesh']['largest_genus'], m['gt_genus'], m['psnr_heldout'])


def cell(v):
    return f'{v[0]:.3f} ({v[1]:.2f}×), {v[3]}' + ('' if v[3] == v[4] else ' ✗')


print(f'| scene | aug | {LABEL}: Chamfer (× floor), genus | committed | change | normal error (°) {COLUMN} / committed | PSNR (dB) {COLUMN} / committed |')
print('|---|---|---|---|---|---|---|')
ratios = [[], []]
for scene in SCENES:
    for aug in (['none', 'sia', 'dia'] if 'torus' in scene else ['none']):
        p = HERE + f'hard-{scene}-{"baseline" if aug == "none" else aug}-s0'
        if not os.path.exists(p + '/metrics.json'):
            continue
        g = load(p)
        b = committed(scene, aug)
        if b is None:
            print(f'| `{scene}` | {aug} | {cell(g)} | – | | {g[2]:.2f} / – | {g[5]:.2f} / – |')
            continue
        c = load(b)
        if aug == 'none':
            ratios[0].append(g[1])
            ratios[1].append(c[1])
        print(f'| `{scene}` | {aug} | {cell(g)} | {cell(c)} | {100 * (g[0] / c[0] - 1):+.0f} % '
              f'| {g[2]:.2f} / {c[2]:.2f} | {g[5]:.2f} / {c[5]:.2f} |')
if ratios[0]:
    print(f'\nMean ratio to the floor over the {len(ratios[0])} scenes without augmentation that '
          f'have both: {sum(ratios[0]) / len(ratios[0]):.3f}× with {PHRASE}, '
          f'{sum(ratios[1]) / len(ratios[1]):.3f}× committed.')
