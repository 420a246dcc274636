"""Table of the runs under runs/: Chamfer sum, accuracy, completeness, ratio to the floor, the
closed surface's Chamfer, genus of the largest component, held-out normal error."""
import json, glob, os
print("| run | Chamfer sum (mm) | acc | comp | × floor | closed-mesh Chamfer | genus (largest component) | normal error (°) | held-out PSNR |")
print("|---|---|---|---|---|---|---|---|---|")
for f in sorted(glob.glob(os.path.join(os.path.dirname(__file__) or ".", "runs/*/metrics.json"))):
    m = json.load(open(f)); c = m["chamfer"]
    print(f"| `{f.split('/')[-2]}` | {c['chamfer_sum']:.3f} | {c['mean_d2s']:.3f} | {c['mean_s2d']:.3f} | "
          f"{m['ratio_to_floor']:.1f} | {m['chamfer_closed']['chamfer_sum']:.3f} | {m['mesh']['largest_genus']} | "
          f"{m['normal_error_deg']:.1f} | {m['psnr_heldout']:.2f} |")
