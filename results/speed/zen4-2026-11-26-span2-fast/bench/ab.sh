# Field bench A/B, idle machine: `ab.sh ORDER...` runs old (7524d2f, /work/wt-old) and new (this tree,
# its main measurement at fast's tap layout: NEUS_AUG_BENCH_FD_EVERY=4, span 2 by default) builds in the
# given order, e.g. `ab.sh old-v3 new-v3 new-v3 old-v3` (x86-64-v3) or `old-n new-n ...` (native).
# Sittings final2 and final3 ran this loop as `ab.sh old-v3 new-v3 new-v3 old-v3 old-v3 new-v3` and the
# same with -n, grepping only the FMA peak and train_step lines. NEW_V3 and NEW_N name other new bench
# binaries (the plan-per-level record's sittings ran copies of its commits' benches that way).
q() { NEUS_AUG_BENCH_QUICK=1 "$@" --bench 2>&1 | grep -E "^== machine|FMA peak|triad|train_step alone|one-sided against|^== default|^== training|load average|hash encode|MLP fwd|MLP bwd" ; }
cd /work/main
for b in "$@"; do
  echo "######## $b $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  case $b in
    old-v3) (cd /work/wt-old && q /work/tgt-old-v3/release/deps/field-888ad52637d5f02a) ;;
    new-v3) NEUS_AUG_BENCH_FD_EVERY=4 q "${NEW_V3:-/work/tgt-v3/release/deps/field-888ad52637d5f02a}" ;;
    old-n) (cd /work/wt-old && q /work/tgt-old-n/release/deps/field-4bfe497daf268df4) ;;
    new-n) NEUS_AUG_BENCH_FD_EVERY=4 q "${NEW_N:-target/release/deps/field-4bfe497daf268df4}" ;;
  esac
done
