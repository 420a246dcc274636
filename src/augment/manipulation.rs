//! The colour manipulations `M(I, p)`: whole-image reference ([`Manipulation::apply`]) and the
//! per-pixel fast path DIA uses ([`PixelSource::pixel`]). Semantics: see the module docs of
//! [`crate::augment`].

use super::{normalise_name, range_text, AugmentError};
use crate::scene::image::{luma, RgbImage};
use std::fmt;
use std::str::FromStr;

/// Pillow's `ImageFilter.SMOOTH` kernel (row-major, `[dy][dx]` for `dy, dx ∈ {-1, 0, 1}`), divided by
/// [`SMOOTH_DIVISOR`].
const SMOOTH_KERNEL: [[f32; 3]; 3] = [[1.0, 1.0, 1.0], [1.0, 5.0, 1.0], [1.0, 1.0, 1.0]];
const SMOOTH_DIVISOR: f32 = 13.0;

/// A colour manipulation. The discriminant is the stable integer code that indexes the colour
/// network's appearance-embedding table (identity = 0); never reorder.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Manipulation {
    /// `M(I, p) = I` for every `p` (only `p = 0` is accepted from user input).
    Identity = 0,
    /// `I·(1 + p)`.
    Brightness = 1,
    /// Blend with the image's mean luma, factor `1 + p`.
    Contrast = 2,
    /// Blend with each pixel's luma, factor `1 + p`.
    Saturation = 3,
    /// HSV hue rotation by `p` turns.
    Hue = 4,
    /// Blend with the 3×3 smoothed image, factor `1 + p`; border pixels unchanged.
    Sharpness = 5,
}

impl Manipulation {
    /// Number of codes (rows of the appearance-embedding table).
    pub const COUNT: usize = 6;
    /// Every manipulation, in code order.
    pub const ALL: [Manipulation; 6] = [
        Manipulation::Identity,
        Manipulation::Brightness,
        Manipulation::Contrast,
        Manipulation::Saturation,
        Manipulation::Hue,
        Manipulation::Sharpness,
    ];
    /// The five manipulations the paper's DIA draws from (everything but the identity).
    pub const NON_IDENTITY: [Manipulation; 5] = [
        Manipulation::Brightness,
        Manipulation::Contrast,
        Manipulation::Saturation,
        Manipulation::Hue,
        Manipulation::Sharpness,
    ];

    /// The embedding code (0..[`Self::COUNT`]).
    #[inline]
    pub fn code(self) -> u32 {
        self as u32
    }

    /// The manipulation with this code, if any.
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.get(code as usize).copied()
    }

    /// The name used on the command line and in config files.
    pub fn name(self) -> &'static str {
        match self {
            Manipulation::Identity => "identity",
            Manipulation::Brightness => "brightness",
            Manipulation::Contrast => "contrast",
            Manipulation::Saturation => "saturation",
            Manipulation::Hue => "hue",
            Manipulation::Sharpness => "sharpness",
        }
    }

    /// The valid range of `p`, inclusive at both ends: `[-1, 1]` (factor `[0, 2]`) for the blends,
    /// `[-0.5, 0.5]` turns for hue, `[0, 0]` for the identity.
    pub fn p_range(self) -> (f32, f32) {
        match self {
            Manipulation::Identity => (0.0, 0.0),
            Manipulation::Hue => (-0.5, 0.5),
            _ => (-1.0, 1.0),
        }
    }

    /// Checks `p` against [`Self::p_range`] (NaN and infinities are out of range).
    pub fn check_p(self, p: f32) -> Result<(), AugmentError> {
        let (lo, hi) = self.p_range();
        if p.is_finite() && (lo..=hi).contains(&p) {
            Ok(())
        } else {
            Err(AugmentError::OutOfRange {
                what: format!("{} p", self.name()),
                value: p.to_string(),
                range: range_text(lo as f64, true, hi as f64, true),
            })
        }
    }

    /// The whole-image reference: `M(img, p)`, clipped to `[0, 1]`. `img` must hold values in
    /// `[0, 1]`; `p` is not range-checked here (see [`Self::check_p`]). Bit-exact identity at
    /// `p = 0`.
    pub fn apply(self, img: &RgbImage, p: f32) -> RgbImage {
        let f = 1.0 + p;
        match self {
            Manipulation::Identity => img.clone(),
            Manipulation::Brightness => map_values(img, |v| (v * f).clamp(0.0, 1.0)),
            Manipulation::Contrast => {
                let mean = gray_mean(img);
                map_values(img, |v| blend(v, mean, f))
            }
            Manipulation::Saturation => map_pixels(img, |c| {
                let g = luma(c);
                [blend(c[0], g, f), blend(c[1], g, f), blend(c[2], g, f)]
            }),
            Manipulation::Hue => map_pixels(img, |c| rotate_hue(c, p)),
            Manipulation::Sharpness => {
                // Two passes, as Pillow does it: the smoothed ("degenerate") image with the
                // original border, then the blend everywhere. Blending a border pixel with itself
                // is skipped so the border is kept bit for bit.
                let (w, h) = (img.width, img.height);
                let mut smooth = img.clone();
                for y in 1..h.saturating_sub(1) {
                    for x in 1..w.saturating_sub(1) {
                        let mut acc = [0.0f32; 3];
                        for (ky, row) in SMOOTH_KERNEL.iter().enumerate() {
                            for (kx, &k) in row.iter().enumerate() {
                                let c = img.get(x + kx - 1, y + ky - 1);
                                for ch in 0..3 {
                                    acc[ch] += k * c[ch];
                                }
                            }
                        }
                        smooth.set(x, y, acc.map(|a| a / SMOOTH_DIVISOR));
                    }
                }
                RgbImage::from_fn(w, h, |x, y| {
                    let c = img.get(x, y);
                    if is_border(x, y, w, h) {
                        return c;
                    }
                    let d = smooth.get(x, y);
                    [
                        blend(c[0], d[0], f),
                        blend(c[1], d[1], f),
                        blend(c[2], d[2], f),
                    ]
                })
            }
        }
    }
}

impl fmt::Display for Manipulation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Manipulation {
    type Err = AugmentError;

    /// Case-insensitive; `_` reads as `-`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let n = normalise_name(s);
        Self::ALL
            .into_iter()
            .find(|m| m.name() == n)
            .ok_or_else(|| AugmentError::UnknownName {
                what: "manipulation",
                name: s.to_string(),
                expected: Self::ALL.map(|m| m.name()).join(", "),
            })
    }
}

/// Mean luma of the whole image (contrast's blend target), accumulated in f64; 0 for an empty
/// image.
pub fn gray_mean(img: &RgbImage) -> f32 {
    if img.is_empty() {
        return 0.0;
    }
    let sum: f64 = img
        .data
        .chunks_exact(3)
        .map(|c| luma([c[0], c[1], c[2]]) as f64)
        .sum();
    (sum / img.len() as f64) as f32
}

/// `clamp(x·f + d·(1 − f), 0, 1)`: equal to `x` bit for bit when `f = 1` (`d·0 = 0`, `x + 0 = x`).
#[inline]
fn blend(x: f32, d: f32, f: f32) -> f32 {
    (x * f + d * (1.0 - f)).clamp(0.0, 1.0)
}

#[inline]
fn is_border(x: usize, y: usize, w: usize, h: usize) -> bool {
    x == 0 || y == 0 || x + 1 >= w || y + 1 >= h
}

/// Rotates the HSV hue of one pixel by `turns` (value and saturation unchanged). Zero turns
/// returns the pixel untouched (the HSV round trip is not bit-exact); gray pixels (`max = min`)
/// come back exactly gray. Conversions follow Python's `colorsys` (Smith's hexcone model).
#[inline]
fn rotate_hue(c: [f32; 3], turns: f32) -> [f32; 3] {
    if turns == 0.0 {
        return c;
    }
    let [r, g, b] = c;
    let maxc = r.max(g).max(b);
    let minc = r.min(g).min(b);
    if maxc == minc {
        return c;
    }
    let d = maxc - minc;
    let s = d / maxc;
    let (rc, gc, bc) = ((maxc - r) / d, (maxc - g) / d, (maxc - b) / d);
    let h6 = if r == maxc {
        bc - gc
    } else if g == maxc {
        2.0 + rc - bc
    } else {
        4.0 + gc - rc
    };
    // Hue in turns, rotated, wrapped into [0, 1); `rem_euclid` may round up to exactly 1.0,
    // which the sector arithmetic below treats as 0.
    let h = (h6 / 6.0 + turns).rem_euclid(1.0);
    let v = maxc;
    let hh = h * 6.0;
    let sector = hh.floor();
    let frac = hh - sector;
    let p = v * (1.0 - s);
    let q = v * (1.0 - s * frac);
    let t = v * (1.0 - s * (1.0 - frac));
    let out = match (sector as i32).rem_euclid(6) {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    };
    out.map(|x| x.clamp(0.0, 1.0))
}

fn map_values(img: &RgbImage, f: impl Fn(f32) -> f32) -> RgbImage {
    RgbImage {
        width: img.width,
        height: img.height,
        data: img.data.iter().map(|&v| f(v)).collect(),
    }
}

fn map_pixels(img: &RgbImage, f: impl Fn([f32; 3]) -> [f32; 3]) -> RgbImage {
    RgbImage::from_fn(img.width, img.height, |x, y| f(img.get(x, y)))
}

/// The training views plus what the per-pixel manipulations need, computed once: each view's
/// mean luma (contrast). [`Self::pixel`] then manipulates one pixel on demand, reading at most its
/// 3×3 neighbourhood (sharpness), so DIA touches only the pixels a batch samples.
#[derive(Clone, Debug)]
pub struct PixelSource {
    views: Vec<RgbImage>,
    gray_means: Vec<f32>,
}

impl PixelSource {
    /// Takes ownership of the views (`[n_views]`, each `[h][w][3]` in `[0, 1]`; sizes may differ).
    pub fn new(views: Vec<RgbImage>) -> Self {
        let gray_means = views.iter().map(gray_mean).collect();
        Self { views, gray_means }
    }

    /// The original views.
    pub fn views(&self) -> &[RgbImage] {
        &self.views
    }

    /// Gives the views back.
    pub fn into_views(self) -> Vec<RgbImage> {
        self.views
    }

    /// `M(view, p)` at pixel `(x, y)`: bit-identical to `m.apply(&views[view], p).get(x, y)`.
    /// Panics if `view`, `x` or `y` is out of bounds (an indexing bug of the caller).
    #[inline]
    pub fn pixel(&self, view: usize, x: usize, y: usize, m: Manipulation, p: f32) -> [f32; 3] {
        let img = &self.views[view];
        let c = img.get(x, y);
        let f = 1.0 + p;
        match m {
            Manipulation::Identity => c,
            Manipulation::Brightness => c.map(|v| (v * f).clamp(0.0, 1.0)),
            Manipulation::Contrast => {
                let mean = self.gray_means[view];
                c.map(|v| blend(v, mean, f))
            }
            Manipulation::Saturation => {
                let g = luma(c);
                c.map(|v| blend(v, g, f))
            }
            Manipulation::Hue => rotate_hue(c, p),
            Manipulation::Sharpness => {
                let (w, h) = (img.width, img.height);
                if is_border(x, y, w, h) {
                    return c;
                }
                // Same kernel, same summation order as the reference, so the result is identical.
                let mut acc = [0.0f32; 3];
                for (ky, row) in SMOOTH_KERNEL.iter().enumerate() {
                    let base = ((y + ky - 1) * w + x - 1) * 3;
                    let line = &img.data[base..base + 9];
                    for (kx, &k) in row.iter().enumerate() {
                        for ch in 0..3 {
                            acc[ch] += k * line[kx * 3 + ch];
                        }
                    }
                }
                let d = acc.map(|a| a / SMOOTH_DIVISOR);
                [
                    blend(c[0], d[0], f),
                    blend(c[1], d[1], f),
                    blend(c[2], d[2], f),
                ]
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    fn random_image(w: usize, h: usize, seed: u64) -> RgbImage {
        let mut rng = Pcg64Mcg::seed_from_u64(seed);
        RgbImage::from_fn(w, h, |_, _| [rng.random(), rng.random(), rng.random()])
    }

    /// A random image with some exactly-gray pixels, pure colours, black and white.
    fn mixed_image(w: usize, h: usize, seed: u64) -> RgbImage {
        let mut rng = Pcg64Mcg::seed_from_u64(seed);
        RgbImage::from_fn(w, h, |x, y| match (x + 3 * y) % 7 {
            0 => {
                let g = rng.random();
                [g, g, g]
            }
            1 => [1.0, 0.0, 0.0],
            2 => [0.0, 0.0, 0.0],
            3 => [1.0, 1.0, 1.0],
            _ => [rng.random(), rng.random(), rng.random()],
        })
    }

    #[test]
    fn identity_at_p_zero_is_bit_exact_for_every_manipulation() {
        let img = mixed_image(23, 17, 1);
        let src = PixelSource::new(vec![img.clone()]);
        let mut bad = Vec::new();
        for m in Manipulation::ALL {
            let out = m.apply(&img, 0.0);
            let n_diff = out
                .data
                .iter()
                .zip(&img.data)
                .filter(|(a, b)| a.to_bits() != b.to_bits())
                .count();
            if n_diff > 0 {
                bad.push(format!("{m}: {n_diff} values differ (whole image)"));
            }
            for y in 0..img.height {
                for x in 0..img.width {
                    let px = src.pixel(0, x, y, m, 0.0);
                    if px.map(f32::to_bits) != img.get(x, y).map(f32::to_bits) {
                        bad.push(format!("{m}: pixel ({x}, {y}) differs (per-pixel path)"));
                    }
                }
            }
        }
        assert!(
            bad.is_empty(),
            "identity at p = 0 broken:\n{}",
            bad.join("\n")
        );
    }

    #[test]
    fn per_pixel_path_equals_whole_image_reference_bit_for_bit() {
        // Several sizes, including degenerate ones where every pixel is a border pixel.
        let views = vec![
            random_image(31, 19, 2),
            mixed_image(8, 5, 3),
            random_image(2, 9, 4),
            random_image(1, 1, 5),
        ];
        let src = PixelSource::new(views.clone());
        let mut rng = Pcg64Mcg::seed_from_u64(6);
        let mut bad = Vec::new();
        for m in Manipulation::ALL {
            let (lo, hi) = m.p_range();
            for trial in 0..6 {
                let p = if trial == 0 {
                    hi
                } else {
                    rng.random_range(lo..=hi)
                };
                for (v, img) in views.iter().enumerate() {
                    let reference = m.apply(img, p);
                    // Every pixel of the small images (borders included) rather than a sample.
                    for y in 0..img.height {
                        for x in 0..img.width {
                            let a = src.pixel(v, x, y, m, p);
                            let b = reference.get(x, y);
                            if a.map(f32::to_bits) != b.map(f32::to_bits) {
                                bad.push(format!("{m} p={p} view {v} ({x},{y}): {a:?} vs {b:?}"));
                            }
                        }
                    }
                }
            }
        }
        assert!(
            bad.is_empty(),
            "{} mismatches:\n{}",
            bad.len(),
            bad.join("\n")
        );
    }

    #[test]
    fn gray_pixels_stay_exactly_gray_under_hue_rotation() {
        let img = RgbImage::from_fn(16, 1, |x, _| [x as f32 / 15.0; 3]);
        for p in [-0.5, -0.37, -0.1, 0.01, 0.25, 0.5] {
            let out = Manipulation::Hue.apply(&img, p);
            assert_eq!(out, img, "hue p={p} changed a gray pixel");
        }
    }

    #[test]
    fn hue_rotation_by_a_third_permutes_primaries_and_keeps_value_and_saturation() {
        let img = RgbImage::from_fn(3, 1, |x, _| {
            let mut c = [0.0; 3];
            c[x] = 0.8;
            c
        });
        // +1/3 turn: red -> green -> blue -> red.
        let out = Manipulation::Hue.apply(&img, 1.0 / 3.0);
        let expect = [[0.0, 0.8, 0.0], [0.0, 0.0, 0.8], [0.8, 0.0, 0.0]];
        for (x, e) in expect.iter().enumerate() {
            let got = out.get(x, 0);
            for ch in 0..3 {
                assert!(
                    (got[ch] - e[ch]).abs() < 1e-6,
                    "pixel {x}: {got:?} vs {e:?}"
                );
            }
        }
        // A full round trip of random colours preserves max and min channel (V and S).
        let img = random_image(9, 9, 7);
        let out = Manipulation::Hue.apply(&img, 0.2);
        for (a, b) in img.data.chunks_exact(3).zip(out.data.chunks_exact(3)) {
            let (amax, bmax) = (
                a.iter().cloned().fold(0.0, f32::max),
                b.iter().cloned().fold(0.0, f32::max),
            );
            let (amin, bmin) = (
                a.iter().cloned().fold(1.0, f32::min),
                b.iter().cloned().fold(1.0, f32::min),
            );
            assert!(
                (amax - bmax).abs() < 1e-6 && (amin - bmin).abs() < 1e-5,
                "{a:?} -> {b:?}"
            );
        }
    }

    #[test]
    fn closed_forms_of_each_manipulation() {
        let img = random_image(6, 5, 8);
        let tol = 1e-6;
        // Brightness -0.5 halves every value.
        let out = Manipulation::Brightness.apply(&img, -0.5);
        for (o, i) in out.data.iter().zip(&img.data) {
            assert!((o - 0.5 * i).abs() < tol);
        }
        // Contrast -1 gives the constant mean luma; saturation -1 gives per-pixel luma.
        let mean = gray_mean(&img);
        let out = Manipulation::Contrast.apply(&img, -1.0);
        assert!(
            out.data.iter().all(|&v| (v - mean).abs() < tol),
            "contrast -1"
        );
        let out = Manipulation::Saturation.apply(&img, -1.0);
        for y in 0..img.height {
            for x in 0..img.width {
                let g = luma(img.get(x, y));
                assert!(
                    out.get(x, y).iter().all(|&v| (v - g).abs() < tol),
                    "saturation -1"
                );
            }
        }
        // Sharpness -1 at an interior pixel is the SMOOTH kernel average; borders are unchanged.
        let out = Manipulation::Sharpness.apply(&img, -1.0);
        let (x, y) = (2, 2);
        for ch in 0..3 {
            let mut s = 0.0;
            for dy in 0..3 {
                for dx in 0..3 {
                    let wgt = if dx == 1 && dy == 1 { 5.0 } else { 1.0 };
                    s += wgt * img.get(x + dx - 1, y + dy - 1)[ch];
                }
            }
            assert!((out.get(x, y)[ch] - s / 13.0).abs() < tol);
        }
        for x in 0..img.width {
            assert_eq!(out.get(x, 0), img.get(x, 0));
            assert_eq!(out.get(x, img.height - 1), img.get(x, img.height - 1));
        }
    }

    #[test]
    fn results_stay_in_unit_range_at_extreme_p() {
        let img = mixed_image(12, 10, 9);
        for m in Manipulation::ALL {
            let (lo, hi) = m.p_range();
            for p in [lo, hi] {
                let out = m.apply(&img, p);
                assert!(
                    out.data.iter().all(|v| (0.0..=1.0).contains(v)),
                    "{m} p={p} left [0, 1]"
                );
            }
        }
    }

    #[test]
    fn names_codes_and_ranges() {
        for (i, m) in Manipulation::ALL.into_iter().enumerate() {
            assert_eq!(m.code() as usize, i);
            assert_eq!(Manipulation::from_code(i as u32), Some(m));
            assert_eq!(m.to_string().parse::<Manipulation>(), Ok(m));
        }
        assert_eq!(Manipulation::Identity.code(), 0);
        assert_eq!("Hue".parse::<Manipulation>(), Ok(Manipulation::Hue));
        assert_eq!(Manipulation::from_code(6), None);
        let err = "blur".parse::<Manipulation>().unwrap_err().to_string();
        assert!(err.contains("`blur`") && err.contains("sharpness"), "{err}");
        let err = Manipulation::Hue.check_p(0.6).unwrap_err().to_string();
        assert!(
            err.contains("hue p = 0.6") && err.contains("[-0.5, 0.5]"),
            "{err}"
        );
        assert!(Manipulation::Brightness.check_p(f32::NAN).is_err());
        assert!(Manipulation::Identity.check_p(0.1).is_err());
        assert!(Manipulation::Contrast.check_p(-1.0).is_ok());
    }
}
