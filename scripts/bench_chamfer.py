#!/usr/bin/env python3
"""Times open3d and scipy on the point sets of dtu_eval's Rust benchmark, in the same run.

Run through `cargo bench -p dtu_eval --bench chamfer`, which writes the two sets (binary PLY) and
its own per-point distances, then calls

    bench_chamfer.py --a A.ply --b B.ply --rust-d-ab F --rust-d-ba F --rust-seconds S --reps N

For each peer: both directed distances (A->B and B->A), each the way a user would call it
(open3d: `compute_point_cloud_distance`, which builds its kd-tree inside; scipy: `cKDTree(b)`
then `query(a, workers=-1)`), best of N; the ratio peer / Rust; and the largest relative
difference between the peer's distances and Rust's (exit 1 above 1e-6).
"""

import _pyenv

_pyenv.ensure({"numpy": "numpy", "scipy": "scipy", "open3d": "open3d-cpu"})
_pyenv.ensure_libusb()

import argparse  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import open3d as o3d  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

RTOL = 1e-6


def max_rel(x, ref):
    ref = np.asarray(ref)
    err = np.abs(np.asarray(x) - ref)
    nz = ref > 1e-9
    if np.any(~nz & (err > 1e-9)):
        return float("inf")
    return float((err[nz] / ref[nz]).max())


def o3d_both(a, b):
    pa = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(a))
    pb = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(b))
    t, c = time.perf_counter(), time.process_time()
    d_ab = np.asarray(pa.compute_point_cloud_distance(pb))
    d_ba = np.asarray(pb.compute_point_cloud_distance(pa))
    return time.perf_counter() - t, time.process_time() - c, d_ab, d_ba


def scipy_both(a, b):
    t, c = time.perf_counter(), time.process_time()
    d_ab, _ = cKDTree(b).query(a, workers=-1)
    d_ba, _ = cKDTree(a).query(b, workers=-1)
    return time.perf_counter() - t, time.process_time() - c, d_ab, d_ba


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--a", required=True)
    ap.add_argument("--b", required=True)
    ap.add_argument("--rust-d-ab", required=True, help="raw little-endian float64 distances A->B")
    ap.add_argument("--rust-d-ba", required=True)
    ap.add_argument("--rust-seconds", type=float, required=True, help="best wall time, both directions")
    ap.add_argument("--rust-cpu", type=float, default=float("nan"), help="best CPU time (all threads)")
    ap.add_argument("--reps", type=int, default=3)
    args = ap.parse_args()
    a = np.asarray(o3d.io.read_point_cloud(args.a).points)
    b = np.asarray(o3d.io.read_point_cloud(args.b).points)
    r_ab = np.fromfile(args.rust_d_ab, dtype="<f8")
    r_ba = np.fromfile(args.rust_d_ba, dtype="<f8")
    print(f"  python peers on {len(a)} x {len(b)} points, {os.cpu_count()} CPUs, "
          f"open3d {o3d.__version__}, numpy {np.__version__}")
    bad = False
    for name, fn in [("open3d compute_point_cloud_distance", o3d_both), ("scipy cKDTree", scipy_both)]:
        times, cpus = [], []
        for rep in range(args.reps):
            secs, cpu, d_ab, d_ba = fn(a, b)
            times.append(secs)
            cpus.append(cpu)
            print(f"  {name} rep {rep}: {secs:.3f} s wall, {cpu:.2f} s CPU (both directions)")
        err = max(max_rel(d_ab, r_ab), max_rel(d_ba, r_ba))
        ok = err <= RTOL
        bad |= not ok
        best, best_cpu = min(times), min(cpus)
        print(f"  {name}: best {best:.3f} s wall vs Rust {args.rust_seconds:.3f} s: "
              f"ratio {best / args.rust_seconds:.1f}x (CPU time {best_cpu:.2f} s vs {args.rust_cpu:.2f} s: "
              f"{best_cpu / args.rust_cpu:.1f}x); max rel diff vs Rust {err:.1e} "
              f"[{'same numbers' if ok else 'DIFFERENT'}]")
        print(f"    means: A->B {d_ab.mean():.9f}, B->A {d_ba.mean():.9f}")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
