cd /work/exp10
while pgrep -f "bash q5.sh" >/dev/null; do sleep 5; done
for s in thin double-torus blob relief blocks plate cup; do ./run.sh nb1 $s 0 hull --set 'train.init.kind="visual_hull"'; done
