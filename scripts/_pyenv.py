"""Shared bootstrap for the cross-check scripts: a project virtual environment, created once.

Every script under scripts/ starts with

    import _pyenv
    _pyenv.ensure({"numpy": "numpy", "cv2": "opencv-python-headless"})

which (1) creates the venv at $NEUS_AUG_VENV (default: <repo>/target/py-venv) if it is missing,
(2) re-executes the script with the venv's interpreter, and (3) pip-installs the requirements whose
import name is not importable yet. Nothing is installed outside the venv, except Debian's
libusb-1.0-0 that `import open3d` needs (see `ensure_libusb`).

Safe to run from parallel tests on a fresh machine: venv creation, pip installs and the system
package install all hold ONE inter-process lock (`fcntl.flock` on `<venv>.lock`, by default
target/py-venv.lock), and each re-checks under the lock whether another process already did the
work. A venv counts as made only once its marker file is written, so a creation killed half-way is
redone, not trusted. `apt-get update` always runs before the first `apt-get install`, and apt waits
for dpkg's own lock (other tools may hold it) instead of failing. Where nothing can be installed
(not root, no apt-get, no network) the scripts stop with a message naming what to install by hand.
"""

from __future__ import annotations

import ctypes.util
import fcntl
import glob
import importlib.util
import os
import shutil
import subprocess
import sys
import venv
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = Path(os.environ.get("NEUS_AUG_VENV", ROOT / "target" / "py-venv")).resolve()
# The one lock for everything this module installs (venv, pip packages, system packages).
LOCK = VENV.parent / (VENV.name + ".lock")
# Written last by a successful venv creation.
READY = VENV / ".neus-aug-ready"
# Seconds apt waits for dpkg's lock when a process outside this module holds it.
APT_LOCK_TIMEOUT_S = 300


@contextmanager
def _locked():
    """Hold the module's exclusive inter-process lock (blocking) for the body of the `with`."""
    LOCK.parent.mkdir(parents=True, exist_ok=True)
    with open(LOCK, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _python() -> Path:
    return VENV / "bin" / "python"


def _die(message: str) -> None:
    sys.exit(f"[pyenv] {message}")


def _create_venv() -> None:
    """Create the venv from scratch (caller holds the lock); a failure says what to install."""
    print(f"[pyenv] creating {VENV}", file=sys.stderr)
    try:
        venv.EnvBuilder(with_pip=True, clear=True).create(VENV)
    except (OSError, subprocess.CalledProcessError) as e:
        shutil.rmtree(VENV, ignore_errors=True)
        _die(
            f"could not create the virtual environment {VENV}: {e}\n"
            "  Python's venv module with pip is needed; on Debian/Ubuntu install it by hand with\n"
            "  `apt-get install -y python3-venv` (as root), then retry."
        )
    READY.write_text("ok\n")


def _venv_ready() -> bool:
    """The venv is complete: its marker exists, or (made before markers existed) it has both an
    interpreter and pip, which `venv` installs last."""
    if READY.exists():
        return True
    if _python().exists() and glob.glob(str(VENV / "lib" / "python*" / "site-packages" / "pip")):
        READY.write_text("ok\n")
        return True
    return False


def ensure_venv() -> None:
    """Create the venv unless it is complete; parallel callers create it once, under the lock."""
    if not _venv_ready():
        with _locked():
            if not _venv_ready():
                _create_venv()


def ensure(requirements: dict[str, str]) -> None:
    """Enter the venv and make sure every `import name -> pip requirement` is installed."""
    if Path(sys.prefix).resolve() != VENV:
        ensure_venv()
        os.execv(str(_python()), [str(_python()), *sys.argv])
    missing = [req for mod, req in requirements.items() if importlib.util.find_spec(mod) is None]
    if missing:
        with _locked():
            importlib.invalidate_caches()
            missing = [r for m, r in requirements.items() if importlib.util.find_spec(m) is None]
            if missing:
                print(f"[pyenv] pip install {' '.join(missing)}", file=sys.stderr)
                pip = [str(_python()), "-m", "pip", "install", "-q", "--disable-pip-version-check"]
                if subprocess.run([*pip, *missing]).returncode != 0:
                    _die(
                        f"`pip install {' '.join(missing)}` failed (see pip's message above; "
                        "a machine without network access cannot install them).\n"
                        f"  Install them by hand into the venv: {_python()} -m pip install "
                        f"{' '.join(missing)}"
                    )
                importlib.invalidate_caches()


# Where Debian and other distributions put shared libraries, for the file check below.
_LIB_DIRS = ["/lib", "/usr/lib", "/lib64", "/usr/lib64", "/usr/local/lib", "/lib/*-linux-gnu", "/usr/lib/*-linux-gnu"]


def library_present(name: str) -> bool:
    """True when the shared library `lib<name>.so*` is on the loader's path (`ldconfig -p`, via
    ctypes) or present as a file in one of the usual library folders."""
    if ctypes.util.find_library(name):
        return True
    return any(glob.glob(os.path.join(d, f"lib{name}.so*")) for d in _LIB_DIRS)


def ensure_system_library(name: str, package: str, why: str) -> None:
    """Make sure shared library `lib<name>` exists, installing Debian package `package` with apt
    when it is missing and we are root; otherwise stop with a message naming what to install.

    Held under the module's lock and re-checked there, so parallel callers install at most once;
    `apt-get update` runs first (a fresh machine's package lists are empty or stale)."""
    if library_present(name):
        return
    by_hand = f"install it by hand with `apt-get update && apt-get install -y {package}` (as root), then retry"
    with _locked():
        if library_present(name):
            return
        apt = shutil.which("apt-get")
        if os.geteuid() != 0 or apt is None:
            reason = "not running as root" if os.geteuid() != 0 else "apt-get is not available"
            _die(f"{why} needs lib{name} (Debian package {package}), which is missing, and {reason}:\n  {by_hand}")
        wait = ["-o", f"DPkg::Lock::Timeout={APT_LOCK_TIMEOUT_S}"]
        print(f"[pyenv] apt-get update && apt-get install {package} (needed by {why})", file=sys.stderr)
        for step in (["update", "-qq"], ["install", "-y", "-qq", package]):
            done = subprocess.run(
                [apt, *wait, *step],
                stdout=subprocess.DEVNULL,
                env={**os.environ, "DEBIAN_FRONTEND": "noninteractive"},
            )
            if done.returncode != 0:
                _die(f"`apt-get {' '.join(step)}` failed (exit {done.returncode}, message above): {by_hand}")
        if not library_present(name):
            _die(f"apt-get installed {package} but lib{name} is still not found: {by_hand}")


def ensure_libusb() -> None:
    """open3d's CPU wheel links libusb-1.0 (Debian package libusb-1.0-0)."""
    ensure_system_library("usb-1.0", "libusb-1.0-0", "open3d")
