# Final sitting (idle machine): field bench old (7524d2f) against new (this tree: fast = span 2, k = 4),
# x86-64-v3 then native; new's main measurement at fast's tap layout (NEUS_AUG_BENCH_FD_EVERY=4, span 2 by
# default), its pairs central against fast's layout. Then time to mesh: blob s0 at fast, new recipe
# against the previous one (central: --set fd_central_every=1, fd_one_sided_span=1), same binary.
q() { NEUS_AUG_BENCH_QUICK=1 "$@" --bench 2>&1 | grep -E "^== machine|FMA peak|triad|train_step alone|one-sided against|^== default|^== training|load average|hash encode|MLP fwd|MLP bwd" ; }
cd /work/main
for b in old-v3 new-v3 new-v3 old-v3 old-n new-n new-n old-n; do
  echo "######## $b $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  case $b in
    old-v3) (cd /work/wt-old && q /work/tgt-old-v3/release/deps/field-888ad52637d5f02a) ;;
    new-v3) NEUS_AUG_BENCH_FD_EVERY=4 q /work/tgt-v3/release/deps/field-888ad52637d5f02a ;;
    old-n) (cd /work/wt-old && q /work/tgt-old-n/release/deps/field-4bfe497daf268df4) ;;
    new-n) NEUS_AUG_BENCH_FD_EVERY=4 q target/release/deps/field-4bfe497daf268df4 ;;
  esac
done
B=/work/exp19/neus-aug-fast
cp target/release/neus-aug $B
cd /work/exp19
for r in span2 central; do
  echo "######## time to mesh $r $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  F=""; [ $r = central ] && F="--set model.render.fd_central_every=1 --set model.render.fd_one_sided_span=1.0"
  rm -rf ttm-$r
  /usr/bin/time -f "%e s wall" $B reconstruct blob --preset fast --seed 0 --quiet --out ttm-$r $F 2>&1 | tail -3
done
