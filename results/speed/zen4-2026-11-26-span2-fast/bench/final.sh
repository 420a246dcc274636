# Final sitting (idle machine): the field bench, old against new, x86-64-v3 then native (ab.sh), then
# time to mesh: blob s0 at fast, new recipe against the previous one (central: --set
# fd_central_every=1, fd_one_sided_span=1), same binary.
bash "$(dirname "$0")/ab.sh" old-v3 new-v3 new-v3 old-v3 old-n new-n new-n old-n
B=/work/exp19/neus-aug-fast
cp /work/main/target/release/neus-aug $B
cd /work/exp19
for r in span2 central; do
  echo "######## time to mesh $r $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  F=""; [ $r = central ] && F="--set model.render.fd_central_every=1 --set model.render.fd_one_sided_span=1.0"
  rm -rf ttm-$r
  /usr/bin/time -f "%e s wall" $B reconstruct blob --preset fast --seed 0 --quiet --out ttm-$r $F 2>&1 | tail -3
done
