cd /work/cup
for s in torus thin blocks relief double-torus plate rods; do
  [ -d sc/$s ] || /work/main/target/release/neus-aug synth $s --out sc/$s > /dev/null 2>&1
  NEUS_DEPTH_MVS=1 MVS_HALF=2 MVS_MAXCOST=0.5 MVS_MINCONS=2 MVS_MINSTD=0.005 MVS_RELTOL=0.002 ./mvs10 reconstruct sc/$s --preset fast --seed 0 --quiet --out r/${s}_m3 --force --set train.multiview.weight=0.000001 --set train.multiview.carve.weight=5 --set train.multiview.carve.surface_weight=0.2 > r/${s}_m3.log 2>&1
  /work/main/target/release/neus-aug reconstruct sc/$s --preset fast --seed 0 --quiet --out r/${s}_fast --force > r/${s}_fast.log 2>&1
  for r in ${s}_m3 ${s}_fast; do python3 -c "
import json;m=json.load(open('r/$r/metrics.json'));print('$r %.3f ratio %.2f genus %s/%s nerr %.1f t %.0f'%(m['chamfer']['chamfer_sum'],m['ratio_to_floor'],m['mesh']['largest_genus'],m['gt_genus'],m['normal_error_deg'],m['timings_s']['total']))"; done
done
