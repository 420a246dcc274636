#!/usr/bin/env python3
"""Cross-check `neus-aug export`'s files with the tools people open them in.

    python3 scripts/crosscheck_export.py DIR

DIR holds mesh.ply, mesh_textured.{obj,mtl,png,glb} and export.json (as `neus-aug export`
writes them). Checks, each with trimesh and with Open3D:

  mesh.ply            vertex and face counts as export.json says, unit vertex normals, vertex
                      colours present and not constant;
  mesh_textured.obj   the same geometry (positions to float precision), texture coordinates in
                      [0, 1], the texture image found through the MTL and not constant;
  mesh_textured.glb   one mesh with a base-colour texture; in metres (the node's matrix scales
                      by 1e-3), so its extent is the PLY's / 1000.

Exits 1 with a message on any failure, prints "OK: trimesh and open3d read ..." otherwise.
"""

import _pyenv

_pyenv.ensure({"numpy": "numpy", "trimesh": "trimesh", "PIL": "pillow", "open3d": "open3d-cpu"})
_pyenv.ensure_libusb()

import json  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import open3d as o3d  # noqa: E402
import trimesh  # noqa: E402


def one_mesh(scene):
    """A scene's geometry as one mesh, transforms applied (trimesh ≥ 4.5: `to_geometry`)."""
    return scene.to_geometry() if hasattr(scene, "to_geometry") else scene.dump(concatenate=True)


def fail(msg: str) -> None:
    sys.exit(f"FAIL: {msg}")


def main() -> None:
    d = Path(sys.argv[1])
    meta = json.loads((d / "export.json").read_text())
    nv, nf = meta["vertices"], meta["faces"]

    # PLY.
    ply = trimesh.load(d / "mesh.ply", process=False)
    if len(ply.vertices) != nv or len(ply.faces) != nf:
        fail(f"trimesh PLY: {len(ply.vertices)} vertices, {len(ply.faces)} faces; expected {nv}, {nf}")
    cols = np.asarray(ply.visual.vertex_colors)[:, :3].astype(float)
    if cols.std(axis=0).max() < 1.0:
        fail(f"trimesh PLY: colours are constant ({cols.mean(axis=0)})")
    raw = ply.metadata.get("_ply_raw", {}).get("vertex", {}).get("data")
    if raw is None or "nx" not in raw.dtype.names:
        fail("trimesh PLY: no nx/ny/nz vertex properties")
    n = np.stack([raw["nx"], raw["ny"], raw["nz"]], axis=1)
    if np.abs(np.linalg.norm(n, axis=1) - 1).max() > 1e-4:
        fail("trimesh PLY: normals are not unit vectors")
    o = o3d.io.read_triangle_mesh(str(d / "mesh.ply"))
    if not (o.has_vertex_colors() and o.has_vertex_normals()):
        fail("open3d PLY: no vertex colours or normals")
    if len(o.vertices) != nv or len(o.triangles) != nf:
        fail(f"open3d PLY: {len(o.vertices)} vertices, {len(o.triangles)} triangles")
    if np.asarray(o.vertex_colors).std(axis=0).max() < 1 / 255:
        fail("open3d PLY: colours are constant")
    if not np.allclose(np.asarray(o.vertices), ply.vertices, atol=0, rtol=0):
        fail("open3d and trimesh read different positions from the PLY")

    # OBJ + MTL + PNG.
    obj = trimesh.load(d / "mesh_textured.obj", process=False, maintain_order=True)
    if isinstance(obj, trimesh.Scene):
        obj = one_mesh(obj)
    if len(obj.faces) != nf:
        fail(f"trimesh OBJ: {len(obj.faces)} faces, expected {nf}")
    uv = np.asarray(obj.visual.uv)
    if uv.min() < 0 or uv.max() > 1:
        fail(f"trimesh OBJ: UVs outside [0, 1]: {uv.min()} .. {uv.max()}")
    img = getattr(obj.visual.material, "image", None)
    if img is None:
        fail("trimesh OBJ: the texture named by map_Kd was not found")
    if np.asarray(img).std() < 1.0:
        fail("trimesh OBJ: the texture is constant")
    if np.abs(np.asarray(obj.bounds) - ply.bounds).max() > 1e-3:
        fail(f"trimesh OBJ bounds {obj.bounds} differ from the PLY's {ply.bounds}")
    oo = o3d.io.read_triangle_mesh(str(d / "mesh_textured.obj"), enable_post_processing=False)
    if not oo.has_triangle_uvs() or len(oo.textures) == 0:
        fail("open3d OBJ: no triangle UVs or no texture")
    if len(oo.triangles) != nf:
        fail(f"open3d OBJ: {len(oo.triangles)} triangles")

    # GLB.
    scene = trimesh.load(d / "mesh_textured.glb")
    geoms = list(scene.geometry.values())
    if len(geoms) != 1 or len(geoms[0].faces) != nf:
        fail(f"trimesh GLB: {len(geoms)} meshes")
    mat = geoms[0].visual.material
    if getattr(mat, "baseColorTexture", None) is None:
        fail("trimesh GLB: no base colour texture")
    # Radius about the centroid: the node's rotation leaves it, its scale divides it by 1000.
    def radius(v):
        v = np.asarray(v, dtype=float)
        return np.linalg.norm(v - v.mean(axis=0), axis=1).max()

    r_m, r_mm = radius(one_mesh(scene).vertices), radius(ply.vertices)
    if abs(r_m * 1000 - r_mm) > 1e-3 * r_mm:
        fail(f"trimesh GLB: radius {r_m} m, the PLY's {r_mm} mm")
    og = o3d.io.read_triangle_mesh(str(d / "mesh_textured.glb"))
    if len(og.triangles) != nf or not og.has_triangle_uvs():
        fail(f"open3d GLB: {len(og.triangles)} triangles, UVs {og.has_triangle_uvs()}")

    print(
        f"OK: trimesh and open3d read mesh.ply ({nv} vertices, colour std "
        f"{cols.std(axis=0).round(1).tolist()}), mesh_textured.obj (UVs in [0, 1], texture "
        f"{np.asarray(img).shape}) and mesh_textured.glb (radius {r_m:.4f} m)"
    )


if __name__ == "__main__":
    main()
