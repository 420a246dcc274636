//! The training-side sampler: given a chosen training pixel, the colour the model must reproduce
//! and the appearance-embedding input `(code, p)` for `none`, SIA or DIA (paper §3).
//!
//! The training loop picks pixels (its own RNG); this sampler picks augmentations (the RNG it is
//! given, normally [`AugmentConfig::rng`]). Two ways to use it:
//! - rays that sample images independently (instant-nsr-pl's `batch_image_sampling`): call
//!   [`AugSampler::sample`] (or [`AugSampler::sample_batch`]) per ray: one draw per ray;
//! - a batch of rays from one image (NeuS's original sampler): call [`AugSampler::draw`] once for
//!   the image, then [`AugSampler::rgb`] and [`AugSampler::embedding_p`] per ray with that choice.

use super::{AugMode, AugmentConfig, AugmentError, Manipulation, PixelSource};
use crate::scene::image::RgbImage;
use rand::Rng;
use rayon::prelude::*;

/// Replicas per SIA pixel record (the five non-identity manipulations).
const SIA_SLOTS: usize = 5;

/// One training pixel: view index and integer pixel coordinates (OpenCV frame, `x` right, `y`
/// down; the ray goes through `(x + 0.5, y + 0.5)` or a jittered point of the same pixel).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRef {
    /// Index into the sampler's views.
    pub view: u32,
    /// Column.
    pub x: u32,
    /// Row.
    pub y: u32,
}

/// An augmentation drawn for a ray or an image: the manipulation and the intensity applied to the
/// pixels (for SIA the replica's fixed `p_i`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AugChoice {
    /// The manipulation (its code indexes the embedding table).
    pub manipulation: Manipulation,
    /// The intensity applied to the image.
    pub p: f32,
}

impl AugChoice {
    /// No augmentation.
    pub const IDENTITY: AugChoice = AugChoice {
        manipulation: Manipulation::Identity,
        p: 0.0,
    };
}

/// What one training ray gets: target colour and the colour network's embedding input.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AugSample {
    /// Target RGB in `[0, 1]` (the manipulated pixel).
    pub rgb: [f32; 3],
    /// Appearance-embedding row, [`Manipulation::code`] (0 = identity).
    pub code: u32,
    /// The embedding's scalar input: DIA's `p`; always 0 for `none` and SIA (whose embedding is
    /// `Emb(M)` alone, paper §3).
    pub p: f32,
}

impl AugSample {
    /// The embedding input at test time: identity code with `p = 0` (`rgb` is unused there).
    pub const TEST: AugSample = AugSample {
        rgb: [0.0; 3],
        code: 0,
        p: 0.0,
    };
}

/// Serves training pixels under the configured augmentation.
///
/// Memory: `none` and DIA hold the views once (plus one mean per view); SIA holds six copies
/// (the originals and five replicas), `6 × n_views × h × w × 3 × 4` bytes.
#[derive(Clone, Debug)]
pub struct AugSampler {
    cfg: AugmentConfig,
    /// `p_i` (SIA) or `w_i` (DIA) indexed by code, so a draw looks it up without a branch.
    by_code: [f32; Manipulation::COUNT],
    source: PixelSource,
    /// SIA only, per view: the five manipulated replicas interleaved per pixel,
    /// `[h][w][5][3]` row-major, slot `code − 1` holding `M_code(view, p_code)`. A random pixel's
    /// five variants share one or two cache lines, so a SIA fetch misses cache as often as a
    /// plain one (separate replica images made SIA's gather 1.5–2× slower in `benches/augment.rs`).
    replicas: Vec<Vec<f32>>,
}

impl AugSampler {
    /// Validates `cfg`, takes ownership of the training views (`[n_views]`, each `[h][w][3]` in
    /// `[0, 1]`) and, for SIA, computes the five manipulated replicas (in parallel).
    pub fn new(views: Vec<RgbImage>, cfg: &AugmentConfig) -> Result<Self, AugmentError> {
        cfg.validate()?;
        if views.is_empty() {
            return Err(AugmentError::NoImages {
                reason: "the view list is empty".into(),
            });
        }
        if let Some(i) = views.iter().position(|v| v.is_empty()) {
            return Err(AugmentError::NoImages {
                reason: format!("view {i} has no pixels"),
            });
        }
        let replicas = if cfg.mode == AugMode::Sia {
            views
                .par_iter()
                .map(|v| {
                    let manipulated: Vec<RgbImage> = Manipulation::NON_IDENTITY
                        .iter()
                        .map(|&m| m.apply(v, cfg.sia_p.get(m)))
                        .collect();
                    let mut buf = Vec::with_capacity(v.data.len() * SIA_SLOTS);
                    for i in 0..v.len() {
                        for r in &manipulated {
                            buf.extend_from_slice(&r.data[i * 3..i * 3 + 3]);
                        }
                    }
                    buf
                })
                .collect()
        } else {
            Vec::new()
        };
        let by_code = Manipulation::ALL.map(|m| match cfg.mode {
            AugMode::Sia => cfg.sia_p.get(m),
            AugMode::Dia => cfg.dia_width.get(m),
            AugMode::None => 0.0,
        });
        Ok(Self {
            cfg: cfg.clone(),
            by_code,
            source: PixelSource::new(views),
            replicas,
        })
    }

    /// The configured mode.
    pub fn mode(&self) -> AugMode {
        self.cfg.mode
    }

    /// The (validated) configuration.
    pub fn config(&self) -> &AugmentConfig {
        &self.cfg
    }

    /// The original views.
    pub fn views(&self) -> &[RgbImage] {
        self.source.views()
    }

    /// Bytes of image data held (originals plus SIA replicas).
    pub fn image_bytes(&self) -> usize {
        let originals: usize = self.views().iter().map(|v| v.data.len() * 4).sum();
        let replicas: usize = self.replicas.iter().map(|r| r.len() * 4).sum();
        originals + replicas
    }

    /// Draws the augmentation for one ray or one image.
    /// - `none`: always [`AugChoice::IDENTITY`], without touching `rng`.
    /// - SIA: one of the six replicas uniformly (identity included), with its `p_i`.
    /// - DIA: one of the five non-identity manipulations uniformly (six with
    ///   `include_identity`, the identity with `p = 0`), `p = (u − ½)·w_M`, `u ~ U[0, 1)`.
    #[inline]
    pub fn draw<R: Rng + ?Sized>(&self, rng: &mut R) -> AugChoice {
        match self.cfg.mode {
            AugMode::None => AugChoice::IDENTITY,
            AugMode::Sia => {
                let code = rng.random_range(0..Manipulation::COUNT);
                AugChoice {
                    manipulation: Manipulation::ALL[code],
                    p: self.by_code[code],
                }
            }
            AugMode::Dia => {
                // Codes 1..=5, or 0..=5 with the identity; the identity's width is 0, so its p
                // is exactly 0 without a branch.
                let first = if self.cfg.include_identity { 0 } else { 1 };
                let code = rng.random_range(first..Manipulation::COUNT);
                // `+ 0.0` turns the identity's possible −0.0 into +0.0.
                let p = (rng.random::<f32>() - 0.5) * self.by_code[code] + 0.0;
                AugChoice {
                    manipulation: Manipulation::ALL[code],
                    p,
                }
            }
        }
    }

    /// The target colour of pixel `(x, y)` of `view` under `choice`: a replica lookup for SIA,
    /// the per-pixel manipulation for DIA (so any `choice` works in DIA; in SIA `choice.p` must
    /// be the replica's `p_i`, as [`Self::draw`] returns it). Panics on out-of-bounds indices.
    #[inline]
    pub fn rgb(&self, view: usize, x: usize, y: usize, choice: AugChoice) -> [f32; 3] {
        match (self.cfg.mode, choice.manipulation) {
            (_, Manipulation::Identity) | (AugMode::None, _) => self.source.views()[view].get(x, y),
            (AugMode::Sia, m) => {
                let w = self.source.views()[view].width;
                let i = ((y * w + x) * SIA_SLOTS + m.code() as usize - 1) * 3;
                let r = &self.replicas[view][i..i + 3];
                [r[0], r[1], r[2]]
            }
            (AugMode::Dia, m) => self.source.pixel(view, x, y, m, choice.p),
        }
    }

    /// The embedding's scalar input for `choice`: `choice.p` under DIA, 0 otherwise.
    #[inline]
    pub fn embedding_p(&self, choice: AugChoice) -> f32 {
        if self.cfg.mode == AugMode::Dia {
            choice.p
        } else {
            0.0
        }
    }

    /// One ray with its own draw: `(rgb, code, p)`.
    #[inline]
    pub fn sample<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        view: usize,
        x: usize,
        y: usize,
    ) -> AugSample {
        let choice = self.draw(rng);
        AugSample {
            rgb: self.rgb(view, x, y, choice),
            code: choice.manipulation.code(),
            p: self.embedding_p(choice),
        }
    }

    /// [`Self::sample`] for each pixel of `pixels`, in order; `out` is cleared first and reused
    /// (no allocation once it has grown to the batch size).
    pub fn sample_batch<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        pixels: &[PixelRef],
        out: &mut Vec<AugSample>,
    ) {
        out.clear();
        out.extend(
            pixels
                .iter()
                .map(|px| self.sample(rng, px.view as usize, px.x as usize, px.y as usize)),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_pcg::Pcg64Mcg;

    fn views(n: usize, w: usize, h: usize) -> Vec<RgbImage> {
        let mut rng = Pcg64Mcg::seed_from_u64(21);
        (0..n)
            .map(|_| RgbImage::from_fn(w, h, |_, _| [rng.random(), rng.random(), rng.random()]))
            .collect()
    }

    fn cfg(mode: AugMode, include_identity: bool) -> AugmentConfig {
        AugmentConfig {
            mode,
            include_identity,
            ..Default::default()
        }
    }

    #[test]
    fn none_returns_the_original_pixel_with_identity_embedding() {
        let v = views(2, 7, 5);
        let s = AugSampler::new(v.clone(), &cfg(AugMode::None, false)).unwrap();
        let mut rng = Pcg64Mcg::seed_from_u64(1);
        for (view, x, y) in [(0, 0, 0), (1, 6, 4), (1, 3, 2)] {
            let a = s.sample(&mut rng, view, x, y);
            assert_eq!(
                a,
                AugSample {
                    rgb: v[view].get(x, y),
                    code: 0,
                    p: 0.0
                }
            );
        }
        assert_eq!(s.image_bytes(), 2 * 7 * 5 * 3 * 4);
    }

    #[test]
    fn sia_draws_the_six_replicas_uniformly_and_serves_the_replica_pixels() {
        let v = views(3, 9, 6);
        let c = cfg(AugMode::Sia, false);
        let s = AugSampler::new(v.clone(), &c).unwrap();
        assert_eq!(s.image_bytes(), 6 * 3 * 9 * 6 * 3 * 4);
        // Replica pixels equal the whole-image reference of each manipulation at p_i.
        for m in Manipulation::ALL {
            let choice = AugChoice {
                manipulation: m,
                p: c.sia_p.get(m),
            };
            for (i, img) in v.iter().enumerate() {
                let reference = m.apply(img, c.sia_p.get(m));
                for (x, y) in [(0, 0), (4, 3), (8, 5)] {
                    assert_eq!(s.rgb(i, x, y, choice), reference.get(x, y), "{m} view {i}");
                }
            }
        }
        let mut rng = Pcg64Mcg::seed_from_u64(2);
        let n = 60_000;
        let mut counts = [0usize; 6];
        for _ in 0..n {
            let a = s.sample(&mut rng, 1, 4, 3);
            assert_eq!(a.p, 0.0, "SIA passes no p to the model");
            counts[a.code as usize] += 1;
        }
        assert_counts_uniform(&counts, n);
    }

    #[test]
    fn dia_draws_non_identity_manipulations_uniformly_with_p_in_range() {
        let v = views(2, 8, 8);
        let c = cfg(AugMode::Dia, false);
        let s = AugSampler::new(v, &c).unwrap();
        let mut rng = Pcg64Mcg::seed_from_u64(3);
        let n = 50_000;
        let mut counts = [0usize; 6];
        let mut p_min = [f32::INFINITY; 6];
        let mut p_max = [f32::NEG_INFINITY; 6];
        for _ in 0..n {
            let ch = s.draw(&mut rng);
            let k = ch.manipulation.code() as usize;
            counts[k] += 1;
            p_min[k] = p_min[k].min(ch.p);
            p_max[k] = p_max[k].max(ch.p);
        }
        assert_eq!(counts[0], 0, "the paper's DIA never draws the identity");
        assert_counts_uniform(&counts[1..], n);
        for m in Manipulation::NON_IDENTITY {
            let (k, half) = (m.code() as usize, c.dia_width.get(m) / 2.0);
            // p covers [-w/2, w/2): both ends approached within 1 % of the width, never exceeded.
            assert!(
                p_min[k] >= -half && p_max[k] < half,
                "{m}: [{}, {}]",
                p_min[k],
                p_max[k]
            );
            assert!(
                p_min[k] < -0.98 * half && p_max[k] > 0.98 * half,
                "{m}: [{}, {}]",
                p_min[k],
                p_max[k]
            );
        }
    }

    #[test]
    fn dia_with_include_identity_draws_six_and_identity_has_p_zero() {
        let s = AugSampler::new(views(1, 4, 4), &cfg(AugMode::Dia, true)).unwrap();
        let mut rng = Pcg64Mcg::seed_from_u64(4);
        let n = 60_000;
        let mut counts = [0usize; 6];
        for _ in 0..n {
            let a = s.sample(&mut rng, 0, 1, 1);
            if a.code == 0 {
                assert_eq!(a.p, 0.0);
            }
            counts[a.code as usize] += 1;
        }
        assert_counts_uniform(&counts, n);
    }

    #[test]
    fn dia_sample_equals_the_whole_image_manipulation_of_its_draw() {
        let v = views(2, 10, 7);
        let s = AugSampler::new(v.clone(), &cfg(AugMode::Dia, false)).unwrap();
        let mut rng = Pcg64Mcg::seed_from_u64(5);
        let mut replay = Pcg64Mcg::seed_from_u64(5);
        let pixels: Vec<PixelRef> = (0..200)
            .map(|i| PixelRef {
                view: (i % 2) as u32,
                x: (i * 7 % 10) as u32,
                y: (i * 3 % 7) as u32,
            })
            .collect();
        let mut out = Vec::new();
        s.sample_batch(&mut rng, &pixels, &mut out);
        assert_eq!(out.len(), pixels.len());
        for (px, a) in pixels.iter().zip(&out) {
            let ch = s.draw(&mut replay);
            assert_eq!((a.code, a.p), (ch.manipulation.code(), ch.p));
            let whole = ch.manipulation.apply(&v[px.view as usize], ch.p);
            assert_eq!(a.rgb, whole.get(px.x as usize, px.y as usize));
        }
    }

    #[test]
    fn bad_inputs_are_clear_errors() {
        let err = AugSampler::new(Vec::new(), &cfg(AugMode::Dia, false)).unwrap_err();
        assert!(err.to_string().contains("empty"), "{err}");
        let err =
            AugSampler::new(vec![RgbImage::new(0, 0)], &cfg(AugMode::Sia, false)).unwrap_err();
        assert!(err.to_string().contains("view 0"), "{err}");
        let mut c = cfg(AugMode::Sia, false);
        c.sia_p.hue = 0.7;
        let err = AugSampler::new(views(1, 3, 3), &c).unwrap_err();
        assert!(err.to_string().contains("augment.sia_p.hue"), "{err}");
    }

    /// Counts of a uniform categorical draw: each within 5 standard deviations of `n / k`.
    fn assert_counts_uniform(counts: &[usize], n: usize) {
        let k = counts.len() as f64;
        let expect = n as f64 / k;
        let sd = (n as f64 * (1.0 / k) * (1.0 - 1.0 / k)).sqrt();
        for (i, &c) in counts.iter().enumerate() {
            assert!(
                (c as f64 - expect).abs() < 5.0 * sd,
                "category {i}: {c} vs {expect} ± {sd}: {counts:?}"
            );
        }
    }
}
