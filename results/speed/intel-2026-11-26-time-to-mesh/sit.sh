#!/bin/bash
# One idle sitting on the 2-core Intel Xeon (family 6 model 167): time to mesh, old `fast`
# (7524d2f) against new `quick` (this session's HEAD), native and x86-64-v3 builds, two rounds,
# the second reversed. Run from a folder holding the four binaries, after one untimed run of each
# code (two training steps) has generated its default scene into the cache (~/.cache/neus-aug).
run() { # bin preset tag
  t0=$(date +%s.%N)
  ./$1 reconstruct --preset $2 --seed 0 --out t/$3 --force > t/$3.log 2>&1
  rc=$?
  t1=$(date +%s.%N)
  echo "$3 $1 $2 rc=$rc wall=$(echo "$t1 - $t0" | bc) $(grep -o 'sum [0-9.]* mm' t/$3.log | tail -1)" >> timing.log
}
echo "start $(date) load $(cut -d' ' -f1-3 /proc/loadavg)" >> timing.log
run old-n fast c-old-n-fast; run new-n quick c-new-n-quick; run old-v3 fast c-old-v3-fast; run new-v3 quick c-new-v3-quick
run new-v3 quick d-new-v3-quick; run old-v3 fast d-old-v3-fast; run new-n quick d-new-n-quick; run old-n fast d-old-n-fast
echo "end $(date)" >> timing.log
