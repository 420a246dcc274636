cd /work/exp10
./nb1 study hard --preset fast --scenes torus --out /work/exp10/torus-soh --set 'train.init.kind="sphere_or_hull"' > torus-soh.log 2>&1
for s in 0 1 2; do ./run.sh nb1 rods $s soh --set 'train.init.kind="sphere_or_hull"'; done
./run.sh nb1 double-torus 0 soh --set 'train.init.kind="sphere_or_hull"'
