cd /work/cup
for s in blob torus thin blocks relief double-torus plate rods; do
  NEUS_DEPTH_MVS=1 MVS_HALF=2 MVS_MAXCOST=0.5 MVS_MINCONS=2 MVS_MINSTD=0.005 MVS_RELTOL=0.002 ./mvs10 reconstruct sc/$s --preset fast --seed 1 --quiet --out r/${s}_m3_s1 --force --set train.multiview.weight=0.000001 --set train.multiview.carve.weight=5 --set train.multiview.carve.surface_weight=0.2 > r/${s}_m3_s1.log 2>&1
  python3 -c "
import json;m=json.load(open('r/${s}_m3_s1/metrics.json'));print('${s}_m3_s1 %.3f ratio %.2f genus %s/%s nerr %.1f t %.0f'%(m['chamfer']['chamfer_sum'],m['ratio_to_floor'],m['mesh']['largest_genus'],m['gt_genus'],m['normal_error_deg'],m['timings_s']['total']))"
done
