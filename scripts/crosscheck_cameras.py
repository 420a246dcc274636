#!/usr/bin/env python3
"""Cross-check neus-aug's camera decomposition against OpenCV, as NeuS itself decomposes cameras.

An independent writer (numpy + OpenCV, not neus-aug) creates a small scene in the NeuS layout with
random intrinsics (skew included), random rotations, and a non-trivial scale_mat; then
`neus-aug inspect --json -` loads it, and every K, camera-to-world rotation and camera centre is
compared with `cv2.decomposeProjectionMatrix` applied to P = (world_mat @ scale_mat)[:3, :4], the
way Totoro97/NeuS `models/dataset.py` (load_K_Rt_from_P) does it.

P is only defined up to scale. For a positively scaled P both must agree exactly. For a
negatively scaled P, OpenCV returns negative focal lengths: K_cv = K·D and R_cv = D·R with
D = diag(-1, -1, 1) (the same projection, rotated 180° about the optical axis), while neus-aug
normalises to positive focal lengths and det R = +1; the script checks that relation and that
the camera centres agree. With `--scene DIR` an existing
scene is checked instead. Exits non-zero on any disagreement above --tol (relative).

usage: crosscheck_cameras.py --neus-aug PATH/TO/neus-aug [--scene DIR] [--views N] [--seed S]
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _pyenv  # noqa: E402

_pyenv.ensure({"numpy": "numpy", "cv2": "opencv-python-headless"})

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402


def random_scene(root: Path, n: int, seed: int) -> None:
    """Writes image/, mask/ and cameras_sphere.npz with numpy and OpenCV only."""
    rng = np.random.default_rng(seed)
    w, h = 40, 30
    (root / "image").mkdir(parents=True)
    (root / "mask").mkdir()
    scale = np.diag([180.0, 180.0, 180.0, 1.0])
    scale[:3, 3] = [-20.0, 35.5, 640.0]
    arrays = {}
    for i in range(n):
        rvec = rng.uniform(-np.pi, np.pi, 3)
        rot, _ = cv2.Rodrigues(rvec)
        K = np.array(
            [
                [rng.uniform(30, 90), rng.uniform(-1, 1), rng.uniform(15, 25)],
                [0.0, rng.uniform(30, 90), rng.uniform(10, 20)],
                [0.0, 0.0, 1.0],
            ]
        )
        # A centre 2-3 normalised units from the object's centre, in world mm.
        d = rng.normal(size=3)
        centre = scale[:3, 3] + scale[0, 0] * rng.uniform(2, 3) * d / np.linalg.norm(d)
        P = K @ np.hstack([rot, -rot @ centre[:, None]])
        P *= rng.choice([-1.0, 1.0]) * rng.uniform(0.1, 10)  # projective scale, either sign
        world = np.eye(4)
        world[:3, :4] = P
        arrays[f"world_mat_{i}"] = world
        arrays[f"scale_mat_{i}"] = scale
        img = rng.integers(0, 256, size=(h, w, 3), dtype=np.uint8)
        cv2.imwrite(str(root / "image" / f"{i:06d}.png"), img)
        cv2.imwrite(str(root / "mask" / f"{i:03d}.png"), np.full((h, w, 3), 255, np.uint8))
    np.savez(root / "cameras_sphere.npz", **arrays)


def opencv_cameras(root: Path, n: int):
    cams = np.load(root / "cameras_sphere.npz")
    out = []
    for i in range(n):
        P = (cams[f"world_mat_{i}"] @ cams[f"scale_mat_{i}"])[:3, :4]
        K, R, t = cv2.decomposeProjectionMatrix(P)[:3]
        K = K / K[2, 2]
        sign = np.sign(np.linalg.det(P[:, :3]))
        if sign < 0:
            # OpenCV's negative-focal solution; map it to the positive-focal one (see docstring).
            D = np.diag([-1.0, -1.0, 1.0])
            assert K[0, 0] < 0 and K[1, 1] < 0, "OpenCV's convention changed"
            K, R = K @ D, D @ R
        out.append((K, R.T, (t[:3] / t[3])[:, 0]))
    return out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--neus-aug", required=True)
    ap.add_argument("--scene")
    ap.add_argument("--views", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--tol", type=float, default=1e-9)
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(args.scene) if args.scene else Path(tmp) / "scene"
        if not args.scene:
            random_scene(root, args.views, args.seed)
        dump = json.loads(
            subprocess.run(
                [args.neus_aug, "inspect", str(root), "--json", "-"],
                check=True,
                capture_output=True,
                text=True,
            ).stdout
        )
        ours = dump["cameras"]
        ref = opencv_cameras(root, len(ours))
    failures = []
    worst = 0.0
    for i, (cam, (K, c2w_rot, centre)) in enumerate(zip(ours, ref)):
        k = np.array(cam["k"])
        c2w = np.array(cam["c2w"])
        errs = {
            "K": np.abs(k - K).max() / np.abs(K).max(),
            "R": np.abs(c2w[:, :3] - c2w_rot).max(),
            "C": np.linalg.norm(np.array(cam["center"]) - centre) / np.linalg.norm(centre),
            "C(pose)": np.linalg.norm(c2w[:, 3] - centre) / np.linalg.norm(centre),
        }
        worst = max(worst, *errs.values())
        bad = {k: v for k, v in errs.items() if not v <= args.tol}
        if bad:
            failures.append(f"view {i}: " + ", ".join(f"{k} {v:.3e}" for k, v in bad.items()))
    print(f"cameras compared: {len(ours)}, worst relative difference vs OpenCV: {worst:.3e}")
    if failures or len(ours) != len(ref) or not ours:
        print("MISMATCH (tolerance %g):\n" % args.tol + "\n".join(failures), file=sys.stderr)
        return 1
    print("OK: neus-aug matches cv2.decomposeProjectionMatrix")
    return 0


if __name__ == "__main__":
    sys.exit(main())
