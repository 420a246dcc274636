#!/bin/bash
# Field bench A/B on the 2-core Intel Xeon (family 6 model 167; rustc's `native` = rocketlake):
# 7524d2f (old, the "today") against this session's code, x86-64-v3 builds then native
# builds, each pair alternated; then the native build of the new code without the explicit
# AVX-512 tile (`plain`) and with LLVM's prefer-256-bit tuning turned off (`flag`), once each.
# Each bench is stopped after its first train_step line (the main measurement). Binaries: the
# `cargo bench --no-run --bench field` executables, copied to $D.
D=${D:-/work/bins}
lscpu | grep -E 'Model name|^Model:|CPU family|^CPU\(s\)|L3'
grep -o -w -E 'avx512f|avx2|fma|avx512_fp16|amx_tile' /proc/cpuinfo | sort | uniq -c
q() { NEUS_AUG_BENCH_QUICK=1 RAYON_NUM_THREADS=2 "$@" --bench 2>&1 | awk '/FMA peak|triad|^== default|^== training/{print} /train_step alone/{print; exit}' ; }
for b in ${ORDER:-new-v3 old-v3 old-v3 new-v3 new-n-zmm old-n old-n new-n-zmm new-n-plain new-n-flag}; do
  echo "######## $b $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)"
  case $b in
    old-*) q $D/$b ;;
    new-*) NEUS_AUG_BENCH_FD_EVERY=4 q $D/$b ;;
  esac
done
