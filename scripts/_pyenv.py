"""Shared bootstrap for the cross-check scripts: a project virtual environment, created once.

Every script under scripts/ starts with

    import _pyenv
    _pyenv.ensure({"numpy": "numpy", "cv2": "opencv-python-headless"})

which (1) creates the venv at $NEUS_AUG_VENV (default: <repo>/target/py-venv) if it is missing,
(2) re-executes the script with the venv's interpreter, and (3) pip-installs the requirements whose
import name is not importable yet. Creation and installs hold a file lock, so tests that run scripts
in parallel do not race. Nothing is installed outside the venv, except Debian's libusb-1.0-0 that
`import open3d` needs (see `ensure_libusb`).
"""

from __future__ import annotations

import ctypes.util
import fcntl
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


@contextmanager
def _locked():
    VENV.parent.mkdir(parents=True, exist_ok=True)
    with open(VENV.parent / (VENV.name + ".lock"), "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _python() -> Path:
    return VENV / "bin" / "python"


def ensure(requirements: dict[str, str]) -> None:
    """Enter the venv and make sure every `import name -> pip requirement` is installed."""
    if Path(sys.prefix).resolve() != VENV:
        with _locked():
            if not _python().exists():
                print(f"[pyenv] creating {VENV}", file=sys.stderr)
                venv.EnvBuilder(with_pip=True, clear=True).create(VENV)
        os.execv(str(_python()), [str(_python()), *sys.argv])
    missing = [req for mod, req in requirements.items() if importlib.util.find_spec(mod) is None]
    if missing:
        with _locked():
            importlib.invalidate_caches()
            missing = [r for m, r in requirements.items() if importlib.util.find_spec(m) is None]
            if missing:
                print(f"[pyenv] pip install {' '.join(missing)}", file=sys.stderr)
                subprocess.run(
                    [str(_python()), "-m", "pip", "install", "-q", "--disable-pip-version-check", *missing],
                    check=True,
                )
                importlib.invalidate_caches()


def ensure_libusb() -> None:
    """open3d's CPU wheel links libusb-1.0; install Debian's package when it is absent and we are root."""
    if ctypes.util.find_library("usb-1.0"):
        return
    if os.geteuid() == 0 and shutil.which("apt-get"):
        print("[pyenv] apt-get install libusb-1.0-0 (needed by open3d)", file=sys.stderr)
        subprocess.run(["apt-get", "update", "-qq"], check=False, stdout=subprocess.DEVNULL)
        subprocess.run(["apt-get", "install", "-y", "-qq", "libusb-1.0-0"], check=True, stdout=subprocess.DEVNULL)
        return
    sys.exit("open3d needs libusb-1.0: run `apt-get install -y libusb-1.0-0` as root, then retry")
