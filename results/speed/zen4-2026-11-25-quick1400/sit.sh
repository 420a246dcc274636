#!/bin/bash
# One idle sitting: time to mesh (old fast vs new quick, native and v3, two rounds, the second
# reversed), then the new pareto grid and the old one (each stopped before its `default` run).
cd /work/exp9
run() { # bin preset tag
  t0=$(date +%s.%N)
  ./$1 reconstruct --preset $2 --seed 0 --out t/$3 --force > t/$3.log 2>&1
  rc=$?
  t1=$(date +%s.%N)
  echo "$3 $1 $2 rc=$rc wall=$(echo "$t1 - $t0" | bc) $(grep -o 'sum [0-9.]* mm' t/$3.log | tail -1)" >> timing.log
}
pareto() { # bin dir
  ./$1 study pareto --preset fast --seeds 1 --scenes blob --out $2 > $2.log 2>&1 &
  pid=$!
  while kill -0 $pid 2>/dev/null; do
    if [ -d $2/runs/blob-presetdefault-s0 ]; then kill $pid; sleep 2; pkill -f "$2/runs/blob-presetdefault" ; pkill -f "runs/blob-presetdefault-s0"; break; fi
    sleep 2
  done
  wait $pid 2>/dev/null
  echo "pareto $1 $2 stopped $(date)" >> timing.log
}
echo "start $(date)" >> timing.log
run na0 fast c-na0-fast; run na9 quick c-na9-quick; run na0v3 fast c-na0v3-fast; run na9v3 quick c-na9v3-quick
run na9v3 quick d-na9v3-quick; run na0v3 fast d-na0v3-fast; run na9 quick d-na9-quick; run na0 fast d-na0-fast
pareto na9 par-new
pareto na0 par-old
echo "end $(date)" >> timing.log
