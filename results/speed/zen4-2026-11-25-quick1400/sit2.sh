#!/bin/bash
# One idle sitting on a second Zen 4 instance: time to mesh, old fast (7524d2f) against new quick
# (HEAD), native and x86-64-v3, two rounds, the second reversed.
cd /work/exp9
run() { # bin preset tag
  t0=$(date +%s.%N)
  ./$1 reconstruct --preset $2 --seed 0 --out t/$3 --force > t/$3.log 2>&1
  rc=$?
  t1=$(date +%s.%N)
  echo "$3 $1 $2 rc=$rc wall=$(echo "$t1 - $t0" | bc) $(grep -o 'sum [0-9.]* mm' t/$3.log | tail -1)" >> timing2.log
}
echo "start $(date) load $(cut -d' ' -f1-3 /proc/loadavg)" >> timing2.log
run na0 fast c-na0-fast; run nanew quick c-nanew-quick; run na0v3 fast c-na0v3-fast; run nav3 quick c-nav3-quick
run nav3 quick d-nav3-quick; run na0v3 fast d-na0v3-fast; run nanew quick d-nanew-quick; run na0 fast d-na0-fast
echo "end $(date)" >> timing2.log
