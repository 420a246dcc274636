#!/bin/bash
# Run from a copy of this folder with src/main.rs = peer-probe.rs (needs the crates.io index
# cached or network). The two builds differ only in which kernel matrixmultiply may pick.
set -e
mkdir -p src && cp peer-probe.rs src/main.rs
RUSTFLAGS="-C target-cpu=x86-64-v3" cargo build --release -q 2>/dev/null
echo "## matrixmultiply free to pick (AVX-512 on this CPU)"; ./target/release/pk
MMTEST_FEATURE=avx,avx2,fma RUSTFLAGS="-C target-cpu=x86-64-v3" cargo build --release -q 2>/dev/null
echo "## MMTEST_FEATURE=avx,avx2,fma (the crate's AVX2 + FMA kernel)"; ./target/release/pk
