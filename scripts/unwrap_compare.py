#!/usr/bin/env python3
"""xatlas (the C++ library nerfstudio's `exporter/texture_utils.py` unwraps with, through its
PyPI binding) on a mesh, with the figures `neus-aug export` prints for its own unwrap
(uvunwrap): time, charts, seam vertices (output / input vertices), atlas utilisation (share of
the atlas texels that chart triangles cover, rasterised here at the atlas size).

    python3 scripts/unwrap_compare.py RUN/mesh.ply [--size 1024] [--padding 2]
    python3 scripts/unwrap_compare.py --obj RUN/export/mesh_textured.obj x --size 1024
"""

import _pyenv

_pyenv.ensure({"numpy": "numpy", "trimesh": "trimesh", "xatlas": "xatlas"})

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import trimesh  # noqa: E402
import xatlas  # noqa: E402


def coverage(uv: np.ndarray, faces: np.ndarray, w: int, h: int) -> float:
    """Share of the w x h texels whose centre lies in some UV triangle (uv in [0, 1])."""
    covered = np.zeros((h, w), dtype=bool)
    p = uv[faces] * np.array([w, h])  # [F, 3, 2] texel units
    for tri in p:
        lo = np.floor(tri.min(axis=0)).astype(int)
        hi = np.ceil(tri.max(axis=0)).astype(int)
        lo = np.clip(lo, 0, [w - 1, h - 1])
        hi = np.clip(hi, 0, [w, h])
        xs, ys = np.meshgrid(np.arange(lo[0], hi[0]) + 0.5, np.arange(lo[1], hi[1]) + 0.5)
        a, b, c = tri
        d = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        if d == 0:
            continue
        w0 = ((b[0] - xs) * (c[1] - ys) - (b[1] - ys) * (c[0] - xs)) / d
        w1 = ((c[0] - xs) * (a[1] - ys) - (c[1] - ys) * (a[0] - xs)) / d
        inside = (w0 >= 0) & (w1 >= 0) & (1 - w0 - w1 >= 0)
        covered[lo[1] : hi[1], lo[0] : hi[0]] |= inside
    return float(covered.mean())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("mesh")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--padding", type=int, default=2)
    ap.add_argument("--no-coverage", action="store_true")
    ap.add_argument("--obj", help="only measure the texel coverage of this OBJ's UVs (e.g. "
                    "RUN/export/mesh_textured.obj) at --size")
    a = ap.parse_args()
    if a.obj:
        o = trimesh.load(a.obj, process=False, maintain_order=True)
        if isinstance(o, trimesh.Scene):
            o = o.dump(concatenate=True)
        uv = np.asarray(o.visual.uv, dtype=np.float64)
        print(f"texel coverage of {a.obj} at {a.size}x{a.size}: "
              f"{coverage(uv, np.asarray(o.faces), a.size, a.size):.3f}")
        return
    m = trimesh.load(a.mesh, process=False)
    v = np.asarray(m.vertices, dtype=np.float32)
    f = np.asarray(m.faces, dtype=np.uint32)
    atlas = xatlas.Atlas()
    atlas.add_mesh(v, f)
    pack = xatlas.PackOptions()
    pack.resolution = a.size
    pack.padding = a.padding
    t0 = time.perf_counter()
    atlas.generate(xatlas.ChartOptions(), pack)
    dt = time.perf_counter() - t0
    vmap, idx, uv = atlas[0]
    print(
        f"xatlas {xatlas.__version__ if hasattr(xatlas, '__version__') else ''}: faces {len(f)} "
        f"verts_in {len(v)} verts_out {len(vmap)} ({len(vmap) / len(v):.3f}x) charts "
        f"{atlas.chart_count} atlas {atlas.width}x{atlas.height} utilisation "
        f"{atlas.get_utilization(0):.3f} time {dt:.2f} s"
    )
    if not a.no_coverage:
        print(f"texel coverage at {atlas.width}x{atlas.height}: {coverage(uv, idx, atlas.width, atlas.height):.3f}")


if __name__ == "__main__":
    main()
