# Sitting A: central path A/B, native. head = 9cec5df (/work/tgt-head), new = working tree
# (const-generic two-cell stencil), NEUS_AUG_BENCH_FD_SPAN=2 for its one-sided pairs.
q() { NEUS_AUG_BENCH_QUICK=1 "$@" --bench 2>&1 | grep -E "^== machine|FMA peak|triad|train_step alone|one-sided against|^== default|^== training|load average" ; }
G=$(pgrep -f grid.sh | head -1); PG=$(ps -o pgid= -p $G | tr -d ' ')
kill -STOP -- -$PG; sleep 5
cd /work/main
for b in head new new head head new new head; do
  echo "######## $b $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  case $b in
    head) q /work/tgt-head/release/deps/field-4bfe497daf268df4 ;;
    new) NEUS_AUG_BENCH_FD_SPAN=2 q target/release/deps/field-4bfe497daf268df4 ;;
  esac
done
kill -CONT -- -$PG
