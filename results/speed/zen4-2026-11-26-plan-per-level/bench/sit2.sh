# Sitting 2 (2026-11-26, session 7): 7524d2f (old) against this change (new), native and x86-64-v3, alternated.
q() { NEUS_AUG_BENCH_QUICK=1 "$@" --bench 2>&1 | grep -E "FMA peak|train_step alone|one-sided against|^== default" ; }
cd /work/main
for b in new-n old-n old-n new-n new-n old-n old-n new-n; do
  echo "######## $b $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  case $b in
    old-n) (cd /work/wt-old && q /work/tgt-old-n/release/deps/field-4bfe497daf268df4) ;;
    new-n) NEUS_AUG_BENCH_FD_EVERY=4 q /work/exp20/n-final ;;
    old-v3) (cd /work/wt-old && q /work/tgt-old-v3/release/deps/field-888ad52637d5f02a) ;;
    new-v3) NEUS_AUG_BENCH_FD_EVERY=4 q /work/exp20/v3-final ;;
  esac
done
