#!/usr/bin/env bash
# One sitting of the quick field bench, base (commit 2ea29a2) against new (2ea29a2 + the d_out
# prefetch of README section 3), alternated, native then x86-64-v3. Expects the four bench
# binaries beside this script as field-{base,new}-{n,v3} (copied from target/release/deps after
# `cargo bench --bench field --no-run` with the README's RUSTFLAGS) and writes sit1/*.log.
cd "$(dirname "$0")" || exit 1
mkdir -p sit1
for b in base-n new-n new-n base-n base-v3 new-v3 new-v3 base-v3; do
  i=$(ls sit1 | grep -c "^$b")
  NEUS_AUG_BENCH_QUICK=1 ./field-$b --bench > sit1/$b-$i.log 2>&1
  echo "$b $(grep 'train_step alone' sit1/$b-$i.log)"
done
