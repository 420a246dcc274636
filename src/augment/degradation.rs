//! Image degradations (the paper's appendix), each with one strength `q`, applied on `[0, 1]`
//! values and clipped back to `[0, 1]`.

use super::{normalise_name, range_text, AugmentError};
use crate::scene::image::RgbImage;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Poisson, StandardNormal};
use rand_pcg::Pcg64Mcg;
use std::fmt;
use std::str::FromStr;

/// The kind of a degradation; its strength `q` lives in [`Degradation`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DegradationKind {
    /// `x + N(0, q²)` per value; `q` is the standard deviation, in `(0, 1]`.
    Gaussian,
    /// Horizontal motion blur with a normalised line kernel `q` pixels long ([`motion_blur_kernel`]),
    /// per channel, edges replicated; `q ∈ [1, 100]` pixels. Deterministic.
    MotionBlur,
    /// `Poisson(q·x) / q` per value: `q` is the photon count of a white value, in `(0, 1e6]`; the
    /// variance is `x / q` before clipping.
    Poisson,
    /// Each pixel (all three channels together) becomes white with probability `q` and black with
    /// probability `q`; `q ∈ (0, 0.5]`.
    SaltPepper,
    /// `x + x·N(0, q²)` per value (multiplicative noise); `q ∈ (0, 2]`.
    Speckle,
}

impl DegradationKind {
    /// All kinds, in the order of the paper's appendix.
    pub const ALL: [DegradationKind; 5] = [
        DegradationKind::Gaussian,
        DegradationKind::MotionBlur,
        DegradationKind::Poisson,
        DegradationKind::SaltPepper,
        DegradationKind::Speckle,
    ];

    /// The name used on the command line (`KIND:q`) and in config files.
    pub fn name(self) -> &'static str {
        match self {
            DegradationKind::Gaussian => "gaussian",
            DegradationKind::MotionBlur => "motion-blur",
            DegradationKind::Poisson => "poisson",
            DegradationKind::SaltPepper => "salt-pepper",
            DegradationKind::Speckle => "speckle",
        }
    }

    /// The paper's main strength (appendix): 0.1, 5 px, 10, 0.05, 0.4.
    pub fn default_q(self) -> f32 {
        match self {
            DegradationKind::Gaussian => 0.1,
            DegradationKind::MotionBlur => 5.0,
            DegradationKind::Poisson => 10.0,
            DegradationKind::SaltPepper => 0.05,
            DegradationKind::Speckle => 0.4,
        }
    }

    /// The paper's milder second strength (appendix): 0.05, 2.5 px, 100, 0.025, 0.2.
    pub fn mild_q(self) -> f32 {
        match self {
            DegradationKind::Gaussian => 0.05,
            DegradationKind::MotionBlur => 2.5,
            DegradationKind::Poisson => 100.0,
            DegradationKind::SaltPepper => 0.025,
            DegradationKind::Speckle => 0.2,
        }
    }

    /// Valid `q`: `(lo, lo_inclusive, hi)`, the upper end always inclusive.
    fn q_range(self) -> (f32, bool, f32) {
        match self {
            DegradationKind::Gaussian => (0.0, false, 1.0),
            DegradationKind::MotionBlur => (1.0, true, 100.0),
            DegradationKind::Poisson => (0.0, false, 1e6),
            DegradationKind::SaltPepper => (0.0, false, 0.5),
            DegradationKind::Speckle => (0.0, false, 2.0),
        }
    }
}

impl fmt::Display for DegradationKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for DegradationKind {
    type Err = AugmentError;

    /// Case-insensitive; `_` reads as `-`; also accepts `motionblur`, `saltpepper`,
    /// `salt-and-pepper` and `s&p`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let kind = match normalise_name(s).as_str() {
            "gaussian" => DegradationKind::Gaussian,
            "motion-blur" | "motionblur" => DegradationKind::MotionBlur,
            "poisson" => DegradationKind::Poisson,
            "salt-pepper" | "saltpepper" | "salt-and-pepper" | "s&p" => DegradationKind::SaltPepper,
            "speckle" => DegradationKind::Speckle,
            _ => {
                return Err(AugmentError::UnknownName {
                    what: "degradation",
                    name: s.to_string(),
                    expected: Self::ALL.map(|k| k.name()).join(", "),
                })
            }
        };
        Ok(kind)
    }
}

/// A degradation with its strength. Build with [`Degradation::new`] (range-checked) or parse
/// `KIND:q` / `KIND` (default `q`). Serialises as the string `KIND:q`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct Degradation {
    kind: DegradationKind,
    q: f32,
}

impl Degradation {
    /// A degradation of `kind` with strength `q`; an error names the kind, `q` and the valid range.
    pub fn new(kind: DegradationKind, q: f32) -> Result<Self, AugmentError> {
        let (lo, lo_inclusive, hi) = kind.q_range();
        let above = if lo_inclusive { q >= lo } else { q > lo };
        if q.is_finite() && above && q <= hi {
            Ok(Self { kind, q })
        } else {
            Err(AugmentError::OutOfRange {
                what: format!("{} q", kind.name()),
                value: q.to_string(),
                range: range_text(lo as f64, lo_inclusive, hi as f64, true),
            })
        }
    }

    /// The kind at its paper default strength ([`DegradationKind::default_q`]).
    pub fn default_for(kind: DegradationKind) -> Self {
        Self {
            kind,
            q: kind.default_q(),
        }
    }

    /// The kind.
    pub fn kind(&self) -> DegradationKind {
        self.kind
    }

    /// The strength.
    pub fn q(&self) -> f32 {
        self.q
    }

    /// The degraded image (same size), values clipped to `[0, 1]`. Random kinds draw from `rng` in
    /// row-major pixel order, channel by channel, so a seed fixes the result; motion blur draws
    /// nothing.
    pub fn apply<R: Rng + ?Sized>(&self, img: &RgbImage, rng: &mut R) -> RgbImage {
        let q = self.q;
        let mut out = img.clone();
        match self.kind {
            DegradationKind::Gaussian => {
                for v in &mut out.data {
                    let n: f32 = StandardNormal.sample(rng);
                    *v = (*v + q * n).clamp(0.0, 1.0);
                }
            }
            DegradationKind::Speckle => {
                for v in &mut out.data {
                    let n: f32 = StandardNormal.sample(rng);
                    *v = (*v + *v * q * n).clamp(0.0, 1.0);
                }
            }
            DegradationKind::Poisson => {
                for v in &mut out.data {
                    let lambda = q as f64 * v.clamp(0.0, 1.0) as f64;
                    // Poisson(0) is the constant 0; rand_distr rejects lambda = 0.
                    let k = if lambda > 0.0 {
                        Poisson::new(lambda)
                            .expect("0 < lambda <= 1e6 is a valid Poisson rate")
                            .sample(rng)
                    } else {
                        0.0
                    };
                    *v = ((k / q as f64) as f32).clamp(0.0, 1.0);
                }
            }
            DegradationKind::SaltPepper => {
                for px in out.data.chunks_exact_mut(3) {
                    let u: f32 = rng.random();
                    if u < q {
                        px.fill(1.0);
                    } else if u < 2.0 * q {
                        px.fill(0.0);
                    }
                }
            }
            DegradationKind::MotionBlur => {
                let kernel = motion_blur_kernel(q);
                let half = (kernel.len() / 2) as isize;
                let w = img.width as isize;
                for y in 0..img.height {
                    for x in 0..img.width {
                        let mut acc = [0.0f32; 3];
                        for (i, &k) in kernel.iter().enumerate() {
                            // Replicated edges: the kernel stays normalised at the border.
                            let xs = (x as isize + i as isize - half).clamp(0, w - 1) as usize;
                            let c = img.get(xs, y);
                            for ch in 0..3 {
                                acc[ch] += k * c[ch];
                            }
                        }
                        out.set(x, y, acc.map(|a| a.clamp(0.0, 1.0)));
                    }
                }
            }
        }
        out
    }
}

impl fmt::Display for Degradation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.kind.name(), self.q)
    }
}

impl FromStr for Degradation {
    type Err = AugmentError;

    /// `KIND:q` (e.g. `gaussian:0.05`, `motion-blur:2.5`) or `KIND` alone for the default `q`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.split_once(':') {
            None => Ok(Self::default_for(s.parse()?)),
            Some((name, value)) => {
                let kind: DegradationKind = name.parse()?;
                let q = parse_number(s, value)?;
                Self::new(kind, q)
            }
        }
    }
}

impl TryFrom<String> for Degradation {
    type Error = AugmentError;
    fn try_from(s: String) -> Result<Self, Self::Error> {
        s.parse()
    }
}

impl From<Degradation> for String {
    fn from(d: Degradation) -> String {
        d.to_string()
    }
}

/// Parses the numeric part of a `KIND:value` spec, naming the whole spec on error.
pub(crate) fn parse_number(spec: &str, value: &str) -> Result<f32, AugmentError> {
    value
        .trim()
        .parse::<f32>()
        .map_err(|_| AugmentError::BadSpec {
            spec: spec.to_string(),
            reason: format!("`{}` is not a number", value.trim()),
        })
}

/// The horizontal motion-blur kernel for a line of length `len` pixels (`len ≥ 1`): tap `k`
/// (offset `k − n/2` from the centre, `n` odd) weighs the overlap of pixel `[k − ½, k + ½]` with the
/// segment `[−len/2, len/2]`, normalised to sum 1. Integer odd lengths give a box (`5 → 1/5 × 5`);
/// fractional or even lengths give partial end taps (`2.5 → [0.3, 0.4, 0.3]`), always symmetric,
/// so the blur does not shift the image.
pub fn motion_blur_kernel(len: f32) -> Vec<f32> {
    let len = len.max(1.0) as f64;
    let half_len = len / 2.0;
    let half_taps = (half_len - 0.5).ceil().max(0.0) as i64;
    let weights: Vec<f64> = (-half_taps..=half_taps)
        .map(|k| {
            let (a, b) = (k as f64 - 0.5, k as f64 + 0.5);
            (b.min(half_len) - a.max(-half_len)).max(0.0)
        })
        .collect();
    let sum: f64 = weights.iter().sum();
    weights.iter().map(|w| (w / sum) as f32).collect()
}

/// Degrades every view in place with one RNG stream per view, seeded from `(seed, view index)`,
/// so the result does not depend on the order (or parallelism) of the loop. For
/// `reconstruct --degrade KIND:q` and the simulator's degradation effects.
pub fn degrade_views(views: &mut [RgbImage], degradation: &Degradation, seed: u64) {
    for (i, view) in views.iter_mut().enumerate() {
        let mut rng = view_rng(seed, i);
        *view = degradation.apply(view, &mut rng);
    }
}

/// The RNG of view `i` under `seed` (splitmix-style mixing of the index into the seed).
fn view_rng(seed: u64, i: usize) -> Pcg64Mcg {
    Pcg64Mcg::seed_from_u64(seed ^ (i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn constant(w: usize, h: usize, v: f32) -> RgbImage {
        RgbImage::from_fn(w, h, |_, _| [v; 3])
    }

    /// Sample mean and variance (f64) of all values.
    fn mean_var(data: &[f32]) -> (f64, f64) {
        let n = data.len() as f64;
        let mean = data.iter().map(|&v| v as f64).sum::<f64>() / n;
        let var = data.iter().map(|&v| (v as f64 - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, var)
    }

    /// Checks a sample variance against `expected` within 5 standard errors of the variance
    /// estimator for Gaussian-like data, `sqrt(2/(n-1))·σ²` (Poisson gets its own excess-kurtosis
    /// term, small for the rates used).
    fn assert_variance(what: &str, data: &[f32], mean: f64, var: f64) {
        let (m, v) = mean_var(data);
        let n = data.len() as f64;
        let se_var = (2.0 / (n - 1.0)).sqrt() * var * 1.2;
        let se_mean = (var / n).sqrt();
        assert!(
            (m - mean).abs() < 5.0 * se_mean,
            "{what}: mean {m} vs {mean} (se {se_mean})"
        );
        assert!(
            (v - var).abs() < 5.0 * se_var,
            "{what}: variance {v} vs {var} (se {se_var})"
        );
    }

    #[test]
    fn gaussian_variance_is_q_squared() {
        let img = constant(200, 100, 0.5);
        for q in [0.05f32, 0.1] {
            let mut rng = Pcg64Mcg::seed_from_u64(11);
            let out = Degradation::new(DegradationKind::Gaussian, q)
                .unwrap()
                .apply(&img, &mut rng);
            // 0.5 ± 5σ stays inside [0, 1] for q ≤ 0.1, so clipping does not bias the statistics.
            assert_variance("gaussian", &out.data, 0.5, (q as f64).powi(2));
        }
    }

    #[test]
    fn speckle_variance_is_x_squared_q_squared() {
        for (x, q) in [(0.5f32, 0.15f32), (0.2, 0.15), (0.8, 0.04)] {
            let img = constant(200, 100, x);
            let mut rng = Pcg64Mcg::seed_from_u64(12);
            let out = Degradation::new(DegradationKind::Speckle, q)
                .unwrap()
                .apply(&img, &mut rng);
            // 5·x·q ≤ min(x, 1 − x) for these pairs, so clipping is negligible.
            assert_variance(
                "speckle",
                &out.data,
                x as f64,
                (x as f64 * q as f64).powi(2),
            );
        }
    }

    #[test]
    fn poisson_variance_is_x_over_q() {
        for (x, q) in [(0.3f32, 100.0f32), (0.2, 10.0), (0.05, 1000.0)] {
            let img = constant(200, 100, x);
            let mut rng = Pcg64Mcg::seed_from_u64(13);
            let out = Degradation::new(DegradationKind::Poisson, q)
                .unwrap()
                .apply(&img, &mut rng);
            // P(Poisson(q·x) > q) is below 1e-5 for these pairs, so clipping at 1 is negligible.
            assert_variance("poisson", &out.data, x as f64, x as f64 / q as f64);
            // Values are multiples of 1/q.
            assert!(out
                .data
                .iter()
                .all(|&v| ((v * q).round() - v * q).abs() < 1e-3));
        }
        // Black stays black.
        let mut rng = Pcg64Mcg::seed_from_u64(14);
        let out = Degradation::new(DegradationKind::Poisson, 10.0)
            .unwrap()
            .apply(&constant(4, 4, 0.0), &mut rng);
        assert!(out.data.iter().all(|&v| v == 0.0));
    }

    #[test]
    fn salt_and_pepper_fractions_are_q_each() {
        let img = constant(200, 150, 0.5);
        let n = img.len() as f64;
        for q in [0.05f32, 0.025] {
            let mut rng = Pcg64Mcg::seed_from_u64(15);
            let out = Degradation::new(DegradationKind::SaltPepper, q)
                .unwrap()
                .apply(&img, &mut rng);
            let mut counts = [0usize; 3]; // salt, pepper, untouched
            for px in out.data.chunks_exact(3) {
                match px {
                    [1.0, 1.0, 1.0] => counts[0] += 1,
                    [0.0, 0.0, 0.0] => counts[1] += 1,
                    [0.5, 0.5, 0.5] => counts[2] += 1,
                    other => panic!("pixel {other:?} is neither salt, pepper nor untouched"),
                }
            }
            let se = (q as f64 * (1.0 - q as f64) / n).sqrt();
            for (what, c) in [("salt", counts[0]), ("pepper", counts[1])] {
                let frac = c as f64 / n;
                assert!(
                    (frac - q as f64).abs() < 5.0 * se,
                    "{what} fraction {frac} vs q {q}"
                );
            }
        }
    }

    #[test]
    fn motion_blur_kernel_is_normalised_symmetric_and_sized() {
        for (len, taps) in [
            (1.0f32, 1usize),
            (2.0, 3),
            (2.5, 3),
            (4.0, 5),
            (5.0, 5),
            (7.3, 9),
        ] {
            let k = motion_blur_kernel(len);
            assert_eq!(k.len(), taps, "length {len}");
            let sum: f32 = k.iter().sum();
            assert!((sum - 1.0).abs() < 1e-6, "length {len}: sum {sum}");
            for i in 0..k.len() {
                assert_eq!(k[i], k[k.len() - 1 - i], "length {len} not symmetric");
            }
        }
        let k = motion_blur_kernel(5.0);
        assert!(k.iter().all(|&w| (w - 0.2).abs() < 1e-7), "{k:?}");
        let k = motion_blur_kernel(2.5);
        assert!(
            (k[0] - 0.3).abs() < 1e-6 && (k[1] - 0.4).abs() < 1e-6,
            "{k:?}"
        );
    }

    #[test]
    fn motion_blur_is_horizontal_and_preserves_row_sums() {
        let mut rng = Pcg64Mcg::seed_from_u64(16);
        let d = Degradation::new(DegradationKind::MotionBlur, 5.0).unwrap();
        // An image constant along x (each row its own colour) is unchanged: nothing mixes rows.
        let rows = RgbImage::from_fn(12, 6, |_, y| [y as f32 / 6.0, 0.3, 1.0 - y as f32 / 6.0]);
        let out = d.apply(&rows, &mut rng);
        for (a, b) in out.data.iter().zip(&rows.data) {
            assert!((a - b).abs() < 1e-6);
        }
        // A single bright pixel spreads along its row only, over exactly 5 pixels of 1/5.
        let mut dot = RgbImage::new(15, 7);
        dot.set(7, 3, [1.0, 1.0, 1.0]);
        let out = d.apply(&dot, &mut rng);
        for y in 0..7 {
            for x in 0..15 {
                let expect = if y == 3 && (5..=9).contains(&x) {
                    0.2
                } else {
                    0.0
                };
                assert!(
                    (out.get(x, y)[0] - expect).abs() < 1e-6,
                    "({x}, {y}): {:?}",
                    out.get(x, y)
                );
            }
        }
    }

    #[test]
    fn same_seed_same_bytes_and_views_are_order_independent() {
        let img = RgbImage::from_fn(9, 7, |x, y| [x as f32 / 9.0, y as f32 / 7.0, 0.5]);
        for kind in DegradationKind::ALL {
            let d = Degradation::default_for(kind);
            let a = d.apply(&img, &mut Pcg64Mcg::seed_from_u64(3));
            let b = d.apply(&img, &mut Pcg64Mcg::seed_from_u64(3));
            assert_eq!(a, b, "{kind}");
            if kind != DegradationKind::MotionBlur {
                let c = d.apply(&img, &mut Pcg64Mcg::seed_from_u64(4));
                assert_ne!(a, c, "{kind}: a different seed should change the noise");
            }
        }
        let d = Degradation::default_for(DegradationKind::Gaussian);
        let mut views = vec![img.clone(), img.clone(), img.clone()];
        degrade_views(&mut views, &d, 5);
        let mut last = vec![img.clone()];
        degrade_views(&mut last, &d, 5);
        assert_eq!(views[0], last[0]);
        assert_ne!(views[0], views[1], "views must get different noise");
    }

    #[test]
    fn parsing_defaults_and_errors() {
        let d: Degradation = "gaussian:0.05".parse().unwrap();
        assert_eq!((d.kind(), d.q()), (DegradationKind::Gaussian, 0.05));
        let d: Degradation = "Motion_Blur".parse().unwrap();
        assert_eq!((d.kind(), d.q()), (DegradationKind::MotionBlur, 5.0));
        assert_eq!(d.to_string().parse::<Degradation>(), Ok(d));
        for kind in DegradationKind::ALL {
            assert!(Degradation::new(kind, kind.default_q()).is_ok());
            assert!(Degradation::new(kind, kind.mild_q()).is_ok());
            assert!(Degradation::new(kind, f32::NAN).is_err());
        }
        let err = "blurry:3".parse::<Degradation>().unwrap_err().to_string();
        assert!(
            err.contains("unknown degradation `blurry`") && err.contains("motion-blur"),
            "{err}"
        );
        let err = "salt-pepper:0.7"
            .parse::<Degradation>()
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("salt-pepper q = 0.7") && err.contains("(0, 0.5]"),
            "{err}"
        );
        let err = "gaussian:0".parse::<Degradation>().unwrap_err().to_string();
        assert!(err.contains("(0, 1]"), "{err}");
        let err = "poisson:lots"
            .parse::<Degradation>()
            .unwrap_err()
            .to_string();
        assert!(err.contains("`lots` is not a number"), "{err}");
        // Serde goes through the same string form.
        #[derive(serde::Deserialize)]
        struct Wrap {
            d: Degradation,
        }
        let w: Wrap = toml::from_str("d = \"speckle:0.2\"").unwrap();
        assert_eq!(
            w.d,
            Degradation::new(DegradationKind::Speckle, 0.2).unwrap()
        );
        assert!(toml::from_str::<Wrap>("d = \"speckle:9\"").is_err());
    }
}
