# Third sitting, native only: old (7524d2f) and new (fast's tap layout) alternated, three rounds each.
q() { NEUS_AUG_BENCH_QUICK=1 "$@" --bench 2>&1 | grep -E "FMA peak|train_step alone|one-sided against|^== default" ; }
cd /work/main
for b in old-n new-n new-n old-n old-n new-n; do
  echo "######## $b $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  case $b in
    old-n) (cd /work/wt-old && q /work/tgt-old-n/release/deps/field-4bfe497daf268df4) ;;
    new-n) NEUS_AUG_BENCH_FD_EVERY=4 q target/release/deps/field-4bfe497daf268df4 ;;
  esac
done
