#!/bin/bash
cd /work/exp8
run() { # bin preset tag
  t0=$(date +%s.%N)
  ./$1 reconstruct --preset $2 --seed 0 --out t/$3 --force > t/$3.log 2>&1
  rc=$?
  t1=$(date +%s.%N)
  echo "$3 $1 $2 rc=$rc wall=$(echo "$t1 - $t0" | bc) $(grep -o 'sum [0-9.]* mm' t/$3.log | tail -1)" >> timing2.log
}
echo "start timing2 $(date)" >> queue.log
run na0 fast c-na0-fast; run na6 quick c-na6-quick; run na0v3 fast c-na0v3-fast; run na6v3 quick c-na6v3-quick; run na4v3 fast c-na4v3-fast; run na6v3 fast c-na6v3-fast
run na6v3 fast d-na6v3-fast; run na4v3 fast d-na4v3-fast; run na6v3 quick d-na6v3-quick; run na0v3 fast d-na0v3-fast; run na6 quick d-na6-quick; run na0 fast d-na0-fast
echo "end timing2 $(date)" >> queue.log
