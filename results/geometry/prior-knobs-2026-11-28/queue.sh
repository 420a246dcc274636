#!/bin/bash
# queue.sh BIN NAME "args" NAME "args" ... : each config, seeds 0 and 1 concurrently
bin=$1; shift
while [ $# -gt 0 ]; do
  n=$1; a=$2; shift 2
  SEED=0 ./one.sh $n $bin $a > r/$n.sum 2>&1 &
  SEED=1 ./one.sh ${n}_s1 $bin $a > r/${n}_s1.sum 2>&1 &
  wait
done
