#!/usr/bin/env python3
"""The normal error a surface smooth at a scale r would score against a scene's true mesh.

The held-out normal error of a run (`normal_error_deg` in metrics.json,
src/reconstruct/normal_error.rs) compares the rendered normal, the direction of the field's
SDF gradient, with the face normal of the true mesh where the pixel's ray hits it. A field
that is exact down to a scale r but smooth below it still misses the normal variation the
true mesh has below r (a scan's fine relief, a faceted model's edges). This script measures
that share: points sampled uniformly by area on `gt_mesh.ply` (world mm), each point's face
normal against the mean of the face normals of the samples within r of it (the surface
smoothed over a ball of radius r), as a mean angle in degrees per r. It also prints the
scene's scale (mm per normalised unit, from `cameras_sphere.npz`) and the footprint of a
training pixel at the mean camera distance, the two resolutions a run has to work with.

    python3 scripts/normal_floor.py SCENE|MESH [...] [--radii 0.25,0.5,1,2] [--samples N]

A SCENE is a folder `neus-aug synth` wrote (its `gt_mesh.ply` and cameras); a MESH is a .ply
or .obj file in mm, for which the scale and pixel columns are left empty.

The mean is over the whole surface, not over the pixels a held-out view sees; it is a
floor's estimate, not the metric.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _pyenv  # noqa: E402

_pyenv.ensure({"numpy": "numpy", "scipy": "scipy", "trimesh": "trimesh"})

import numpy as np  # noqa: E402
import trimesh  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402


def smoothed_angles(points, normals, radius, queries):
    """Mean angle (degrees) between each query sample's normal and the mean normal of the
    samples within `radius` of it."""
    tree = cKDTree(points)
    out = []
    for i in queries:
        idx = tree.query_ball_point(points[i], radius)
        m = normals[idx].sum(axis=0)
        n = np.linalg.norm(m)
        if n == 0:
            continue
        c = float(np.clip(np.dot(normals[i], m / n), -1.0, 1.0))
        out.append(np.degrees(np.arccos(c)))
    return float(np.mean(out)) if out else float("nan")


def scene_scale(scene: Path):
    """(mm per normalised unit, mean camera distance in mm, focal in px) of a DTU-layout scene."""
    cams = np.load(scene / "cameras_sphere.npz")
    s = float(cams["scale_mat_0"][0, 0])
    centre = cams["scale_mat_0"][:3, 3]
    dists, focals = [], []
    i = 0
    while f"world_mat_{i}" in cams:
        p = cams[f"world_mat_{i}"][:3, :4]
        # The camera centre is the null vector of P; the focal is K's first diagonal entry.
        c = -np.linalg.solve(p[:, :3], p[:, 3])
        dists.append(np.linalg.norm(c - centre))
        k = np.linalg.qr(np.linalg.inv(p[:, :3]))[1]
        focals.append(abs(1.0 / k[0, 0]))
        i += 1
    return s, float(np.mean(dists)), float(np.median(focals))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+", type=Path)
    ap.add_argument("--radii", default="0.25,0.5,1,2", help="smoothing radii, mm")
    ap.add_argument("--samples", type=int, default=400_000)
    ap.add_argument("--queries", type=int, default=20_000)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    radii = [float(r) for r in a.radii.split(",")]
    print("| scene | mm / unit | pixel (mm) | " + " | ".join(f"r = {r} mm" for r in radii) + " |")
    print("|---|---:|---:|" + "---:|" * len(radii))
    for scene in a.scenes:
        gt = scene if scene.is_file() else scene / "gt_mesh.ply"
        if not gt.is_file():
            print(f"error: {gt} not found (a scene `neus-aug synth` wrote, or a mesh file)",
                  file=sys.stderr)
            return 2
        mesh = trimesh.load(gt, force="mesh", process=False)
        if len(mesh.faces) == 0:
            print(f"error: {gt} has no faces", file=sys.stderr)
            return 2
        rng = np.random.default_rng(a.seed)
        pts, face = trimesh.sample.sample_surface(mesh, a.samples, seed=a.seed)
        nrm = mesh.face_normals[face]
        ok = np.isfinite(nrm).all(axis=1) & (np.linalg.norm(nrm, axis=1) > 0.5)
        pts, nrm = pts[ok], nrm[ok]
        q = rng.choice(len(pts), size=min(a.queries, len(pts)), replace=False)
        if scene.is_file():
            scale_col, pix_col = "", ""
        else:
            scale, dist, focal = scene_scale(scene)
            # A training pixel's footprint at the mean camera distance.
            scale_col, pix_col = f"{scale:.1f}", f"{dist / focal:.2f}"
        cols = [smoothed_angles(pts, nrm, r, q) for r in radii]
        print(f"| {scene.name} | {scale_col} | {pix_col} | "
              + " | ".join(f"{c:.1f}°" for c in cols) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
