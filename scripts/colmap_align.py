#!/usr/bin/env python3
"""Map a mesh reconstructed in a COLMAP-posed scene back into the true frame of the scene it was
made from, with the similarity between the two scenes' cameras (Umeyama, with scale): fitted to
the camera centres alone, and to the whole poses (centres and viewing directions).

The COLMAP round trip (`scripts/colmap_roundtrip.sh`) runs COLMAP on a synthetic scene's images,
imports the model with `neus-aug import colmap` and reconstructs it. Its `mesh.ply` is in the
imported scene's world frame, which is COLMAP's: `reconstruct` maps the mesh out of normalised
space with `scale_mat_0` (`X_world = s·X_norm + c`, src/scene/dtu.rs), and the importer applies no
similarity of its own to the cameras (src/import/mod.rs). COLMAP's frame differs from the true
one by an unknown similarity (gauge freedom of structure from motion). This script

1. reads every camera of both scenes from `cameras_sphere.npz`: `world_mat_i` is `K·[R | −R·C]`
   in the scene's world frame (src/scene/dtu.rs `write_cameras`; NeuS's layout, where
   `scale_mat_i` is applied on top, so it plays no part here), hence the centre `C = −M⁻¹·p4` with
   `M` the left 3×3 block and `p4` the last column, and the viewing direction (camera +z, OpenCV
   axes) `z = M₃/|M₃|`, the third row of `M = K·R` being `R`'s since `K`'s is `(0, 0, 1)`;
2. matches views by image name: view `i` of the imported scene is `import.json`'s `names[i]`, the
   name COLMAP gave the image (relative to the folder COLMAP read, the true scene's `image/`); view
   `i` of the true scene is the `i`-th file of its sorted `image/` folder (the order of
   `world_mat_i`);
3. finds `s, R, t` minimising `Σ |C_true − (s·R·C_colmap + t)|²` (Umeyama, "Least-squares
   estimation of transformation parameters between two point patterns", IEEE TPAMI 13(4), 1991,
   eqs. 34–43), and reports the residual `|C_true − (s·R·C_colmap + t)|` in the true frame's unit
   (mm for the simulator's scenes). This is the fit by the camera centres ("centres");
4. fits a second similarity ("poses") to the centres plus one point per camera on its optical
   axis at the working distance, `A = C + D·z`: `D` is the mean distance of the COLMAP cameras
   to the point nearest all their optical axes (the object, for a capture that orbits it), and
   `s₀·D` on the true side with `s₀` the centres fit's scale. Why: on a rig whose cameras lie on a
   shallow cap (DTU's, the simulator's), the centres pin the rotation about the cap's in-plane
   axes only weakly, and the object sits a lever arm of ~D from the cameras' centroid, so a
   rotation error the centres barely notice moves the object by millimetres; the viewing
   directions pin exactly that rotation;
5. with `--colmap-model` (COLMAP's text model: `images.txt`, `points3D.txt`), fits a third
   similarity ("points") to COLMAP's sparse points and the same tracks triangulated again with
   the true cameras (linear triangulation, Hartley & Zisserman, "Multiple View Geometry", 2nd
   ed., §12.2; both use COLMAP's pixel convention, the centre of the top-left pixel at
   (0.5, 0.5)), keeping the 90 % of the points that fit best (three rounds). Why: on a compact
   object seen from afar, a camera's centre moved sideways and its axis turned back onto the
   object give nearly the same image, so the images pin the cameras' centres and directions far
   less than they pin the structure between them; the sparse points are what the images
   measured, so this fit maps the structure COLMAP saw onto the structure the true cameras see,
   without using the true surface;
6. rewrites the mesh with every vertex mapped by `X ↦ s·R·X + t` of each fit (binary
   little-endian PLY, the vertex element first, as `dtu_eval::ply::write` writes it; other elements
   copied byte for byte): `--out` (centres), `--out-poses` (poses, optional), `--out-points`
   (points, optional);
7. when the true scene has the simulator's `gt_mesh.ply`, reports the fraction of its vertices
   outside the imported scene's region of interest (the unit sphere of its `scale_mat_0`, mapped
   into the true frame): NeuS reconstructs nothing there, so a non-zero fraction means the
   importer's region cut the object.

usage: colmap_align.py --colmap-scene DIR --true-scene DIR --mesh IN.ply --out OUT.ply
                        [--out-poses OUT2.ply] [--colmap-model TXT_DIR --out-points OUT3.ply]
                        [--json F]
       colmap_align.py --self-check
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _pyenv  # noqa: E402

_pyenv.ensure({"numpy": "numpy"})

import argparse  # noqa: E402
import json  # noqa: E402
import tempfile  # noqa: E402

import numpy as np  # noqa: E402


def fail(message: str) -> None:
    sys.exit(f"colmap_align: {message}")


def umeyama(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """The similarity `dst ≈ s·R·src + t` of least squares (Umeyama 1991) for `[n, 3]` point
    sets, `n ≥ 3` not collinear. Returns `(s, R [3, 3] with det +1, t [3])`."""
    if src.shape != dst.shape or src.ndim != 2 or src.shape[1] != 3 or src.shape[0] < 3:
        raise ValueError(f"need two [n, 3] sets with n >= 3, got {src.shape} and {dst.shape}")
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    xs, xd = src - mu_s, dst - mu_d
    var_s = (xs**2).sum() / len(src)
    cov = xd.T @ xs / len(src)  # Σ_xy of eq. 38 (dst as y, src as x)
    u, d, vt = np.linalg.svd(cov)
    if d[1] <= 1e-12 * max(d[0], 1e-300) or var_s <= 0.0:
        raise ValueError("the source points are (nearly) collinear: the rotation is undefined")
    sign = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        sign[2, 2] = -1.0  # eq. 39: a reflection would fit better; take the best rotation
    r = u @ sign @ vt
    s = float(np.trace(np.diag(d) @ sign) / var_s)  # eq. 42
    t = mu_d - s * r @ mu_s  # eq. 41
    return s, r, t


def camera_poses(scene: Path) -> tuple[np.ndarray, np.ndarray]:
    """`([n, 3] camera centres, [n, 3] unit viewing directions)` in the scene's world frame, from
    `world_mat_i` (module doc)."""
    path = scene / "cameras_sphere.npz"
    if not path.is_file():
        fail(f"{path} is missing (not a NeuS scene folder)")
    cams = np.load(path)
    n = sum(1 for k in cams.files if k.startswith("world_mat_") and not k.startswith("world_mat_inv"))
    centers, axes = [], []
    for i in range(n):
        p = cams[f"world_mat_{i}"][:3, :4]
        centers.append(-np.linalg.solve(p[:, :3], p[:, 3]))
        # A projection matrix scaled by a negative factor flips M₃; det(M) > 0 for K·R.
        axes.append(np.sign(np.linalg.det(p[:, :3])) * p[2, :3] / np.linalg.norm(p[2, :3]))
    return np.array(centers), np.array(axes)


def image_names(scene: Path) -> list[str]:
    return sorted(p.name for p in (scene / "image").iterdir() if p.suffix == ".png")


def matched_poses(colmap_scene: Path, true_scene: Path):
    """`(names, (C, z) of the COLMAP scene, (C, z) of the true scene)`, row `k` of each the view
    named `names[k]` (module doc)."""
    record = colmap_scene / "import.json"
    if not record.is_file():
        fail(f"{record} is missing: --colmap-scene must be written by `neus-aug import colmap`")
    names = json.loads(record.read_text())["names"]
    c_colmap, z_colmap = camera_poses(colmap_scene)
    if len(names) != len(c_colmap):
        fail(f"{record} names {len(names)} views but the scene has {len(c_colmap)} cameras")
    true_names = image_names(true_scene)
    c_true_all, z_true_all = camera_poses(true_scene)
    if len(true_names) != len(c_true_all):
        fail(f"{true_scene}: {len(true_names)} images but {len(c_true_all)} cameras")
    index = {name: i for i, name in enumerate(true_names)}
    missing = [n for n in names if Path(n).name not in index]
    if missing:
        fail(f"imported views not in {true_scene / 'image'}: {missing[:5]}")
    rows = [index[Path(n).name] for n in names]
    return names, (c_colmap, z_colmap), (c_true_all[rows], z_true_all[rows])


def nearest_to_axes(c: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The point nearest, in least squares, to every line `c_i + λ·z_i`: solves
    `Σ (I − z zᵀ)(p − c_i) = 0` (as `neus_aug::import::roi_from_cameras`)."""
    m = np.eye(3)[None] - z[:, :, None] * z[:, None, :]
    a, b = m.sum(axis=0), np.einsum("nij,nj->i", m, c)
    eig = np.linalg.eigvalsh(a)
    if eig[0] <= 1e-6 * eig[-1]:
        raise ValueError("the optical axes do not meet (parallel axes): no working distance")
    return np.linalg.solve(a, b)


def pose_fit(cc, zc, ct, zt) -> tuple[float, np.ndarray, np.ndarray, float]:
    """The "poses" similarity of the module doc (step 4): Umeyama on the centres plus one point
    per camera at the working distance along its axis. Returns `(s, R, t, D)` with `D` in the
    COLMAP frame's units."""
    s0, _, _ = umeyama(cc, ct)
    d = float(np.linalg.norm(cc - nearest_to_axes(cc, zc), axis=1).mean())
    src = np.vstack([cc, cc + d * zc])
    dst = np.vstack([ct, ct + s0 * d * zt])
    s, r, t = umeyama(src, dst)
    return s, r, t, d


def read_text_model(model: Path) -> tuple[dict, dict, list]:
    """COLMAP's text model (`images.txt`, `points3D.txt`; COLMAP's "Output Format" page):
    `({image id: name}, {image id: [n, 2] keypoint pixels}, [(X [3], [(image id, keypoint index)])])`."""
    for f in ("images.txt", "points3D.txt"):
        if not (model / f).is_file():
            fail(f"{model / f} is missing: --colmap-model is a text model (colmap model_converter --output_type TXT)")
    rows = [l for l in (model / "images.txt").read_text().splitlines() if not l.startswith("#")]
    names, keypoints = {}, {}
    for head, pts in zip(rows[0::2], rows[1::2]):
        f = head.split()
        names[int(f[0])] = f[9]
        v = pts.split()
        keypoints[int(f[0])] = np.array(v, dtype=np.float64).reshape(-1, 3)[:, :2] if v else np.zeros((0, 2))
    points = []
    for line in (model / "points3D.txt").read_text().splitlines():
        if line.startswith("#") or not line.strip():
            continue
        f = line.split()
        track = [int(x) for x in f[8:]]
        points.append((np.array(f[1:4], dtype=np.float64), list(zip(track[0::2], track[1::2]))))
    return names, keypoints, points


def triangulate(projections: np.ndarray, pixels: np.ndarray) -> np.ndarray | None:
    """The point whose projections by `[k, 3, 4]` matrices best fit `[k, 2]` pixels, `k ≥ 2`, by
    the linear (DLT) method of the module doc; each row's residual is the pixel error times the
    point's depth in that view, so views at similar distances weigh alike. None when the views
    cannot fix it (a point at infinity or a rank below 3)."""
    rows = np.concatenate([pixels[:, :1] * projections[:, 2] - projections[:, 0],
                           pixels[:, 1:] * projections[:, 2] - projections[:, 1]])
    _, sv, vt = np.linalg.svd(rows)
    if len(sv) < 4 or sv[2] <= 1e-9 * sv[0] or abs(vt[-1, 3]) <= 1e-12 * np.abs(vt[-1, :3]).max():
        return None
    return vt[-1, :3] / vt[-1, 3]


def trimmed_umeyama(src: np.ndarray, dst: np.ndarray, keep: float = 0.9, rounds: int = 3):
    """Umeyama on every pair, then `rounds` times on the `keep` fraction whose residual is
    smallest. Returns `(s, R, t, [n] residuals, [n] kept)`."""
    s, r, t = umeyama(src, dst)
    kept = np.ones(len(src), dtype=bool)
    for _ in range(rounds):
        res = np.linalg.norm(dst - (s * src @ r.T + t), axis=1)
        kept = res <= np.quantile(res, keep)
        s, r, t = umeyama(src[kept], dst[kept])
    return s, r, t, np.linalg.norm(dst - (s * src @ r.T + t), axis=1), kept


def points_fit(model: Path, true_scene: Path):
    """The "points" similarity of the module doc (step 5), COLMAP frame → true frame: returns
    `(s, R, t, [n] residuals in the true frame's unit, [n] kept)` over the sparse points seen by
    at least two views that the true cameras can triangulate."""
    names, keypoints, points = read_text_model(model)
    true_names = image_names(true_scene)
    cams = np.load(true_scene / "cameras_sphere.npz")
    index = {n: i for i, n in enumerate(true_names)}
    proj = {}
    for iid, name in names.items():
        if Path(name).name not in index:
            fail(f"{model}: image {name} is not in {true_scene / 'image'}")
        proj[iid] = cams[f"world_mat_{index[Path(name).name]}"][:3, :4].astype(np.float64)
    src, dst = [], []
    for x, track in points:
        if len(track) < 2:
            continue
        p = np.array([proj[i] for i, _ in track])
        uv = np.array([keypoints[i][k] for i, k in track])
        xt = triangulate(p, uv)
        if xt is not None:
            src.append(x)
            dst.append(xt)
    if len(src) < 10:
        fail(f"{model}: only {len(src)} sparse points could be triangulated with the true cameras")
    return trimmed_umeyama(np.array(src), np.array(dst))


def read_vertices(src: Path) -> tuple[bytes, bytes, np.ndarray]:
    """`(file bytes, header bytes, vertex records)` of a binary little-endian PLY whose first
    element is `vertex` with scalar properties including x, y, z (module doc)."""
    data = src.read_bytes()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        fail(f"{src} is not a PLY file with a header")
    header = data[: end + len(b"end_header\n")]
    lines = header.decode("ascii").splitlines()
    if "format binary_little_endian 1.0" not in lines:
        fail(f"{src}: only binary little-endian PLY is handled (as neus-aug writes it)")
    types = {"float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8",
             "uchar": "u1", "uint8": "u1", "char": "i1", "int8": "i1", "short": "<i2",
             "ushort": "<u2", "int": "<i4", "int32": "<i4", "uint": "<u4", "uint32": "<u4"}
    elements = [i for i, l in enumerate(lines) if l.startswith("element ")]
    if not elements or lines[elements[0]].split()[1] != "vertex":
        fail(f"{src}: the first element is not 'vertex'")
    n = int(lines[elements[0]].split()[2])
    fields = []
    for l in lines[elements[0] + 1:]:
        if not l.startswith("property "):
            break
        parts = l.split()
        if parts[1] == "list" or parts[1] not in types:
            fail(f"{src}: vertex property '{l}' is not a scalar this script knows")
        fields.append((parts[2], types[parts[1]]))
    dtype = np.dtype(fields)
    if not {"x", "y", "z"} <= set(dtype.names):
        fail(f"{src}: vertices lack x, y, z")
    vertices = np.frombuffer(data, dtype=dtype, count=n, offset=len(header)).copy()
    return data, header, vertices


def xyz_of(vertices: np.ndarray) -> np.ndarray:
    return np.stack([vertices[a].astype(np.float64) for a in "xyz"], axis=1)


def transform_ply(src: Path, dst: Path, s: float, r: np.ndarray, t: np.ndarray) -> int:
    """Writes `src` with its vertices mapped by `X ↦ s·R·X + t` (module doc); returns the number
    of vertices."""
    data, header, vertices = read_vertices(src)
    n, body = len(vertices), len(header)
    xyz = xyz_of(vertices)
    mapped = s * xyz @ r.T + t
    for k, a in enumerate("xyz"):
        vertices[a] = mapped[:, k]
    dst.write_bytes(header + vertices.tobytes() + data[body + n * vertices.dtype.itemsize:])
    return n


def outside_roi(colmap_scene: Path, gt_mesh: Path, s: float, r: np.ndarray, t: np.ndarray) -> float:
    """Fraction of `gt_mesh`'s vertices (true frame) outside the imported scene's unit sphere
    (`scale_mat_0 = diag(ρ, ρ, ρ, 1) + c` in COLMAP's frame, hence centre `s·R·c + t` and radius
    `s·ρ` in the true frame)."""
    m = np.load(colmap_scene / "cameras_sphere.npz")["scale_mat_0"]
    centre, radius = s * r @ m[:3, 3] + t, s * m[0, 0]
    pts = xyz_of(read_vertices(gt_mesh)[2])
    return float((np.linalg.norm(pts - centre, axis=1) > radius).mean())


def self_check() -> None:
    """Umeyama recovers a known similarity exactly, and the PLY rewrite maps vertices by it."""
    rng = np.random.default_rng(7)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    r_true = q * np.sign(np.linalg.det(q))  # a rotation (det +1)
    s_true, t_true = 37.5, np.array([120.0, -40.0, 510.0])
    src = rng.normal(size=(49, 3))
    dst = s_true * src @ r_true.T + t_true
    s, r, t = umeyama(src, dst)
    err = max(abs(s - s_true) / s_true, np.abs(r - r_true).max(), np.abs(t - t_true).max() / 510.0)
    assert err < 1e-12, f"umeyama: exact similarity recovered to {err:.2e} only"
    # Noisy targets: the fit's residual is the noise, not more.
    noisy = dst + rng.normal(scale=0.1, size=dst.shape)
    s2, r2, t2 = umeyama(src, noisy)
    res = np.linalg.norm(noisy - (s2 * src @ r2.T + t2), axis=1)
    assert res.mean() < 0.3 and abs(s2 - s_true) / s_true < 1e-2, (res.mean(), s2)
    # A reflected target set is fitted by a rotation, never a reflection.
    _, r3, _ = umeyama(src, dst * np.array([1.0, 1.0, -1.0]))
    assert abs(np.linalg.det(r3) - 1.0) < 1e-12
    # The pose fit recovers the same similarity when the axes turn with it, and its working
    # distance is the distance to the point the axes meet at.
    target = np.array([0.3, -0.2, 0.5])
    z_src = target - src
    d_true = np.linalg.norm(z_src, axis=1)
    z_src /= d_true[:, None]
    s4, r4, t4, d4 = pose_fit(src, z_src, dst, z_src @ r_true.T)
    assert abs(s4 - s_true) / s_true < 1e-12 and np.abs(r4 - r_true).max() < 1e-12, (s4, r4)
    assert np.abs(t4 - t_true).max() < 1e-9 and abs(d4 - d_true.mean()) < 1e-12, (t4, d4)
    # Centres on a shallow cap with noise: the poses pin the rotation better than the centres.
    ang = rng.uniform(0, 2 * np.pi, 49)
    cap = np.stack([np.cos(ang), np.sin(ang), np.zeros(49)], axis=1) * rng.uniform(0, 0.4, (49, 1))
    cap[:, 2] = 1.0 - 0.5 * (cap[:, :2] ** 2).sum(axis=1)  # ~ a sphere of radius 1 about 0
    z_cap = -cap / np.linalg.norm(cap, axis=1)[:, None]
    cap_dst = s_true * cap @ r_true.T + t_true
    errs = {"centres": [], "poses": []}
    for _ in range(20):
        noisy_c = cap_dst + rng.normal(scale=0.01 * s_true, size=cap_dst.shape)
        noisy_z = z_cap @ r_true.T + rng.normal(scale=0.003, size=z_cap.shape)
        noisy_z /= np.linalg.norm(noisy_z, axis=1)[:, None]
        for name, fit in (("centres", umeyama(cap, noisy_c)), ("poses", pose_fit(cap, z_cap, noisy_c, noisy_z))):
            s5, r5, t5 = fit[:3]
            errs[name].append(np.linalg.norm(s5 * r5 @ np.zeros(3) + t5 - t_true))  # the object, at 0
    obj_c, obj_p = np.median(errs["centres"]), np.median(errs["poses"])
    assert obj_p < 0.5 * obj_c, f"object error: poses {obj_p:.3f}, centres {obj_c:.3f}"
    # The points fit: tracks seen by cameras around the object, COLMAP's frame a similarity of
    # the true one; triangulation with the true cameras recovers the similarity exactly, and
    # the trimmed fit ignores a few gross outliers.
    k_mat = np.array([[700.0, 0.0, 200.0], [0.0, 700.0, 150.0], [0.0, 0.0, 1.0]])
    projections = []
    for c in cap * 500.0:
        zc = -c / np.linalg.norm(c)
        xc = np.cross([0.0, 1.0, 0.0], zc)
        xc /= np.linalg.norm(xc)
        rot = np.stack([xc, np.cross(zc, xc), zc])
        projections.append(k_mat @ np.hstack([rot, -(rot @ c)[:, None]]))
    projections = np.array(projections)
    world = rng.normal(scale=40.0, size=(300, 3))
    hom = np.einsum("vij,nj->nvi", projections, np.hstack([world, np.ones((300, 1))]))
    pixels = hom[:, :, :2] / hom[:, :, 2:]
    back = np.array([triangulate(projections[:5], pixels[n, :5]) for n in range(300)])
    assert np.abs(back - world).max() < 1e-6, np.abs(back - world).max()
    assert triangulate(projections[:1], pixels[0, :1]) is None, "one view fixed a point"
    colmap_pts = (world - t_true) @ r_true / s_true  # the inverse similarity
    colmap_pts[:10] += rng.normal(scale=5.0, size=(10, 3))  # ten wrong points
    s6, r6, t6, res6, kept6 = trimmed_umeyama(colmap_pts, back)
    assert abs(s6 - s_true) / s_true < 1e-9 and np.abs(r6 - r_true).max() < 1e-9, (s6, r6)
    assert not kept6[:10].any() and np.median(res6) < 1e-6, (kept6[:10], np.median(res6))
    # Collinear points are refused.
    try:
        umeyama(np.outer(np.arange(5.0), [1.0, 2.0, 3.0]), dst[:5])
        raise AssertionError("collinear points were accepted")
    except ValueError:
        pass
    # PLY: three float vertices, one colour byte each, then a face copied verbatim.
    with tempfile.TemporaryDirectory() as d:
        pts = rng.normal(size=(3, 3)).astype("<f4")
        head = (b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
                b"property float y\nproperty float z\nproperty uchar red\nelement face 1\n"
                b"property list uchar uint vertex_indices\nend_header\n")
        vt = np.zeros(3, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1")])
        vt["x"], vt["y"], vt["z"], vt["red"] = pts[:, 0], pts[:, 1], pts[:, 2], [1, 2, 3]
        face = bytes([3]) + np.array([0, 1, 2], dtype="<u4").tobytes()
        a, b = Path(d) / "a.ply", Path(d) / "b.ply"
        a.write_bytes(head + vt.tobytes() + face)
        assert transform_ply(a, b, s_true, r_true, t_true) == 3
        out = b.read_bytes()
        got = np.frombuffer(out, dtype=vt.dtype, count=3, offset=len(head))
        want = s_true * pts.astype(np.float64) @ r_true.T + t_true
        got_xyz = np.stack([got[a] for a in "xyz"], axis=1)
        assert np.abs(got_xyz - want).max() < 1e-4 * 510.0, (got_xyz, want)
        assert list(got["red"]) == [1, 2, 3] and out.endswith(face) and len(out) == len(a.read_bytes())
    print("colmap_align self-check: ok (exact similarity to "
          f"{err:.1e}, noisy fit residual {res.mean():.3f} for noise 0.1, reflection refused, exact "
          f"pose fit, object error on a noisy cap: poses {obj_p:.2f} vs centres {obj_c:.2f}, "
          "triangulation and the trimmed points fit, PLY rewrite)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--colmap-scene", type=Path, help="scene written by `neus-aug import colmap`")
    ap.add_argument("--true-scene", type=Path, help="the synthetic scene COLMAP was run on")
    ap.add_argument("--mesh", type=Path, help="mesh.ply of the COLMAP-posed run (its world frame)")
    ap.add_argument("--out", type=Path, help="the mesh mapped into the true frame (centres fit)")
    ap.add_argument("--out-poses", type=Path, help="the mesh mapped by the poses fit")
    ap.add_argument("--colmap-model", type=Path, help="COLMAP's text model, for the points fit")
    ap.add_argument("--out-points", type=Path, help="the mesh mapped by the points fit")
    ap.add_argument("--json", type=Path, help="write the similarity and residuals here")
    ap.add_argument("--self-check", action="store_true", help="test the fit and the PLY rewrite")
    args = ap.parse_args()
    if args.self_check:
        self_check()
        return
    for flag in ("colmap_scene", "true_scene", "mesh", "out"):
        if getattr(args, flag) is None:
            ap.error(f"--{flag.replace('_', '-')} is required")
    names, (c_colmap, z_colmap), (c_true, z_true) = matched_poses(args.colmap_scene, args.true_scene)
    if len(names) < 3:
        fail(f"only {len(names)} matched cameras: a similarity needs at least 3")
    try:
        s, r, t = umeyama(c_colmap, c_true)
        sp, rp, tp, dist = pose_fit(c_colmap, z_colmap, c_true, z_true)
    except ValueError as e:
        fail(str(e))
    res = np.linalg.norm(c_true - (s * c_colmap @ r.T + t), axis=1)
    res_p = np.linalg.norm(c_true - (sp * c_colmap @ rp.T + tp), axis=1)
    ang = np.degrees(np.arccos(np.clip((z_true * (z_colmap @ rp.T)).sum(axis=1), -1.0, 1.0)))
    n = transform_ply(args.mesh, args.out, s, r, t)
    if args.out_poses:
        transform_ply(args.mesh, args.out_poses, sp, rp, tp)
    report = {
        "matched_cameras": len(names),
        "scale": s,
        "rotation": r.tolist(),
        "translation": t.tolist(),
        "residual_rms": float(np.sqrt((res**2).mean())),
        "residual_mean": float(res.mean()),
        "residual_max": float(res.max()),
        "worst_view": names[int(res.argmax())],
        "mesh_vertices": n,
        "poses": {
            "scale": sp,
            "rotation": rp.tolist(),
            "translation": tp.tolist(),
            "working_distance": dist * s,
            "rotation_from_centres_fit_deg": float(
                np.degrees(np.arccos(np.clip((np.trace(r.T @ rp) - 1) / 2, -1.0, 1.0)))),
            "residual_rms": float(np.sqrt((res_p**2).mean())),
            "axis_angle_rms_deg": float(np.sqrt((ang**2).mean())),
        },
    }
    if args.colmap_model:
        s3, r3, t3, res3, kept3 = points_fit(args.colmap_model, args.true_scene)
        if args.out_points:
            transform_ply(args.mesh, args.out_points, s3, r3, t3)
        report["points"] = {
            "scale": s3,
            "rotation": r3.tolist(),
            "translation": t3.tolist(),
            "points": int(len(res3)),
            "kept": int(kept3.sum()),
            "residual_median": float(np.median(res3)),
            "residual_rms_kept": float(np.sqrt((res3[kept3] ** 2).mean())),
            "rotation_from_centres_fit_deg": float(
                np.degrees(np.arccos(np.clip((np.trace(r.T @ r3) - 1) / 2, -1.0, 1.0)))),
        }
    elif args.out_points:
        ap.error("--out-points needs --colmap-model")
    gt_mesh = args.true_scene / "gt_mesh.ply"
    if gt_mesh.is_file():
        report["gt_outside_roi"] = outside_roi(args.colmap_scene, gt_mesh, s, r, t)
    if args.json:
        args.json.write_text(json.dumps(report, indent=2) + "\n")
    print(f"aligned {n} vertices with the similarity of {len(names)} camera centres: scale {s:.6g}, "
          f"residual rms {report['residual_rms']:.4f} mean {report['residual_mean']:.4f} "
          f"max {report['residual_max']:.4f} (true-frame units, mm; worst {report['worst_view']})")
    p = report["poses"]
    print(f"poses fit (centres + axes at {p['working_distance']:.1f} mm): centre residual rms "
          f"{p['residual_rms']:.4f}, axis angle rms {p['axis_angle_rms_deg']:.4f} deg, "
          f"{p['rotation_from_centres_fit_deg']:.4f} deg from the centres fit")
    if "points" in report:
        q = report["points"]
        print(f"points fit ({q['kept']} of {q['points']} sparse points): residual median "
              f"{q['residual_median']:.4f}, rms of those kept {q['residual_rms_kept']:.4f}, "
              f"{q['rotation_from_centres_fit_deg']:.4f} deg from the centres fit")
    if "gt_outside_roi" in report:
        print(f"{100 * report['gt_outside_roi']:.1f} % of the true surface lies outside the "
              "imported region of interest")


if __name__ == "__main__":
    main()
