#!/bin/bash
# Field bench A/B on the lent machine's CPU: 7524d2f (old) against b4adff2 (new; HEAD's code), two
# rayon threads pinned to two distinct cores, the rest of the machine idle; x86-64-v3 builds, then
# sapphirerapids (AVX-512) builds, each pair alternated. Each bench is stopped after its first
# train_step line (the main measurement), so the new bench's one-sided pairs do not run.
D=$(pwd)/.dev21
lscpu | grep -E 'Model name|^Model:|CPU family|Thread|^CPU\(s\)|L3'
grep -o -w -E 'avx512f|avx2|fma|avx512_bf16|amx_tile' /proc/cpuinfo | sort | uniq -c
cpus=$(lscpu -p=CPU,CORE | grep -v '^#' | sort -t, -k2,2n -u | head -2 | cut -d, -f1 | paste -sd,)
echo "pinned to CPUs $cpus"
q() { NEUS_AUG_BENCH_QUICK=1 RAYON_NUM_THREADS=2 taskset -c $cpus "$@" --bench 2>&1 | awk '/FMA peak|triad|^== default|^== training/{print} /train_step alone/{print; exit}' ; }
for b in new-v3 old-v3 old-v3 new-v3 new-spr old-spr old-spr new-spr; do
  echo "######## $b $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  case $b in
    old-*) q $D/$b ;;
    new-*) NEUS_AUG_BENCH_FD_EVERY=4 q $D/$b ;;
  esac
done
