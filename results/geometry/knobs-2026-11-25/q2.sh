cd /work/exp10
while pgrep -f "bash q1.sh" >/dev/null; do sleep 5; done
VD='model.render.view_dependence=[300, 0.0, 1.0, 1500]'
./run.sh nb0 relief 0 vd --set "$VD"
./run.sh nb0 thin 0 vd --set "$VD"
./run.sh nb0 blocks 0 vd --set "$VD"
./run.sh nb0 cup 0 vd --set "$VD"
