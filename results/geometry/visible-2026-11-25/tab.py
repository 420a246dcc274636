# Markdown rows from run folders: run, scene (floor), Chamfer (seen), acc, comp, ratio, closed Chamfer, genus (truth), components raw -> closed cleaned, faces cut, nerr
import json, sys, os
for d in sys.argv[1:]:
    m = json.load(open(os.path.join(d, 'metrics.json')))
    c = m['chamfer']; cc = m.get('chamfer_closed') or {}; me = m['mesh']; cl = me.get('clean') or {}
    print(f"| {os.path.basename(d)} | {m['scene']['name'] if isinstance(m.get('scene'), dict) and 'name' in m['scene'] else ''} ({m['floor_mm']:.3f}) | **{c['chamfer_sum']:.3f}** | {c['mean_d2s']:.3f} | {c['mean_s2d']:.3f} | {m['ratio_to_floor']:.2f}× | {cc.get('chamfer_sum', float('nan')):.3f} | {me.get('largest_genus')} ({m.get('gt_genus')}) | {me['raw_components']} → {cl.get('components_after')} | {cl.get('faces_unseen', 0) / max(me.get('closed_faces') or 1, 1) * 100:.0f} % | {m.get('normal_error_deg') or float('nan'):.2f} |")
