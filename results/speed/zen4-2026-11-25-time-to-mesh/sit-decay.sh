run() { # bin preset tag
  t0=$(date +%s.%N)
  ./$1 reconstruct --preset $2 --seed 0 --out t/$3 --force > t/$3.log 2>&1
  t1=$(date +%s.%N)
  echo "$3 $1 $2 wall=$(echo "$t1 - $t0" | bc) $(grep -o 'sum [0-9.]* mm' t/$3.log | tail -1)" >> timing.log
}
mkdir -p t
run na4 fast a-old-fast; run na6 fast a-new-fast; run na4 quick a-old-quick; run na6 quick a-new-quick
run na6 fast b-new-fast; run na4 fast b-old-fast; run na6 quick b-new-quick; run na4 quick b-old-quick
