#!/usr/bin/env python3
"""Marching cubes at 512^3: scikit-image and PyMCubes against neus-aug, measured in the same run.

Builds the analytic sphere grid (the `sphere` shape of neus_aug::mesh::sdf, radius 0.61 in
[-1, 1]^3; float32, the same values neus-aug samples, see crosscheck_mcubes.py), times
- scikit-image `marching_cubes(vol, 0)` (Lewiner, its default; float32 input, no conversion);
- PyMCubes `marching_cubes(vol, 0)`;
then runs `cargo bench -p neus-aug --bench mcubes -- --res N` (neus-aug's grid evaluation,
extraction from the grid in memory, and streaming SDF + extraction; plus isosurface 0.1.0-alpha.0)
and prints every time and the ratios peer / neus-aug. The peers' times exclude building the grid,
like neus-aug's `extract`; `streaming` includes the SDF evaluation of the sphere. Each figure is the
best of --repeats runs (PyMCubes: one run). Takes about a minute at 512^3 on 2 cores.

usage: bench_mcubes.py [--res 512] [--repeats 2] [--no-oracle]
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _pyenv  # noqa: E402

_pyenv.ensure({"numpy": "numpy", "skimage": "scikit-image", "mcubes": "pymcubes", "scipy": "scipy"})

import argparse  # noqa: E402
import os  # noqa: E402
import subprocess  # noqa: E402
import time  # noqa: E402

import mcubes  # noqa: E402
import numpy as np  # noqa: E402
from skimage.measure import marching_cubes  # noqa: E402

from crosscheck_mcubes import grid_values  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def best_of(repeats, f):
    best, out = float("inf"), None
    for _ in range(max(1, repeats)):
        t = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t)
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--res", type=int, default=512)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--no-oracle", action="store_true", help="skip isosurface 0.1.0-alpha.0")
    args = ap.parse_args()
    n = args.res
    print(f"sphere at {n}^3, {os.cpu_count()} cores")

    t_grid, vol = best_of(1, lambda: grid_values("sphere", (-1, -1, -1), (1, 1, 1), n))
    t_sk, (sv, sf, _, _) = best_of(args.repeats, lambda: marching_cubes(vol, 0.0))
    t_mc, (mv, mf) = best_of(1, lambda: mcubes.marching_cubes(vol, 0.0))
    del vol
    peers = {
        "scikit-image": (t_sk, len(sv), len(sf)),
        "PyMCubes": (t_mc, len(mv), len(mf)),
    }
    del sv, sf, mv, mf

    cmd = ["cargo", "bench", "-q", "-p", "neus-aug", "--bench", "mcubes", "--", "--res", str(n), "--repeats", "3"]
    if args.no_oracle:
        cmd.append("--no-oracle")
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{out.stdout}\n{out.stderr}")
    ours = {}
    for line in out.stdout.splitlines():
        if line.startswith("RESULT "):
            _, name, secs, nv, nf = line.split()
            ours[name] = (float(secs), int(nv), int(nf))

    print(f"\n{'':38}{'seconds':>9}{'vertices':>10}{'faces':>10}")
    print(f"  {'numpy grid evaluation (float32)':<36}{t_grid:>9.3f}")
    for name, (t, nv, nf) in peers.items():
        print(f"  {name:<36}{t:>9.3f}{nv:>10}{nf:>10}")
    labels = {
        "grid_eval": "neus-aug grid evaluation",
        "extract": "neus-aug extraction (grid in memory)",
        "streaming": "neus-aug streaming (SDF + extract)",
        "isosurface": "isosurface 0.1.0-alpha.0",
    }
    for key, (t, nv, nf) in ours.items():
        counts = f"{nv:>10}{nf:>10}" if nf else ""
        print(f"  {labels.get(key, key):<36}{t:>9.3f}{counts}")

    print("\nratios (peer time / neus-aug time, same run):")
    for name, (t, nv, nf) in peers.items():
        for key in ("extract", "streaming"):
            if key in ours:
                print(f"  {name} / neus-aug {key:<10} {t / ours[key][0]:6.1f}x")
    if "isosurface" in ours:
        print(f"  isosurface / neus-aug extract    {ours['isosurface'][0] / ours['extract'][0]:6.1f}x")
    counts = {(nv, nf) for _, nv, nf in peers.values()} | {ours["extract"][1:]}
    print(f"counts {'agree' if len(counts) == 1 else 'DIFFER: ' + str(counts)}")


if __name__ == "__main__":
    main()
