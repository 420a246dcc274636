#!/usr/bin/env python3
"""Cross-check `dtu-eval` against the tools the field trusts.

Two modes, each running `dtu-eval` itself (with --json and --dump-dir) and exiting 1 on any
disagreement:

  distances --dtu-eval BIN --work DIR [--a A.ply --b B.ply | --n N --seed S]
      Plain mode on two point sets: the directed nearest-neighbour distances A->B and B->A,
      point by point, from open3d (`compute_point_cloud_distance`), trimesh (`PointCloud.kdtree`,
      which is a scipy cKDTree underneath), pymeshlab (`compute_scalar_by_distance_from_another_
      mesh_per_vertex`, float32 inside) and scipy's cKDTree; each must agree with dtu-eval to
      1e-6 relative.

  protocol --dtu-eval BIN --work DIR --mesh M.ply --scan N --gt-root G [--seed S]
      The DTU protocol re-implemented here in numpy/scipy from its description (DESIGN.md §4,
      jzhangbs/DTUeval-python): surface sampling (compared with dtu-eval's samples as a
      multiset, exactly), greedy radius downsampling of dtu-eval's shuffled samples (same kept
      points, same order), box and ObsMask filter, plane filter, distances and means, reading the
      ground truth with scipy.io.loadmat and open3d. Counts must match exactly, per-point
      distances to 1e-6 relative, the final means to 1e-4 relative.
"""

import _pyenv

_pyenv.ensure(
    {
        "numpy": "numpy",
        "scipy": "scipy",
        "trimesh": "trimesh",
        "pymeshlab": "pymeshlab",
        "open3d": "open3d-cpu",
    }
)
_pyenv.ensure_libusb()

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import open3d as o3d  # noqa: E402
import pymeshlab  # noqa: E402
import trimesh  # noqa: E402
from scipy.io import loadmat  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

POINT_RTOL = 1e-6
MEAN_RTOL_PROTOCOL = 1e-4
ZERO_ATOL = 1e-9  # mm; for distances that are exactly zero (duplicate points)

failures: list[str] = []


def check(ok: bool, what: str) -> None:
    print(f"  [{'ok' if ok else 'FAIL'}] {what}")
    if not ok:
        failures.append(what)


def max_rel_err(x: np.ndarray, ref: np.ndarray) -> float:
    x = np.asarray(x, dtype=np.float64).ravel()
    ref = np.asarray(ref, dtype=np.float64).ravel()
    if x.shape != ref.shape:
        return float("inf")
    err = np.abs(x - ref)
    zero = ref <= ZERO_ATOL
    if np.any(zero & (err > ZERO_ATOL)):
        return float("inf")
    rel = err[~zero] / ref[~zero]
    return float(rel.max()) if rel.size else 0.0


def run_dtu_eval(binary: str, args: list[str]) -> dict:
    cmd = [binary, *args]
    print("$ " + " ".join(cmd))
    t = time.perf_counter()
    res = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t
    sys.stdout.write(res.stdout)
    if res.returncode != 0:
        sys.stderr.write(res.stderr)
        sys.exit(f"dtu-eval failed with status {res.returncode}")
    print(f"  (dtu-eval wall time {wall:.3f} s, including start-up and file I/O)")
    return json.loads(Path(args[args.index("--json") + 1]).read_text())


def read_points_o3d(path: Path) -> np.ndarray:
    pts = np.asarray(o3d.io.read_point_cloud(str(path)).points)
    if pts.size == 0:
        sys.exit(f"open3d read no points from {path}")
    return pts


# ---- distances --------------------------------------------------------------------------------


def directed_distances(a: np.ndarray, b: np.ndarray) -> dict[str, tuple[np.ndarray, float]]:
    """Distance from each point of `a` to its nearest point of `b`, per back end, with times."""
    out = {}
    t = time.perf_counter()
    pa = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(a))
    pb = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(b))
    d = np.asarray(pa.compute_point_cloud_distance(pb))
    out["open3d"] = (d, time.perf_counter() - t)
    t = time.perf_counter()
    d, _ = trimesh.PointCloud(b).kdtree.query(a)
    out["trimesh"] = (d, time.perf_counter() - t)
    t = time.perf_counter()
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=a), "a")
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=b), "b")
    ms.compute_scalar_by_distance_from_another_mesh_per_vertex(
        measuremesh=0, refmesh=1, signeddist=False
    )
    out["pymeshlab"] = (ms.mesh(0).vertex_scalar_array().copy(), time.perf_counter() - t)
    t = time.perf_counter()
    d, _ = cKDTree(b).query(a, workers=-1)
    out["scipy"] = (d, time.perf_counter() - t)
    return out


def make_point_sets(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Two float32 sets at DTU magnitudes: clustered, overlapping, with exact duplicates."""
    rng = np.random.default_rng(seed)
    centre = np.array([-30.0, 40.0, 620.0])
    a = centre + rng.normal(scale=25.0, size=(n, 3))
    b = centre + rng.normal(scale=25.0, size=(n, 3)) + 0.3
    b[: n // 50] = a[: n // 50]  # shared points: zero distances
    a[n // 2 : n // 2 + n // 100] = a[: n // 100]  # duplicates within a set
    return a.astype(np.float32), b.astype(np.float32)


def write_ply(path: Path, pts: np.ndarray) -> None:
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts.astype(np.float64)))
    if not o3d.io.write_point_cloud(str(path), pc, write_ascii=False):
        sys.exit(f"cannot write {path}")


def mode_distances(args) -> None:
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    if args.a and args.b:
        pa, pb = Path(args.a), Path(args.b)
    else:
        a32, b32 = make_point_sets(args.n, args.seed)
        pa, pb = work / "a.ply", work / "b.ply"
        write_ply(pa, a32)
        write_ply(pb, b32)
    dump = work / "dump_distances"
    report = run_dtu_eval(
        args.dtu_eval,
        ["--mesh", str(pa), "--ref", str(pb), "--json", str(work / "distances.json"),
         "--dump-dir", str(dump)],
    )
    a = np.load(dump / "data.npy").astype(np.float64)
    b = np.load(dump / "ref.npy").astype(np.float64)
    check(np.array_equal(a, read_points_o3d(pa)), f"dtu-eval used the points of {pa.name} as open3d reads them")
    check(np.array_equal(b, read_points_o3d(pb)), f"dtu-eval used the points of {pb.name} as open3d reads them")
    rust = {"A->B (d2s)": np.load(dump / "d2s.npy"), "B->A (s2d)": np.load(dump / "s2d.npy")}
    print(f"points: A {len(a)}, B {len(b)}")
    for (label, src, dst), key in zip(
        [("A->B (d2s)", a, b), ("B->A (s2d)", b, a)], ["mean_d2s", "mean_s2d"]
    ):
        peers = directed_distances(src, dst)
        for name, (d, secs) in peers.items():
            err = max_rel_err(d, rust[label])
            check(err <= POINT_RTOL, f"{label}: {name:9s} max rel err {err:.2e} ({secs:.3f} s)")
        mean_ref = float(np.mean(peers["scipy"][0]))
        err = abs(report[key] - mean_ref) / mean_ref
        check(err <= POINT_RTOL, f"{label}: mean {report[key]:.9f} vs scipy {mean_ref:.9f} (rel {err:.1e})")


# ---- protocol ---------------------------------------------------------------------------------


def sample_mesh(vertices: np.ndarray, faces: np.ndarray, density: float) -> np.ndarray:
    """DTU's MeshSupSamp rule, vectorised over triangles with equal grid sizes. float64."""
    q = vertices[faces]
    q0 = q[:, 0]
    v1 = q[:, 1] - q0
    v2 = q[:, 2] - q0
    l1 = np.linalg.norm(v1, axis=-1)
    l2 = np.linalg.norm(v2, axis=-1)
    a2 = np.linalg.norm(np.cross(v1, v2), axis=-1)
    ok = a2 > 0
    q0, v1, v2, l1, l2, a2 = q0[ok], v1[ok], v2[ok], l1[ok], l2[ok], a2[ok]
    thr = density * np.sqrt(l1 * l2 / a2)
    n1 = np.floor(l1 / thr)
    n2 = np.floor(l2 / thr)
    parts = [vertices]
    keys = np.stack([n1, n2], axis=1)
    for g1, g2 in np.unique(keys, axis=0):
        if g1 < 1 or g2 < 1:
            continue  # the grid coordinate divides by ~0: no sample passes k1 + k2 < 1
        c1, c2 = np.meshgrid(np.arange(g1 + 1), np.arange(g2 + 1), indexing="ij")
        k1 = (c1.ravel() + 0.5) / g1
        k2 = (c2.ravel() + 0.5) / g2
        keep = k1 + k2 < 1
        k1, k2 = k1[keep], k2[keep]
        sel = (n1 == g1) & (n2 == g2)
        pts = (v1[sel, None, :] * k1[None, :, None] + v2[sel, None, :] * k2[None, :, None]) + q0[sel, None, :]
        parts.append(pts.reshape(-1, 3))
    return np.concatenate(parts, axis=0)


def sort_rows(p: np.ndarray) -> np.ndarray:
    return p[np.lexsort((p[:, 2], p[:, 1], p[:, 0]))]


def greedy_downsample(points: np.ndarray, radius: float) -> np.ndarray:
    """Keep mask: in order, a point still kept removes every other point within `radius`."""
    tree = cKDTree(points)
    neighbours = tree.query_ball_point(points, r=radius, workers=-1)
    keep = np.ones(len(points), dtype=bool)
    for i, nb in enumerate(neighbours):
        if keep[i]:
            keep[nb] = False
            keep[i] = True
    return keep


def mode_protocol(args) -> None:
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    dump = work / "dump_protocol"
    report = run_dtu_eval(
        args.dtu_eval,
        ["--mesh", args.mesh, "--scan", str(args.scan), "--gt-root", args.gt_root,
         "--json", str(work / "protocol.json"), "--dump-dir", str(dump), "--seed", str(args.seed)],
    )
    p = report["params"]
    c = report["counts"]
    density, patch, max_dist = p["density"], p["patch_size"], p["max_dist"]

    # 1. Sampling, from the mesh file, compared as a multiset with dtu-eval's (shuffled) samples.
    mesh = trimesh.load(args.mesh, process=False)
    ours = sample_mesh(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces), density)
    samples = np.load(dump / "samples.npy")
    check(len(ours) == c["sampled"] == len(samples), f"sample count {len(ours)} = dtu-eval {c['sampled']}")
    same = len(ours) == len(samples) and np.array_equal(sort_rows(ours.astype(np.float32)), sort_rows(samples))
    check(same, "surface samples identical (as float32 multisets)")

    # 2. Downsampling of dtu-eval's shuffled samples (the shuffle is dtu-eval's seeded one).
    t = time.perf_counter()
    keep = greedy_downsample(samples.astype(np.float64), density)
    data_down = samples[keep].astype(np.float64)
    print(f"  (python downsampling {time.perf_counter() - t:.2f} s)")
    check(len(data_down) == c["downsampled"], f"downsampled {len(data_down)} = dtu-eval {c['downsampled']}")
    rust_down = np.load(dump / "data_down.npy")
    check(
        rust_down.shape == data_down.shape and np.array_equal(rust_down.astype(np.float64), data_down),
        "downsampled points identical, same order",
    )

    # 3. Observation mask, read with scipy from the files dtu_eval::gt wrote.
    gt = Path(args.gt_root)
    m = loadmat(gt / "ObsMask" / f"ObsMask{args.scan}_10.mat")
    obs, bb, res = m["ObsMask"], m["BB"], m["Res"]
    check(obs.ndim == 3 and bb.shape == (2, 3) and res.size == 1,
          f"loadmat ObsMask: ObsMask {obs.shape} {obs.dtype}, BB {bb.shape} {bb.dtype}, Res {res.shape}")
    bb = bb.astype(np.float32)
    lo = bb[:1] - np.float32(patch)
    hi = bb[1:] + np.float32(2 * patch)
    in_box = np.all((data_down >= lo) & (data_down < hi), axis=1)
    data_in = data_down[in_box]
    idx = np.around((data_in - bb[:1]) / res).astype(np.int64)
    in_grid = np.all((idx >= 0) & (idx < np.array(obs.shape)), axis=1)
    observed = np.zeros(len(data_in), dtype=bool)
    g = idx[in_grid]
    observed[in_grid] = obs[g[:, 0], g[:, 1], g[:, 2]].astype(bool)
    data_in_obs = data_in[observed]
    check(len(data_in) == c["in_box"], f"in box {len(data_in)} = dtu-eval {c['in_box']}")
    check(len(data_in_obs) == c["in_obs"], f"observed {len(data_in_obs)} = dtu-eval {c['in_obs']}")

    # 4.-5. Distances, GT read with open3d, plane with scipy.
    stl = read_points_o3d(gt / "Points" / "stl" / f"stl{args.scan:03}_total.ply")
    plane = loadmat(gt / "ObsMask" / f"Plane{args.scan}.mat")["P"]
    check(plane.size == 4, f"loadmat Plane: P {plane.shape} {plane.dtype}")
    stl_hom = np.concatenate([stl, np.ones((len(stl), 1))], axis=1)
    above = (stl_hom * plane.reshape(1, 4)).sum(axis=1) > 0  # [x, y, z, 1]·P > 0
    stl_above = stl[above]
    check(len(stl) == c["gt_points"], f"GT points {len(stl)} = dtu-eval {c['gt_points']}")
    check(len(stl_above) == c["gt_above_plane"], f"GT above plane {len(stl_above)} = dtu-eval {c['gt_above_plane']}")
    d2s, _ = cKDTree(stl).query(data_in_obs, workers=-1)
    s2d, _ = cKDTree(data_in).query(stl_above, workers=-1)
    err = max_rel_err(d2s, np.load(dump / "d2s.npy"))
    check(err <= POINT_RTOL, f"d2s per point: max rel err {err:.2e}")
    err = max_rel_err(s2d, np.load(dump / "s2d.npy"))
    check(err <= POINT_RTOL, f"s2d per point: max rel err {err:.2e}")

    # 6. Means with the strict outlier cut.
    acc = d2s[d2s < max_dist].mean()
    comp = s2d[s2d < max_dist].mean()
    check(int((d2s < max_dist).sum()) == c["d2s_below_max"], "d2s count below max_dist")
    check(int((s2d < max_dist).sum()) == c["s2d_below_max"], "s2d count below max_dist")
    for name, ours_v, theirs in [
        ("mean_d2s (accuracy)", acc, report["mean_d2s"]),
        ("mean_s2d (completeness)", comp, report["mean_s2d"]),
        ("overall (acc+comp)/2", (acc + comp) / 2, report["overall"]),
        ("chamfer_sum acc+comp", acc + comp, report["chamfer_sum"]),
    ]:
        rel = abs(ours_v - theirs) / abs(ours_v)
        check(rel <= MEAN_RTOL_PROTOCOL, f"{name}: python {ours_v:.9f} vs dtu-eval {theirs:.9f} (rel {rel:.1e})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="mode", required=True)
    d = sub.add_parser("distances")
    d.add_argument("--dtu-eval", required=True)
    d.add_argument("--work", required=True)
    d.add_argument("--a")
    d.add_argument("--b")
    d.add_argument("--n", type=int, default=20000)
    d.add_argument("--seed", type=int, default=0)
    p = sub.add_parser("protocol")
    p.add_argument("--dtu-eval", required=True)
    p.add_argument("--work", required=True)
    p.add_argument("--mesh", required=True)
    p.add_argument("--scan", type=int, required=True)
    p.add_argument("--gt-root", required=True)
    p.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    print(f"open3d {o3d.__version__}, trimesh {trimesh.__version__}, numpy {np.__version__}")
    if args.mode == "distances":
        mode_distances(args)
    else:
        mode_protocol(args)
    if failures:
        print(f"{len(failures)} check(s) FAILED:\n  " + "\n  ".join(failures))
        sys.exit(1)
    print("all checks passed")


if __name__ == "__main__":
    main()
