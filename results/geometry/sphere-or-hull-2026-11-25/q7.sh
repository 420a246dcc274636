cd /work/exp10
while ! grep -q "rc=" runs/torus-default-s0.log; do sleep 5; done
./run.sh nb1 thin 1 hull --set 'train.init.kind="visual_hull"'
./run.sh nb1 double-torus 1 hull --set 'train.init.kind="visual_hull"'
