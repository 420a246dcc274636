# Sitting B: old (7524d2f, /work/wt-old) against new with the main measurement at
# render.fd_central_every = 4, fd_one_sided_span = 2 (the candidate default), x86-64-v3 then native.
q() { NEUS_AUG_BENCH_QUICK=1 "$@" --bench 2>&1 | grep -E "^== machine|FMA peak|triad|train_step alone|one-sided against|^== default|^== training|load average" ; }
G=$(pgrep -f grid.sh | head -1); PG=$(ps -o pgid= -p $G | tr -d ' ')
kill -STOP -- -$PG; sleep 5
cd /work/main
for b in old-v3 new-v3 new-v3 old-v3 old-n new-n new-n old-n; do
  echo "######## $b $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  case $b in
    old-v3) (cd /work/wt-old && q /work/tgt-old-v3/release/deps/field-888ad52637d5f02a) ;;
    new-v3) NEUS_AUG_BENCH_FD_EVERY=4 NEUS_AUG_BENCH_FD_SPAN=2 q /work/tgt-v3/release/deps/field-888ad52637d5f02a ;;
    old-n) (cd /work/wt-old && q /work/tgt-old-n/release/deps/field-4bfe497daf268df4) ;;
    new-n) NEUS_AUG_BENCH_FD_EVERY=4 NEUS_AUG_BENCH_FD_SPAN=2 q target/release/deps/field-4bfe497daf268df4 ;;
  esac
done
kill -CONT -- -$PG
