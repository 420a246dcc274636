"""The runs table of README.md from runs/*/metrics.json (this record) and, for the two runs marked
'previous record', ../cup-multiview-2026-11-27/runs. Usage: python3 tab.py"""
import json, os, sys
here = os.path.dirname(os.path.abspath(__file__))
rows = [
 # name, seed, start, weight desc, extra, binary
 ('mv5-cav-s0', 0, 'cavity', '5', '', 'previous record'),
 ('mv5-cav-s0-rerun', 0, 'cavity', '5', '', 'mvr'),
 ('mv5-cav-s1', 1, 'cavity', '5', '', 'mvh'),
 ('mv5-cav-s2', 2, 'cavity', '5', '', 'mvr'),
 ('mv2-cav-s0', 0, 'cavity', '2', '', 'previous record'),
 ('mv2-cav-s1', 1, 'cavity', '2', '', 'mvh'),
 ('mv10-cav-s0', 0, 'cavity', '10', '', 'mvr'),
 ('mvramp5-cav-s0', 0, 'cavity', '5 → 0.5', '', 'mvr'),
 ('mvramp10-cav-s0', 0, 'cavity', '10 → 1', '', 'mvr'),
 ('mvramp10-cav-s1', 1, 'cavity', '10 → 1', '', 'mvr'),
 ('mvramp20-cav-s0', 0, 'cavity', '20 → 2', '', 'mvr'),
 ('mvramp10r512-cav-s0', 0, 'cavity', '10 → 1', '512 rays', 'mvr'),
 ('mvramp10mc3-cav-s1', 1, 'cavity', '10 → 1', '`min_cos` 0.3', 'mvr'),
 ('mvramp10g05-cav-s1', 1, 'cavity', '10 → 1', '\\|∇f\\| ≥ 0.5 (scratch)', 'mvs05'),
 ('mvramp10g05mc3-cav-s0', 0, 'cavity', '10 → 1', '\\|∇f\\| ≥ 0.5 (scratch), `min_cos` 0.3', 'mvs05'),
 ('mvramp10g05mc3-cav-s1', 1, 'cavity', '10 → 1', '\\|∇f\\| ≥ 0.5 (scratch), `min_cos` 0.3', 'mvs05'),
 ('mv5g05-cav-s0', 0, 'cavity', '5', '\\|∇f\\| ≥ 0.5 (scratch)', 'mvs05'),
 ('mv5g05-cav-s1', 1, 'cavity', '5', '\\|∇f\\| ≥ 0.5 (scratch)', 'mvs05'),
 ('mv5r160-cav-s0', 0, 'cavity, 160³ carve', '5', '', 'mvr'),
 ('mv5k2-cav-s0', 0, 'cavity', '5', '`top_k` 2', 'mvr'),
 ('mv5k2-cav-s1', 1, 'cavity', '5', '`top_k` 2', 'mvr'),
 ('mv5-truth', 0, '**truth**', '5', '', 'mvtruth'),
 ('mvramp10-truth', 0, '**truth**', '10 → 1', '', 'mvtruth'),
]
print('| run | seed | start | weight | other | Chamfer sum (mm) | acc / comp | × floor | genus (truth 0) | normal error (°) | held-out PSNR (dB) | `mv` | build |')
print('|---|---|---|---|---|---|---|---|---|---|---|---|---|')
for n, s, st, w, ex, b in rows:
    try:
        d = os.path.join(here, 'runs') if b != 'previous record' else os.path.join(here, '..', 'cup-multiview-2026-11-27', 'runs')
        m = json.load(open(os.path.join(d, n, 'metrics.json')))
    except FileNotFoundError:
        print(f'| `{n}` | {s} | {st} | {w} | {ex} | (not run) |', file=sys.stderr); continue
    c = m['chamfer']; t = m['train']; mv = t.get('multiview_last') or {}
    print(f"| `{n}` | {s} | {st} | {w} | {ex} | {c['chamfer_sum']:.3f} | {c['mean_d2s']:.3f} / {c['mean_s2d']:.3f} | {m['ratio_to_floor']:.1f} | {m['mesh']['largest_genus']} | {m['normal_error_deg']:.1f} | {m['psnr_heldout']:.2f} | {mv.get('mean_cost', float('nan')):.3f} | {b} |")
