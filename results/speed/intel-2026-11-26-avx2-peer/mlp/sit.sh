#!/bin/bash
# MLP-only bench sitting, one at a time: old panel (HEAD 26115ad) vs new (ymm_panel), x86-64-v3 builds.
# *-mm: built with MMTEST_FEATURE=avx,avx2,fma (matrixmultiply limited to its AVX2 kernel).
set -u
run() { echo "### $1 $(date -u +%T)"; NEUS_AUG_BENCH_MLP_ONLY=1 RAYON_NUM_THREADS=2 $2 --bench; }
OLDMM=$(ls /work/tgt-headmm/release/deps/field-* | grep -v '\.d$' | head -1)
NEWMM=$(ls /work/tgt-v3mm/release/deps/field-* | grep -v '\.d$' | head -1)
NEW=$(ls /work/tgt-v3/release/deps/field-* | grep -v '\.d$' | head -1)
for round in 1 2; do
  run old-mm $OLDMM > old-mm-$round.out 2>&1
  run new-mm $NEWMM > new-mm-$round.out 2>&1
  run new $NEW > new-$round.out 2>&1
done
