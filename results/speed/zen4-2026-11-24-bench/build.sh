#!/bin/bash
# field bench binaries: new (main HEAD) and old (7524d2f), native and x86-64-v3, separate target dirs
set -x
cd /work/main && RUSTFLAGS="-C target-cpu=native" CARGO_TARGET_DIR=/work/exp7/t-new-n cargo bench --bench field --no-run 2>&1 | tail -2
cd /work/main && RUSTFLAGS="-C target-cpu=x86-64-v3" CARGO_TARGET_DIR=/work/exp7/t-new-v3 cargo bench --bench field --no-run 2>&1 | tail -2
cd /work/wt-old && RUSTFLAGS="-C target-cpu=native" CARGO_TARGET_DIR=/work/exp7/t-old-n cargo bench --bench field --no-run 2>&1 | tail -2
cd /work/wt-old && RUSTFLAGS="-C target-cpu=x86-64-v3" CARGO_TARGET_DIR=/work/exp7/t-old-v3 cargo bench --bench field --no-run 2>&1 | tail -2
