"""Cross-check of the colour manipulations against Pillow's ImageEnhance and Python's colorsys.

Usage: python3 scripts/crosscheck_augment.py [PATH/TO/neus-aug]
(default: $NEUS_AUG_BIN, else target/release/neus-aug). Exits non-zero on any disagreement.

For random 8-bit images (values k/255) and several p per manipulation, runs
`neus-aug augment --apply KIND:p IN.png OUT.png` and compares OUT.png (our float result, rounded to
8 bits on save) with two references:

1. The documented float formula in numpy float64 (module docs of src/augment/mod.rs): our output
   must be that value rounded, so |ours - 255*ref| <= 0.5 level (+0.01 for f32 arithmetic).
   Hue's float reference is colorsys' rgb_to_hsv / hsv_to_rgb in double precision.
2. Pillow's ImageEnhance with factor 1 + p (brightness: Brightness, contrast: Contrast,
   saturation: Color, sharpness: Sharpness) and, for hue, colorsys rounded to 8 bits: at most
   1 level apart.

Why 1 level is the right bound against Pillow: Pillow works on 8-bit images. Its blend
(libImaging/Blend.c) truncates `in1 + f*(in2 - in1)` to an integer, and its blend target (the
"degenerate" image) is itself quantised: `convert("L")` rounds each pixel's luma, the SMOOTH filter
(libImaging/Filter.c) rounds, and Contrast uses `int(mean(L) + 0.5)`, the mean of the rounded luma
image rounded to an integer level. Write x for our exact result in levels and x + d for Pillow's
value before truncation, d = (1 - f) * (Pillow's target - our exact target). Ours is round(x),
Pillow's floor(x + d); whenever |d| < 0.5, round(x) - floor(x + d) lies in (-1, 2), so it is 0 or 1.
The target errors are at most 0.5 level (per-pixel luma, SMOOTH) so |p| < 1 suffices for
saturation and sharpness; brightness's target (black) is exact, so any p works. For contrast the
target error is |int(mean_L + 0.5) - 255 * our_mean| <= 0.5 + |mean_L - 255 * our_mean| (the last
term is the average of per-pixel luma rounding errors, tiny on random images): this script computes
d for every contrast case and fails if the precondition |d| < 0.5 does not hold, rather than
widening the tolerance, so the 1-level comparison is always meaningful.

Also checked: p = 0 returns the input bytes exactly for every manipulation, and pixels with
R = G = B stay exactly gray under every hue rotation.
"""

import _pyenv

_pyenv.ensure({"numpy": "numpy", "PIL": "pillow"})

import colorsys  # noqa: E402
import os  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from PIL import Image, ImageEnhance  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
LUMA = np.array([0.299, 0.587, 0.114])

P_VALUES = {
    "brightness": [-1.0, -0.6, -0.25, 0.3, 0.7, 1.0],
    "contrast": [-0.9, -0.5, -0.2, 0.35, 0.7, 0.9],
    "saturation": [-0.9, -0.5, -0.2, 0.35, 0.7, 0.9],
    "sharpness": [-0.9, -0.5, -0.2, 0.35, 0.7, 0.9],
    "hue": [-0.5, -0.3, -0.05, 0.1, 0.25, 0.5],
}
PILLOW = {
    "brightness": ImageEnhance.Brightness,
    "contrast": ImageEnhance.Contrast,
    "saturation": ImageEnhance.Color,
    "sharpness": ImageEnhance.Sharpness,
}


def binary() -> Path:
    if len(sys.argv) > 1:
        return Path(sys.argv[1])
    if os.environ.get("NEUS_AUG_BIN"):
        return Path(os.environ["NEUS_AUG_BIN"])
    return ROOT / "target" / "release" / "neus-aug"


def test_images(rng: np.random.Generator) -> list[np.ndarray]:
    """uint8 [h, w, 3] images: uniform noise, and a mix with gray pixels, primaries, black, white."""
    a = rng.integers(0, 256, size=(24, 32, 3), dtype=np.uint8)
    b = rng.integers(0, 256, size=(9, 13, 3), dtype=np.uint8)
    c = rng.integers(0, 256, size=(16, 16, 3), dtype=np.uint8)
    gray = rng.integers(0, 256, size=(16, 16), dtype=np.uint8)
    mask = rng.random((16, 16)) < 0.4
    c[mask] = np.repeat(gray[..., None], 3, axis=2)[mask]
    c[0, :4] = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]]
    c[1, :2] = [[0, 0, 0], [128, 128, 128]]
    return [a, b, c]


def float_reference(kind: str, img8: np.ndarray, p: float) -> np.ndarray:
    """The documented formula in float64 on values k/255; returns [h, w, 3] in [0, 1]."""
    x = img8.astype(np.float64) / 255.0
    f = 1.0 + p
    if kind == "brightness":
        out = x * f
    elif kind == "contrast":
        mean = (x @ LUMA).mean()
        out = x * f + mean * (1.0 - f)
    elif kind == "saturation":
        g = (x @ LUMA)[..., None]
        out = x * f + g * (1.0 - f)
    elif kind == "sharpness":
        h, w, _ = x.shape
        out = x.copy()
        if h >= 3 and w >= 3:
            acc = np.zeros_like(x[1:-1, 1:-1])
            for dy in range(3):
                for dx in range(3):
                    k = 5.0 if (dy, dx) == (1, 1) else 1.0
                    acc += k * x[dy : dy + h - 2, dx : dx + w - 2]
            smooth = acc / 13.0
            out[1:-1, 1:-1] = x[1:-1, 1:-1] * f + smooth * (1.0 - f)
    elif kind == "hue":
        out = np.empty_like(x)
        for idx in np.ndindex(x.shape[:2]):
            hh, s, v = colorsys.rgb_to_hsv(*x[idx])
            out[idx] = colorsys.hsv_to_rgb((hh + p) % 1.0, s, v)
    else:
        raise ValueError(kind)
    return np.clip(out, 0.0, 1.0)


def pillow_reference(kind: str, img8: np.ndarray, p: float) -> tuple[np.ndarray, float]:
    """Pillow's (or, for hue, colorsys') 8-bit result and the blend-target offset d in levels."""
    if kind == "hue":
        return np.rint(float_reference("hue", img8, p) * 255.0).astype(np.int64), 0.0
    im = Image.fromarray(img8, "RGB")
    out = np.asarray(PILLOW[kind](im).enhance(1.0 + p)).astype(np.int64)
    d = 0.0
    if kind == "contrast":
        mean_l = np.asarray(im.convert("L")).astype(np.float64).mean()
        pillow_mean = int(mean_l + 0.5)
        ours = 255.0 * ((img8.astype(np.float64) / 255.0) @ LUMA).mean()
        d = abs(p) * abs(pillow_mean - ours)
    elif kind in ("saturation", "sharpness"):
        d = abs(p) * 0.5  # bound on the rounded target's error (see the docstring)
    return out, d


def run(exe: Path, spec: str, src: Path, dst: Path) -> np.ndarray:
    res = subprocess.run(
        [str(exe), "augment", "--apply", spec, str(src), str(dst)], capture_output=True, text=True
    )
    if res.returncode != 0:
        raise RuntimeError(f"neus-aug augment --apply {spec} failed: {res.stderr.strip()}")
    return np.asarray(Image.open(dst).convert("RGB")).astype(np.int64)


def main() -> int:
    exe = binary()
    if not exe.exists():
        print(f"neus-aug binary not found at {exe} (build it, or pass its path)", file=sys.stderr)
        return 2
    rng = np.random.default_rng(20240607)
    failures: list[str] = []
    rows: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for i, img8 in enumerate(test_images(rng)):
            src = tmp / f"in{i}.png"
            Image.fromarray(img8, "RGB").save(src)
            for kind in ["identity", *P_VALUES]:
                ours = run(exe, f"{kind}:0", src, tmp / "out.png")
                if not np.array_equal(ours, img8.astype(np.int64)):
                    failures.append(f"image {i}: {kind}:0 is not the identity")
            for kind, ps in P_VALUES.items():
                for p in ps:
                    ours = run(exe, f"{kind}:{p}", src, tmp / "out.png")
                    ref = float_reference(kind, img8, p) * 255.0
                    err_float = np.abs(ours - ref).max()
                    pil, d = pillow_reference(kind, img8, p)
                    err_pil = int(np.abs(ours - pil).max())
                    rows.append(
                        f"image {i} {kind:>10}:{p:<6} |ours-float|={err_float:.3f}  "
                        f"|ours-{'colorsys' if kind == 'hue' else 'pillow'}|={err_pil}  d={d:.3f}"
                    )
                    if err_float > 0.51:
                        failures.append(f"image {i} {kind}:{p}: {err_float:.3f} levels from the float formula")
                    if d >= 0.5:
                        failures.append(f"image {i} {kind}:{p}: precondition |d| < 0.5 fails (d = {d:.3f})")
                    if err_pil > 1:
                        failures.append(f"image {i} {kind}:{p}: {err_pil} levels from Pillow/colorsys")
                    if kind == "hue":
                        gray = (img8[..., 0] == img8[..., 1]) & (img8[..., 1] == img8[..., 2])
                        if not np.array_equal(ours[gray], img8[gray].astype(np.int64)):
                            failures.append(f"image {i} hue:{p}: a gray pixel changed")
    print("\n".join(rows))
    if failures:
        print(f"\n{len(failures)} FAILURES:\n" + "\n".join(failures), file=sys.stderr)
        return 1
    print(f"\nall {len(rows)} manipulation cases agree (float formula <= 0.51 level, Pillow/colorsys <= 1 level)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
