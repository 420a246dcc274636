# Second sitting, x86-64-v3 only: old (7524d2f) and new (fast's tap layout) alternated, three rounds each.
q() { NEUS_AUG_BENCH_QUICK=1 "$@" --bench 2>&1 | grep -E "FMA peak|train_step alone|one-sided against|^== default" ; }
cd /work/main
for b in old-v3 new-v3 new-v3 old-v3 old-v3 new-v3; do
  echo "######## $b $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  case $b in
    old-v3) (cd /work/wt-old && q /work/tgt-old-v3/release/deps/field-888ad52637d5f02a) ;;
    new-v3) NEUS_AUG_BENCH_FD_EVERY=4 q /work/tgt-v3/release/deps/field-888ad52637d5f02a ;;
  esac
done
