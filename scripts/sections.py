#!/usr/bin/env python3
"""Where a reconstruction goes wrong: cross-sections over the truth, and where its handles sit.

    python3 scripts/sections.py RUN_DIR [--truth SCENE_DIR/gt_mesh.ply] [--out sections.png]

RUN_DIR is a finished `neus-aug reconstruct` folder; the closed surface (`mesh_closed.ply`, or
`mesh.ply` when there is none) is drawn in red over the scene's true mesh (`gt_mesh.ply` of the
scene named in RUN_DIR/config.toml, or --truth) in four planes through the truth's centre: two
across its main axis (at the centre and 30 % of the way to its end) and two along it. The main
axis is the principal axis of the true vertices whose variance differs most from the other two
(a cylinder's axis, a statue's height).

It prints the closed surface's genus and components beside the truth's.
"""

import _pyenv

_pyenv.ensure({"numpy": "numpy", "scipy": "scipy", "trimesh": "trimesh", "PIL": "pillow"})

import argparse  # noqa: E402
import sys  # noqa: E402
import tomllib  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import trimesh  # noqa: E402
from PIL import Image, ImageDraw  # noqa: E402

PANEL = 420  # pixels per panel


def main_axis(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centre and a right-handed frame (axis, e1, e2) of the true vertices."""
    c = vertices.mean(0)
    w, u = np.linalg.eigh(np.cov((vertices - c).T))
    i = int(np.argmax([abs(w[k] - np.mean(np.delete(w, k))) for k in range(3)]))
    ax = u[:, i]
    e1 = u[:, (i + 1) % 3]
    return c, np.stack([ax, e1, np.cross(ax, e1)])


def draw(img, x0, mesh, normal, origin, basis, centre, extent, colour):
    d = ImageDraw.Draw(img)
    for seg in trimesh.intersections.mesh_plane(mesh, normal, origin):
        p = (seg - centre) @ basis.T
        q = [(x0 + PANEL / 2 + x / extent * PANEL / 2, 20 + PANEL / 2 - y / extent * PANEL / 2) for x, y in p]
        d.line(q, fill=colour, width=1)


def truth_of(run: Path) -> Path:
    cfg = tomllib.loads((run / "config.toml").read_text())
    scene = Path(str(cfg.get("scene", "")))
    if not (scene / "gt_mesh.ply").is_file():
        sys.exit(f"no gt_mesh.ply in the run's scene '{scene}': give --truth")
    return scene / "gt_mesh.ply"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path, help="a finished reconstruct folder")
    ap.add_argument("--truth", type=Path, help="the true mesh (default: the run's scene's gt_mesh.ply)")
    ap.add_argument("--out", type=Path, help="the PNG (default: RUN/sections.png)")
    a = ap.parse_args()
    mesh_path = a.run / "mesh_closed.ply"
    if not mesh_path.is_file():
        mesh_path = a.run / "mesh.ply"
    if not mesh_path.is_file():
        sys.exit(f"{a.run}: no mesh_closed.ply or mesh.ply (is it a finished reconstruct folder?)")
    truth = a.truth or truth_of(a.run)
    recon = trimesh.load(mesh_path, process=False)
    gt = trimesh.load(truth, process=False)
    if len(recon.faces) == 0 or len(gt.faces) == 0:
        sys.exit("an empty mesh has no sections")
    centre, (ax, e1, e2) = main_axis(gt.vertices)
    extent = np.abs(gt.vertices - centre).max() * 1.15
    reach = np.abs((gt.vertices - centre) @ ax).max()
    planes = [
        ("across the axis, centre", ax, centre, np.stack([e1, e2])),
        ("across the axis, 30 % out", ax, centre + 0.3 * reach * ax, np.stack([e1, e2])),
        ("along the axis", e2, centre, np.stack([e1, ax])),
        ("along the axis, turned 90°", e1, centre, np.stack([e2, ax])),
    ]
    img = Image.new("RGB", (PANEL * len(planes), PANEL + 20), "white")
    for k, (name, n, o, basis) in enumerate(planes):
        draw(img, k * PANEL, gt, n, o, basis, centre, extent, (0, 0, 0))
        draw(img, k * PANEL, recon, n, o, basis, centre, extent, (220, 0, 0))
        ImageDraw.Draw(img).text((k * PANEL + 5, 3), name, fill=(0, 0, 0))
    out = a.out or a.run / "sections.png"
    img.save(out)
    def genus(m):
        # Euler characteristic of a closed surface: chi = 2c - 2g.
        edges = np.unique(np.sort(m.edges, axis=1), axis=0)
        comps = len(trimesh.graph.connected_components(edges, nodes=np.unique(m.faces)))
        chi = len(np.unique(m.faces)) - len(edges) + len(m.faces)
        return (2 * comps - chi) // 2, comps

    (g, c), (gt_g, gt_c) = genus(recon), genus(gt)
    print(f"{mesh_path}: genus {g}, {c} component(s); the truth {truth}: genus {gt_g}, {gt_c}")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
