#!/usr/bin/env bash
# The fresh-machine proof for the README's test command: make this machine look like a
# fresh one to the Python cross-checks, then run exactly the README's test command.
#   - removes the project venv (target/py-venv, or $NEUS_AUG_VENV) and its lock file;
#   - as root, purges Debian's libusb-1.0-0 (open3d needs it; _pyenv.py must install it itself,
#     once, even though several cross-check tests start at the same time);
#   - as root, removes Debian's colmap package (tests/colmap_roundtrip.rs runs
#     scripts/colmap_roundtrip.sh, which must install it itself; its dependencies stay).
# Run it on a quiet machine: it changes system packages and takes several minutes (pip downloads
# about 1.2 GB). Without root, libusb is left alone and the run proves only the venv part.
set -euo pipefail
cd "$(dirname "$0")/.."

venv="${NEUS_AUG_VENV:-target/py-venv}"
echo "[fresh] removing $venv"
rm -rf -- "$venv" "$venv.lock"

if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
  if dpkg -s libusb-1.0-0 >/dev/null 2>&1; then
    echo "[fresh] purging libusb-1.0-0"
    # dpkg, not apt-get: it refuses (and stops this script) instead of removing packages that
    # depend on libusb.
    dpkg --purge libusb-1.0-0
  fi
  if ldconfig -p | grep -q 'libusb-1.0'; then
    echo "[fresh] warning: libusb-1.0 is still on the loader path (installed outside dpkg?)" >&2
  fi
  if dpkg -s colmap >/dev/null 2>&1; then
    echo "[fresh] removing colmap"
    dpkg --remove colmap
  fi
  if command -v colmap >/dev/null; then
    echo "[fresh] warning: colmap is still on PATH (installed outside dpkg?)" >&2
  fi
else
  echo "[fresh] not root (or no apt-get): libusb-1.0-0 and colmap left as they are" >&2
fi

echo "[fresh] cargo test --release --workspace"
cargo test --release --workspace
