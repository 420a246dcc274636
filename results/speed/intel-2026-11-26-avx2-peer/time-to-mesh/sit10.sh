#!/bin/bash
# One more round of time to mesh (issue 14), this session (2026-11-26, tenth): old `fast`
# (7524d2f binaries of the earlier sitting) against new `quick` (this session's binaries with
# ymm_panel), native then x86-64-v3, on the same idle 2-core Intel Xeon.
run() { # bin preset tag
  t0=$(date +%s.%N)
  ./$1 reconstruct --preset $2 --seed 0 --out t/$3 --force > t/$3.log 2>&1
  rc=$?
  t1=$(date +%s.%N)
  echo "$3 $1 $2 rc=$rc wall=$(echo "$t1 - $t0" | bc) $(grep -o 'sum [0-9.]* mm' t/$3.log | tail -1)" >> timing10.log
}
echo "start $(date) load $(cut -d' ' -f1-3 /proc/loadavg)" >> timing10.log
run old-n fast e-old-n-fast; run new-n-s10 quick e-new-n-quick; run old-v3 fast e-old-v3-fast; run new-v3-s10 quick e-new-v3-quick
echo "end $(date)" >> timing10.log
