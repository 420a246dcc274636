# Sitting C: new native binary, one-sided pairs at span 1 and span 2 (is the cost span-2 specific?)
q() { NEUS_AUG_BENCH_QUICK=1 "$@" --bench 2>&1 | grep -E "train_step alone|one-sided against|^== default" ; }
G=$(pgrep -f grid.sh | head -1); PG=$(ps -o pgid= -p $G | tr -d ' ')
kill -STOP -- -$PG; sleep 3
cd /work/main
for s in 1 2 1 2; do echo "######## span $s $(date +%T)"; NEUS_AUG_BENCH_FD_SPAN=$s q target/release/deps/field-4bfe497daf268df4; done
kill -CONT -- -$PG
