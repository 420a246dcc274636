#!/usr/bin/env python3
"""Tests for _pyenv's inter-process lock, run with the system python3 (standard library only).

Starts several processes at once, as `cargo test` does with the cross-check scripts, against a
fake `apt-get` (first on PATH) and a fake venv builder, each of which logs when it starts and ends
and sleeps in between. Checks that:
  - parallel `ensure_libusb` calls run `apt-get update` then `apt-get install` exactly once,
    never overlapping, and all succeed;
  - no apt-get runs at all when the library is already present;
  - parallel `ensure_venv` calls create the venv exactly once;
  - without root (or when apt fails) the process stops with a message naming what to install.
Exits 1 with the failing check's message; prints "all pyenv checks passed" otherwise.

Used by tests/pyenv_lock.rs. Child mode (internal): test_pyenv.py --child MODE WORKDIR.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
N_PARALLEL = 6

FAKE_APT = """#!/bin/sh
# Fake apt-get: logs start/end of its verb, sleeps, creates the 'library' on install.
verb=""
for a in "$@"; do case "$a" in update|install) verb="$a";; esac; done
echo "start $verb" >> "$WORK/log"
sleep 0.3
if [ "$verb" = update ] && [ -e "$WORK/apt-fails" ]; then echo "end $verb (failed)" >> "$WORK/log"; exit 100; fi
[ "$verb" = install ] && touch "$WORK/libfake.so"
echo "end $verb" >> "$WORK/log"
"""


def child(mode: str, work: Path) -> None:
    os.environ["NEUS_AUG_VENV"] = str(work / "venv")
    sys.path.insert(0, str(HERE))
    import _pyenv

    def log(line: str) -> None:
        with open(work / "log", "a") as fh:
            fh.write(line + "\n")

    _pyenv.library_present = lambda name: (work / "libfake.so").exists()
    _pyenv.os.geteuid = (lambda: 1000) if mode == "noroot" else (lambda: 0)
    if mode == "venv":

        def fake_create() -> None:
            log("start create")
            time.sleep(0.3)
            _pyenv.VENV.mkdir(parents=True)
            _pyenv.READY.write_text("ok\n")
            log("end create")

        _pyenv._create_venv = fake_create
        _pyenv.ensure_venv()
    else:
        _pyenv.ensure_libusb()


def run_children(mode: str, work: Path, n: int) -> list[subprocess.CompletedProcess]:
    env = {**os.environ, "WORK": str(work), "PATH": f"{work / 'bin'}:{os.environ.get('PATH', '')}"}
    procs = [
        subprocess.Popen(
            [sys.executable, __file__, "--child", mode, str(work)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(n)
    ]
    return [subprocess.CompletedProcess(p.args, p.wait(), *p.communicate()) for p in procs]


def fresh_work(root: Path, name: str) -> Path:
    work = root / name
    (work / "bin").mkdir(parents=True)
    apt = work / "bin" / "apt-get"
    apt.write_text(FAKE_APT)
    apt.chmod(0o755)
    return work


def read_log(work: Path) -> list[str]:
    path = work / "log"
    return path.read_text().splitlines() if path.exists() else []


def check(cond: bool, message: str) -> None:
    if not cond:
        sys.exit(f"FAILED: {message}")


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)

        work = fresh_work(root, "apt")
        done = run_children("apt", work, N_PARALLEL)
        for d in done:
            check(d.returncode == 0, f"a parallel ensure_libusb failed: {d.stderr}")
        log = read_log(work)
        expected = ["start update", "end update", "start install", "end install"]
        check(log == expected, f"apt-get calls overlapped or repeated: {log}, expected {expected}")
        print(f"ok: {N_PARALLEL} parallel installs ran apt-get update+install once, in order")

        done = run_children("apt", work, 2)
        check(all(d.returncode == 0 for d in done), "ensure_libusb failed with the library present")
        check(read_log(work) == expected, f"apt-get ran although the library was present: {read_log(work)}")
        print("ok: no apt-get when the library is present")

        work = fresh_work(root, "venv")
        done = run_children("venv", work, N_PARALLEL)
        for d in done:
            check(d.returncode == 0, f"a parallel ensure_venv failed: {d.stderr}")
        check(read_log(work) == ["start create", "end create"], f"venv created more than once: {read_log(work)}")
        print(f"ok: {N_PARALLEL} parallel ensure_venv created the venv once")

        work = fresh_work(root, "noroot")
        [d] = run_children("noroot", work, 1)
        check(d.returncode != 0, "ensure_libusb succeeded without root and without the library")
        check("apt-get install -y libusb-1.0-0" in d.stderr, f"no install instruction: {d.stderr}")
        check("not running as root" in d.stderr, f"reason not stated: {d.stderr}")
        check(read_log(work) == [], f"apt-get ran without root: {read_log(work)}")
        print("ok: without root, a message naming the package to install by hand")

        work = fresh_work(root, "aptfail")
        (work / "apt-fails").touch()
        [d] = run_children("apt", work, 1)
        check(d.returncode != 0, "ensure_libusb succeeded although apt-get update failed")
        check("apt-get update" in d.stderr and "libusb-1.0-0" in d.stderr, f"unclear message: {d.stderr}")
        check(read_log(work) == ["start update", "end update (failed)"], f"install ran after a failed update: {read_log(work)}")
        print("ok: a failed apt-get update stops with a message, install not attempted")
    print("all pyenv checks passed")


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--child":
        child(sys.argv[2], Path(sys.argv[3]))
    else:
        main()
