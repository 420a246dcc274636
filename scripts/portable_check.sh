#!/usr/bin/env bash
# The portable builds: the code paths a user without AVX2 or without x86 takes.
#   x86-64-v2: SSE4.2, no AVX, no FMA (`RUSTFLAGS="-C target-cpu=x86-64-v2"`): the library's unit
#              tests, which test every kernel against its slow reference, run natively.
#   aarch64:   the whole workspace cross-compiles (`cargo check --all-targets`), then the library's
#              unit tests run under qemu user-mode emulation (NEON, the `target_arch` fallbacks).
# Each build has its own target folder (target-v2, target-aarch64), so the native build stays.
# Installs, as root, what it lacks: the rustup target, Debian's gcc-aarch64-linux-gnu (linker and
# C compiler of the -sys build scripts) and qemu-user. Not part of `.ci/run`: a cold build of
# both takes about 10 minutes on 2 cores, and the emulated tests several more.
# Usage: scripts/portable_check.sh [v2|aarch64|all]   (default all)
set -euo pipefail
cd "$(dirname "$0")/.."
what="${1:-all}"
case "$what" in v2 | aarch64 | all) ;; *)
  echo "usage: $0 [v2|aarch64|all]" >&2
  exit 2
  ;;
esac

if [ "$what" = v2 ] || [ "$what" = all ]; then
  echo "[portable] x86-64-v2: unit tests"
  # RUSTFLAGS replaces the repository's `target-cpu=native` (.cargo/config.toml).
  RUSTFLAGS="-C target-cpu=x86-64-v2" CARGO_TARGET_DIR=target-v2 \
    cargo test --release --workspace --lib
fi

if [ "$what" = aarch64 ] || [ "$what" = all ]; then
  t=aarch64-unknown-linux-gnu
  if ! rustup target list --installed | grep -qx "$t"; then
    rustup target add "$t"
  fi
  need=()
  command -v aarch64-linux-gnu-gcc >/dev/null || need+=(gcc-aarch64-linux-gnu)
  command -v qemu-aarch64 >/dev/null || need+=(qemu-user)
  if [ ${#need[@]} -gt 0 ]; then
    if [ "$(id -u)" != 0 ]; then
      echo "[portable] missing ${need[*]}: install them (Debian) or run as root" >&2
      exit 1
    fi
    apt-get update -qq && apt-get install -y -qq "${need[@]}"
  fi
  export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
  export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER="qemu-aarch64 -L /usr/aarch64-linux-gnu"
  echo "[portable] aarch64: every target compiles"
  # An empty RUSTFLAGS: `target-cpu=native` names the host CPU, not an aarch64 one.
  RUSTFLAGS="" CARGO_TARGET_DIR=target-aarch64 \
    cargo check --release --target "$t" --workspace --all-targets
  echo "[portable] aarch64: unit tests under qemu"
  RUSTFLAGS="" CARGO_TARGET_DIR=target-aarch64 \
    cargo test --release --target "$t" --workspace --lib
fi
echo "[portable] done: $what"
