#!/usr/bin/env python3
"""Check a synthetic scene's ground truth with the tools DTU's evaluation uses: scipy.io.loadmat
for ObsMask{scan}_10.mat and Plane{scan}.mat, numpy for Points/stl/stl{scan:03}_total.ply.

The reference values come from the scene's meta.json (written by `neus-aug synth`): the grid
shape, BB, Res, the count of observed voxels, the plane, the number of points and the sum of
their coordinates. On top of the values, the script checks what jzhangbs/DTUeval-python
`eval.py` relies on, with its own indexing code: every ground-truth point falls inside the
ObsMask grid at an observed voxel (`np.around((p - BB[:1]) / Res)` on float32 BB), lies above the
plane (`[x, y, z, 1] @ P > 0`), and inside BB. Exits non-zero on any disagreement.

usage: check_gt_mat.py --scene DIR
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _pyenv  # noqa: E402

_pyenv.ensure({"numpy": "numpy", "scipy": "scipy"})

import argparse  # noqa: E402
import json  # noqa: E402

import numpy as np  # noqa: E402
from scipy.io import loadmat  # noqa: E402

PLY_TYPES = {"float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8",
             "uchar": "u1", "uint8": "u1", "int": "<i4", "uint": "<u4"}


def read_ply_points(path: Path) -> np.ndarray:
    """xyz of a binary little-endian PLY's vertex element (faces, if any, are not read)."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    if "format binary_little_endian 1.0" not in header:
        raise SystemExit(f"{path}: not a binary little-endian PLY")
    count, props, in_vertex = None, [], False
    for line in header:
        parts = line.split()
        if parts[:2] == ["element", "vertex"]:
            count, in_vertex = int(parts[2]), True
        elif parts and parts[0] == "element":
            in_vertex = False
        elif in_vertex and parts[0] == "property":
            props.append((parts[2], PLY_TYPES[parts[1]]))
    vertices = np.frombuffer(data, dtype=np.dtype(props), count=count, offset=end)
    return np.stack([vertices["x"], vertices["y"], vertices["z"]], axis=1)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", required=True, type=Path)
    args = ap.parse_args()
    meta = json.loads((args.scene / "meta.json").read_text())
    gt = meta["gt"]
    errors = []

    def expect(ok, what):
        if not ok:
            errors.append(what)

    m = loadmat(args.scene / gt["obs_mask_file"])
    obs, bb, res = m["ObsMask"], m["BB"], m["Res"]
    expect(obs.ndim == 3, f"ObsMask has {obs.ndim} dimensions, not 3")
    expect(list(obs.shape) == gt["dims"], f"ObsMask shape {obs.shape} != {gt['dims']}")
    expect(obs.dtype in (np.bool_, np.uint8), f"ObsMask dtype {obs.dtype}")
    expect(set(np.unique(obs).tolist()) <= {0, 1}, "ObsMask has values other than 0/1")
    expect(int(obs.astype(bool).sum()) == gt["obs_voxels"],
           f"ObsMask has {int(obs.astype(bool).sum())} observed voxels, meta says {gt['obs_voxels']}")
    expect(bb.shape == (2, 3), f"BB shape {bb.shape}")
    expect(np.array_equal(bb, np.array(gt["bb"])), f"BB {bb.tolist()} != {gt['bb']}")
    expect(res.shape == (1, 1) and float(res[0, 0]) == gt["res"], f"Res {res} != {gt['res']}")
    extent = bb[1] - bb[0]
    expect(np.allclose(extent, (np.array(obs.shape) - 1) * float(res[0, 0])),
           f"BB extent {extent} does not match the grid {obs.shape} x Res")

    p = loadmat(args.scene / gt["plane_file"])["P"]
    expect(p.shape == (4, 1), f"P shape {p.shape}")
    expect(np.array_equal(p.ravel(), np.array(gt["plane"])), f"P {p.ravel()} != {gt['plane']}")

    pts = read_ply_points(args.scene / gt["points_file"])
    expect(pts.dtype == np.float32, f"points dtype {pts.dtype}")
    expect(len(pts) == gt["points"], f"{len(pts)} points, meta says {gt['points']}")
    sums = pts.astype(np.float64).sum(axis=0)
    expect(np.allclose(sums, gt["points_sum"], rtol=1e-12, atol=1e-6),
           f"coordinate sums {sums} != {gt['points_sum']}")

    # eval.py's own indexing and filters.
    bb32 = bb.astype(np.float32)
    grid = np.around((pts - bb32[:1]) / res).astype(np.int32)
    inside = ((grid >= 0) & (grid < np.expand_dims(obs.shape, 0))).sum(axis=-1) == 3
    expect(inside.all(), f"{(~inside).sum()} GT points fall outside the ObsMask grid")
    g = grid[inside]
    observed = obs[g[:, 0], g[:, 1], g[:, 2]].astype(bool)
    expect(observed.all(), f"{(~observed).sum()} GT points fall in unobserved voxels")
    above = np.concatenate([pts, np.ones((len(pts), 1), np.float32)], axis=1) @ p > 0
    expect(above.all(), f"{(~above).sum()} GT points lie below the plane")
    in_bb = ((pts >= bb32[0]) & (pts <= bb32[1])).all(axis=1)
    expect(in_bb.all(), f"{(~in_bb).sum()} GT points lie outside BB")

    if errors:
        for e in errors:
            print("MISMATCH:", e, file=sys.stderr)
        return 1
    print(f"OK: scipy.io.loadmat reads ObsMask {obs.shape} (Res {float(res[0, 0])}, "
          f"{gt['obs_voxels']} observed) and Plane; {len(pts)} GT points match meta.json, "
          f"all observed and above the plane")
    return 0


if __name__ == "__main__":
    sys.exit(main())
