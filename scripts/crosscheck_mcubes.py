#!/usr/bin/env python3
"""Cross-check neus-aug's marching cubes against PyMCubes and scikit-image on analytic SDFs.

For each shape (sphere, torus, box, two-spheres) and resolution, `neus-aug mcubes` writes its mesh
(binary PLY) and the grid it sampled (.npy). This script rebuilds the same grid itself (the
formulas of `neus_aug::mesh::GridSpec::coords` and `mesh::sdf::Shape`, in float32 with the same
operation order, so the values must be bit-identical), then runs
- PyMCubes `marching_cubes(vol, 0)` (the classic table, the same face rule as neus-aug);
- scikit-image `marching_cubes(-vol, 0, method="lorensen")` (its Lorensen table joins the corners
  with values <= level across ambiguous faces; negating the volume makes that the SDF's outside
  corners, the same rule as neus-aug, as long as no grid value is exactly 0);
- scikit-image's default (Lewiner) method on `vol` (asymptotic decider on ambiguous faces);
and requires the same vertex and triangle counts as neus-aug and the same vertex positions as
sets (after mapping index space to the box: `min + index·(max − min)/(res − 1)`), within --tol
times the cell size. Lewiner's counts are compared too; with --lewiner-info they are only printed.

It also checks neus-aug's topology report (closed, edge-manifold, Euler characteristic), its
outward orientation (positive signed volume), the map to world mm (`--scale/--center`), and the
two-pass extraction (the refined box from the coarse mesh's bounds padded by 10 %, at least one
cell, then PyMCubes on that box). Exits non-zero on any disagreement.

usage: crosscheck_mcubes.py --neus-aug PATH/TO/neus-aug [--res 33,48] [--shapes sphere,torus]
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _pyenv  # noqa: E402

_pyenv.ensure({"numpy": "numpy", "skimage": "scikit-image", "mcubes": "pymcubes", "scipy": "scipy"})

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402

import mcubes  # noqa: E402
import numpy as np  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402
from skimage.measure import marching_cubes  # noqa: E402

F = np.float32

# Must match neus_aug::mesh::sdf::Shape::named.
SHAPES = {
    "sphere": ("sphere", dict(c=(0.031, -0.047, 0.013), r=0.61)),
    "torus": ("torus", dict(c=(0.017, 0.023, -0.011), R=0.52, r=0.21)),
    "box": ("box", dict(c=(0.013, -0.021, 0.037), h=(0.43, 0.31, 0.52))),
    "two-spheres": ("two", dict(a=(-0.41, 0.02, 0.03), ra=0.33, b=(0.43, -0.05, 0.01), rb=0.29)),
}
EULER = {"sphere": 2, "torus": 0, "box": 2, "two-spheres": 4}


def coords(lo: float, hi: float, n: int) -> np.ndarray:
    """GridSpec::coords: lo + (hi − lo)·(i/(n − 1)) in float64 from float32 ends, last = hi."""
    lo, hi = float(F(lo)), float(F(hi))
    out = [lo + (hi - lo) * (i / (n - 1)) for i in range(n - 1)] + [hi]
    return np.array(out, dtype=np.float64).astype(F)


def _len(x, y, z):
    return np.sqrt(x * x + y * y + z * z)


def sdf(name: str, x, y, z):
    """Shape::eval in float32 (same operations in the same order)."""
    kind, p = SHAPES[name]
    if kind == "sphere":
        c = [F(v) for v in p["c"]]
        return _len(x - c[0], y - c[1], z - c[2]) - F(p["r"])
    if kind == "torus":
        c = [F(v) for v in p["c"]]
        qx, qy, qz = x - c[0], y - c[1], z - c[2]
        ring = np.sqrt(qx * qx + qy * qy) - F(p["R"])
        return np.sqrt(ring * ring + qz * qz) - F(p["r"])
    if kind == "box":
        c = [F(v) for v in p["c"]]
        h = [F(v) for v in p["h"]]
        d = [np.abs(q) - hh for q, hh in zip((x - c[0], y - c[1], z - c[2]), h)]
        zero = F(0)
        outside = _len(*(np.maximum(di, zero) for di in d))
        return outside + np.minimum(np.maximum(np.maximum(d[0], d[1]), d[2]), zero)
    a = [F(v) for v in p["a"]]
    b = [F(v) for v in p["b"]]
    da = _len(x - a[0], y - a[1], z - a[2]) - F(p["ra"])
    db = _len(x - b[0], y - b[1], z - b[2]) - F(p["rb"])
    return np.minimum(da, db)


def grid_values(name: str, lo, hi, n: int) -> np.ndarray:
    """The SDF on the grid as vol[i, j, k] (float32), evaluated one z-plane at a time."""
    xs, ys, zs = (coords(lo[a], hi[a], n) for a in range(3))
    vol = np.empty((n, n, n), dtype=F)
    x, y = np.meshgrid(xs, ys, indexing="ij")
    for k, z in enumerate(zs):
        vol[:, :, k] = sdf(name, x, y, np.full_like(x, z))
    return vol


def to_box(v_index: np.ndarray, lo, hi, n: int) -> np.ndarray:
    lo = np.array([float(F(c)) for c in lo])
    hi = np.array([float(F(c)) for c in hi])
    return lo + np.asarray(v_index, dtype=np.float64) * (hi - lo) / (n - 1)


def read_ply(path: Path):
    """The binary little-endian layout dtu_eval::ply writes: float x,y,z; list uchar uint."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    assert "format binary_little_endian 1.0" in header, header
    nv = nf = 0
    for line in header:
        if line.startswith("element vertex"):
            nv = int(line.split()[-1])
        if line.startswith("element face"):
            nf = int(line.split()[-1])
    props = [line for line in header if line.startswith("property")]
    assert props[:3] == ["property float x", "property float y", "property float z"], props
    v = np.frombuffer(data, dtype="<f4", count=3 * nv, offset=end).reshape(nv, 3)
    f = np.frombuffer(
        data, dtype=np.dtype([("n", "u1"), ("i", "<u4", (3,))]), count=nf, offset=end + 12 * nv
    )
    assert nf == 0 or (f["n"] == 3).all()
    return v.astype(np.float64), f["i"].astype(np.int64)


def signed_volume(v, f) -> float:
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def set_distance(a, b) -> float:
    if len(a) == 0 and len(b) == 0:
        return 0.0
    return float(max(cKDTree(b).query(a)[0].max(), cKDTree(a).query(b)[0].max()))


class Checker:
    def __init__(self, tol: float):
        self.tol = tol
        self.failures: list[str] = []

    def check(self, ok: bool, what: str) -> None:
        if not ok:
            self.failures.append(what)
            print(f"  FAIL {what}")

    def compare(self, label: str, ours, theirs, cell: float, counts_only=False) -> None:
        (v, f), (tv, tf) = ours, theirs
        same = (len(v), len(f)) == (len(tv), len(tf))
        line = f"  {label:<28} vertices {len(tv):>7} faces {len(tf):>7}"
        if not same:
            self.check(False, f"{label}: counts {len(tv)}/{len(tf)} vs neus-aug {len(v)}/{len(f)}")
            return
        if counts_only:
            print(line + "  (counts agree)")
            return
        d = set_distance(v, tv)
        print(line + f"  max vertex distance {d / cell:.2e} cells")
        self.check(d <= self.tol * cell, f"{label}: vertex sets differ by {d / cell:.3g} cells")


def run_neus_aug(exe: str, args: list[str]) -> dict:
    out = subprocess.run([exe, "mcubes", *args], capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"neus-aug mcubes {' '.join(args)} failed:\n{out.stdout}\n{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def peers(vol, lo, hi, n):
    """(name, (vertices in the box, faces)) of every peer on vol[i, j, k]."""
    out = []
    v, f = mcubes.marching_cubes(vol, 0.0)
    out.append(("PyMCubes", (to_box(v, lo, hi, n), f)))
    if vol.min() < 0 < vol.max():
        v, f, _, _ = marching_cubes(-vol, 0.0, method="lorensen")
        out.append(("scikit-image lorensen(-sdf)", (to_box(v, lo, hi, n), f)))
        v, f, _, _ = marching_cubes(vol, 0.0)
        out.append(("scikit-image lewiner", (to_box(v, lo, hi, n), f)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--neus-aug", required=True, help="path to the neus-aug binary")
    ap.add_argument("--res", default="33,48", help="comma-separated grid resolutions")
    ap.add_argument("--shapes", default=",".join(SHAPES), help="comma-separated shape names")
    ap.add_argument("--tol", type=float, default=1e-4, help="vertex tolerance, in cells")
    ap.add_argument("--lewiner-info", action="store_true", help="only print Lewiner's counts")
    args = ap.parse_args()
    chk = Checker(args.tol)
    lo, hi = (-1.0, -1.0, -1.0), (1.0, 1.0, 1.0)
    scale, center = 237.5, (12.5, -31.0, 604.25)

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for n in [int(r) for r in args.res.split(",")]:
            for name in args.shapes.split(","):
                print(f"{name} at {n}^3")
                ply, npy = tmp / "m.ply", tmp / "g.npy"
                rep = run_neus_aug(args.neus_aug, ["--sdf", name, "--res", str(n), "--out", str(ply), "--grid-out", str(npy)])
                ours = read_ply(ply)
                cell = 2.0 / (n - 1)
                # 1. The grid neus-aug sampled equals the one rebuilt here, bit for bit.
                vol = grid_values(name, lo, hi, n)
                theirs = np.load(npy).transpose(2, 1, 0)  # [k, j, i] -> [i, j, k]
                chk.check(np.array_equal(vol, theirs), f"{name}/{n}: grid values differ (max {np.abs(vol - theirs).max()})")
                chk.check(not (vol == 0).any(), f"{name}/{n}: exact zeros make the skimage comparison ill-posed")
                # 2. Topology and orientation of neus-aug's mesh.
                closed = rep["boundary_edges"] == 0 and rep["non_manifold_edges"] == 0 and rep["misoriented_edges"] == 0
                chk.check(closed, f"{name}/{n}: not a closed oriented manifold: {rep}")
                chk.check(rep["euler_characteristic"] == EULER[name], f"{name}/{n}: Euler characteristic {rep['euler_characteristic']}")
                chk.check(signed_volume(*ours) > 0, f"{name}/{n}: faces point inward")
                print(f"  {'neus-aug':<28} vertices {len(ours[0]):>7} faces {len(ours[1]):>7}  chi {rep['euler_characteristic']}")
                # 3. The peers.
                for label, mesh in peers(vol, lo, hi, n):
                    info = args.lewiner_info and "lewiner" in label
                    if info:
                        print(f"  {label:<28} vertices {len(mesh[0]):>7} faces {len(mesh[1]):>7}  (info)")
                    else:
                        chk.compare(label, ours, mesh, cell, counts_only="lewiner" in label)
            # 4. World mapping and two-pass, once per resolution on the torus (thin along z).
            name = "torus" if "torus" in args.shapes.split(",") else args.shapes.split(",")[0]
            ply = tmp / "w.ply"
            run_neus_aug(args.neus_aug, ["--sdf", name, "--res", str(n), "--out", str(ply), "--scale", str(scale), "--center", ",".join(map(str, center))])
            world, _ = read_ply(ply)
            run_neus_aug(args.neus_aug, ["--sdf", name, "--res", str(n), "--out", str(tmp / "m.ply")])
            norm, _ = read_ply(tmp / "m.ply")
            err = np.abs(world - (scale * norm + np.array(center))).max()
            print(f"{name} at {n}^3: world mapping max error {err:.2e} mm")
            chk.check(err < 1e-3, f"{name}/{n}: world mapping error {err} mm")

            rep = run_neus_aug(args.neus_aug, ["--sdf", name, "--res", str(n), "--two-pass", "--out", str(ply)])
            coarse_v, _ = mcubes.marching_cubes(grid_values(name, lo, hi, n), 0.0)
            coarse_v = to_box(coarse_v, lo, hi, n).astype(F)
            vmin, vmax = coarse_v.min(0), coarse_v.max(0)
            cellf = (F(1) - F(-1)) / F(n - 1)
            pad = np.maximum(F(0.1) * (vmax - vmin), cellf)
            expect = (np.maximum(vmin - pad, F(-1)), np.minimum(vmax + pad, F(1)))
            fine_lo, fine_hi = (np.array(b, dtype=F) for b in rep["fine_box"])
            dbox = max(np.abs(fine_lo - expect[0]).max(), np.abs(fine_hi - expect[1]).max())
            print(f"{name} at {n}^3 two-pass: refined box {fine_lo} .. {fine_hi} (|Δ| to this script's {dbox:.1e})")
            chk.check(dbox < 1e-5, f"{name}/{n}: refined box differs by {dbox}")
            fine_vol = grid_values(name, fine_lo, fine_hi, n)
            fv, ff = mcubes.marching_cubes(fine_vol, 0.0)
            fine_cell = float((fine_hi - fine_lo).min()) / (n - 1)
            chk.compare("two-pass vs PyMCubes", read_ply(ply), (to_box(fv, fine_lo, fine_hi, n), ff), fine_cell)

    if chk.failures:
        print(f"FAILED: {len(chk.failures)} disagreement(s)")
        for f in chk.failures:
            print(f"  {f}")
        sys.exit(1)
    print("OK: neus-aug matches PyMCubes and scikit-image")


if __name__ == "__main__":
    main()
