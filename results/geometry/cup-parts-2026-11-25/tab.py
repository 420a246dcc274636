"""One README table row per run folder: Chamfer sum, accuracy, completeness, ratio to the floor,
held-out PSNR, normal error, closed-mesh Chamfer. Usage: tab.py RUN_DIR..."""
import json,sys
for d in sys.argv[1:]:
    m=json.load(open(d+'/metrics.json')); c=m['chamfer']
    print(f"| {d} | {m['seed']} | {c['chamfer_sum']:.3f} | {c['mean_d2s']:.3f} | {c['mean_s2d']:.3f} | {m['ratio_to_floor']:.1f} | {m['psnr_heldout']:.2f} | {m['normal_error_deg']:.1f} | {m['chamfer_closed']['chamfer_sum']:.3f} |")
