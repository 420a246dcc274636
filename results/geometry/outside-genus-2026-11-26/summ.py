import json, sys, glob
for d in sorted(glob.glob(sys.argv[1] if len(sys.argv) > 1 else "r-*")):
    try: m = json.load(open(d + '/metrics.json'))
    except Exception: continue
    me = m['mesh']; t = m['train']
    print(f"{d:22s} cham {m['chamfer']['chamfer_sum']:.3f} floor {m['floor_mm']:.3f} x{m['ratio_to_floor']:.2f} genus {me['largest_genus']}/{m['gt_genus']} raw {me['raw_genus']} comp {me['raw_components']}->{me['components']} nerr {m['normal_error_deg']:.2f} psnr {m['psnr_heldout']:.2f} cover {t.get('sphere_cover')} train {m['timings_s']['train']:.0f}s")
