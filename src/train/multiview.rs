//! Multi-view patch consistency (`[train.multiview]`, issue 13; opt-in, off by default).
//!
//! The colour loss compares one pixel with a colour the network is free to choose, so a wrong
//! surface can fit the training images when few views see it (the inside of `cup`'s walls, seen
//! only through the mouth by the rig's far end: `results/geometry/cup-parts-2026-11-25`; from
//! the true surface the walls still move, and the moved walls fit the images better,
//! `results/geometry/cup-color-grid-2026-11-27`). This prior asks for what multi-view stereo asks
//! for instead: that the surface, seen from several training views, shows the same texture in
//! each. It is the multi-view photometric consistency of Geo-NeuS (Fu et al., NeurIPS 2022,
//! §3.3), the normalised cross-correlation of plane-induced patch warps that PatchMatch stereo
//! scores with (Schönberger et al., ECCV 2016, §4).
//!
//! Per step, for up to `rays` rays of the step's batch (inside the mask where masks exist):
//! 1. **Surface point.** The first `+ → −` sign change of the SDF along the ray, found on
//!    `march_samples` evenly spaced points over the ray's span of the box `[-r, r]³` and refined
//!    by `refine` Illinois (modified regula falsi) steps: distance `t*` along the unit direction.
//!    Its normal `n = ∇f/|∇f|` comes from central differences of step `model.fd_eps(active)`.
//!    Rays that start inside, find no crossing, or meet the surface at `|cos| < min_cos` are
//!    skipped.
//! 2. **Patch cost.** A `(2h+1)²` grid of points, `patch_step` pixels apart, around the ray's
//!    pixel in its (reference) view is lifted onto the plane through `x* = o + t*·d` with normal
//!    `n`, projected into each of the view's `sources` nearest training views (smallest angle
//!    between the optical axes) and sampled there (bilinear, on the grey image of
//!    [`crate::augment::luma`], ITU-R 601-2).
//!    A source's cost is `1 − NCC` of the two patches (in `[0, 2]`); sources where the patch
//!    leaves the image or lies behind the camera are left out, and the ray's cost is the mean
//!    of the `top_k` lowest, so views that see another surface there (occlusion) drop out, as
//!    Geo-NeuS and PatchMatch stereo's view selection do. A reference patch whose grey values'
//!    standard deviation is below `min_std` (no texture, nothing to match) skips the ray.
//! 3. **Gradient.** `L = weight · mean over the used rays of their cost`. The cost depends on the
//!    network only through `t*` (the normal is held fixed, as a detached plane hypothesis):
//!    `∂cost/∂t*` is analytic (bilinear sampling, projection, NCC). `t*` is defined by
//!    `f(o + t*·d; θ) = 0`, so `∂t*/∂θ = −(∂f/∂θ)(x*) / (∇f·d)` (implicit differentiation, as
//!    IDR, Yariv et al. 2020, §3.1, and Geo-NeuS place their surface points), and the loss adds
//!    `Σ_r w_r ∂f(x*_r)/∂θ` with `w_r = −(∂L/∂t*_r)/(∇f·d)` through
//!    [`NeusModel::sdf_weighted_grad`]. Only the SDF network and hash grid receive it.
//!
//! 4. **Carving (opt-in, `[train.multiview.carve]`, [`CarveConfig`]).** The gradient of step 3
//!    only reaches a surface within a few pixels of disparity of its match; a false sheet far
//!    in front of the true surface is swept back along the ray instead, and the span in front
//!    of a better-matching depth is pushed empty.
//!
//! The reference images are the training images as training sees them (degraded when a study
//! degrades them), before any colour augmentation: NCC is invariant to a gain and an offset of
//! either patch, not to the augmentations' hue or saturation changes.

use super::data::Batch;
use crate::augment::luma;
use crate::field::Real;
use crate::render::rays::ray_aabb;
use crate::render::NeusModel;
use crate::scene::{Camera, RgbImage};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Settings of the multi-view patch consistency (`[train.multiview]`). Absent from a config's
/// text while it is the default (off), so configs and training hashes without it are unchanged.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MultiViewConfig {
    /// Weight of the loss (0: off).
    pub weight: f32,
    /// Rays per step, the first of the step's batch inside the mask (256).
    pub rays: usize,
    /// First step that applies it (0).
    pub start_step: u64,
    /// Weight at the run's last step: the weight goes linearly from `weight` at `start_step` to
    /// this at the last step (absent: constant `weight`). A strong pull shapes the surface
    /// early; a weaker one at the end leaves the fine detail to the colour loss.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_weight: Option<f32>,
    /// Patch half-width `h` in samples: `(2h + 1)²` samples (3).
    pub patch_half: usize,
    /// Spacing of the patch samples in the reference image, pixels (1.5).
    pub patch_step: f32,
    /// Source views per reference view: the nearest by the angle of the optical axes (8).
    pub sources: usize,
    /// The ray's cost is the mean of its `top_k` best sources' (4).
    pub top_k: usize,
    /// Evenly spaced SDF samples of the surface search along each ray (128).
    pub march_samples: usize,
    /// Illinois refinement steps of each bracketed crossing (6).
    pub refine: usize,
    /// Reference patches with a grey standard deviation below this are skipped (0.01).
    pub min_std: f32,
    /// Surface points met at `|cos(n, d)|` below this are skipped (0.1).
    pub min_cos: f32,
    /// Depth-sweep carving (`[train.multiview.carve]`; absent: off): see [`CarveConfig`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub carve: Option<CarveConfig>,
}

/// Depth-sweep carving (`[train.multiview.carve]`, opt-in; issue 13).
///
/// The patch cost's gradient only moves a surface within a few pixels of disparity of where
/// the patches match, so a false sheet well in front of the true surface (the `cup`'s false
/// bottom, 3–20 mm high: `results/geometry/cup-what-the-images-fix-2026-11-27`) feels no pull.
/// This sweeps, as plane-sweep stereo does (Collins, CVPR 1996; the depth hypotheses of
/// PatchMatch stereo, Schönberger et al., ECCV 2016, §4), the plane of each checked ray's
/// surface point back along the ray: hypotheses `t* + j·range/hypotheses`, `j = 1..=hypotheses`,
/// same normal, cost the mean `1 − NCC` of the `top_k` best sources. When the best hypothesis
/// `t_b` costs under `max_cost` and at least `min_gain` less than the surface point itself,
/// the images say the ray passes the surface point and ends at `t_b`, so
/// - the SDF along the ray from `t*` to `t_b − 2·range/hypotheses` (points `range/hypotheses`
///   apart) is pushed up to `min(tau, (t_b − t)/2)` (hinge: empty space, as free-space
///   carving asks);
/// - the SDF at `t_b` is pulled to zero (`|f|`, the sparse-point SDF loss of Geo-NeuS, §3.2).
///
/// `L = weight · mean over carved rays of (mean hinge + surface_weight·|f(t_b)|)`, on the
/// plan's points held fixed ([`carve_loss_grad`]). Distances are in the normalised frame (the
/// unit sphere of `cameras_sphere.npz`). Checked against the true depth on `cup`, the gate is
/// right (most carved surface points are false) but `t_b` is rarely the truth, and later in a
/// run it overshoots into the object more often (`results/geometry/cup-carve-2026-11-27`):
/// hence `end_step`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CarveConfig {
    /// Weight of the carving loss (1).
    pub weight: f32,
    /// First step that applies it (200).
    pub start_step: u64,
    /// Last step that applies it (absent: to the end). Once the false sheets are gone, what
    /// is left to sweep is mostly surface near the truth, where a spurious match behind can
    /// cut into the object.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub end_step: Option<u64>,
    /// Rays checked per step, the first of the step's batch inside the mask, as the prior's
    /// own rays (256: the prior's rays); only those whose surface point costs at least
    /// `min_gain` are swept.
    pub rays: usize,
    /// How far behind the surface point the sweep reaches, normalised units (0.25).
    pub range: f32,
    /// Depth hypotheses over that range (40).
    pub hypotheses: usize,
    /// Sources averaged into a hypothesis's cost (2).
    pub top_k: usize,
    /// A hypothesis is taken only when its cost is below this (0.3).
    pub max_cost: f32,
    /// ... and at least this much below the surface point's cost (0.3).
    pub min_gain: f32,
    /// The SDF the hinge asks for in the carved span, normalised units (0.01).
    pub tau: f32,
    /// Share of `t_b − t*` carved from `t*` on (1: up to `t_b − 2·range/hypotheses`); a
    /// shorter span spares the true surface when the sweep's best hypothesis lies beyond it.
    pub span: f32,
    /// Weight of the `|f(t_b)|` term against the hinge's (1).
    pub surface_weight: f32,
}

impl Default for CarveConfig {
    fn default() -> Self {
        Self {
            weight: 1.0,
            start_step: 200,
            end_step: None,
            rays: 256,
            range: 0.25,
            hypotheses: 40,
            top_k: 2,
            max_cost: 0.3,
            min_gain: 0.3,
            tau: 0.01,
            span: 1.0,
            surface_weight: 1.0,
        }
    }
}

impl CarveConfig {
    /// The first invalid field, as `(key, value, why)`; `sources` is the prior's source count.
    fn invalid(&self, sources: usize) -> Option<(&'static str, String, &'static str)> {
        let pos = |v: f32| v.is_finite() && v > 0.0;
        let nonneg = |v: f32| v.is_finite() && v >= 0.0;
        let checks = [
            (
                "train.multiview.carve.weight",
                nonneg(self.weight),
                self.weight.to_string(),
                "must be ≥ 0",
            ),
            (
                "train.multiview.carve.rays",
                self.rays > 0,
                self.rays.to_string(),
                "must be at least 1",
            ),
            (
                "train.multiview.carve.range",
                pos(self.range),
                self.range.to_string(),
                "must be positive (normalised units)",
            ),
            (
                "train.multiview.carve.hypotheses",
                (2..=1024).contains(&self.hypotheses),
                self.hypotheses.to_string(),
                "must be in 2..=1024",
            ),
            (
                "train.multiview.carve.top_k",
                (1..=sources).contains(&self.top_k),
                self.top_k.to_string(),
                "must be in 1..=train.multiview.sources",
            ),
            (
                "train.multiview.carve.max_cost",
                pos(self.max_cost),
                self.max_cost.to_string(),
                "must be positive",
            ),
            (
                "train.multiview.carve.min_gain",
                nonneg(self.min_gain),
                self.min_gain.to_string(),
                "must be ≥ 0",
            ),
            (
                "train.multiview.carve.span",
                pos(self.span) && self.span <= 1.0,
                self.span.to_string(),
                "must be in (0, 1]",
            ),
            (
                "train.multiview.carve.surface_weight",
                nonneg(self.surface_weight),
                self.surface_weight.to_string(),
                "must be ≥ 0",
            ),
            (
                "train.multiview.carve.tau",
                pos(self.tau),
                self.tau.to_string(),
                "must be positive (normalised units)",
            ),
        ];
        let (key, _, value, why) = checks.into_iter().find(|c| !c.1)?;
        Some((key, value, why))
    }
}

impl Default for MultiViewConfig {
    fn default() -> Self {
        Self {
            weight: 0.0,
            rays: 256,
            start_step: 0,
            final_weight: None,
            patch_half: 3,
            patch_step: 1.5,
            sources: 8,
            top_k: 4,
            march_samples: 128,
            refine: 6,
            min_std: 0.01,
            min_cos: 0.1,
            carve: None,
        }
    }
}

impl MultiViewConfig {
    /// Whether this is the default (the section is then left out of the config text).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// Whether the prior runs at all.
    pub fn enabled(&self) -> bool {
        self.weight > 0.0
    }

    /// The weight at `step` of a run of `iterations` steps (0 before `start_step`): `weight`,
    /// or the linear ramp to `final_weight` at step `iterations − 1`.
    pub fn weight_at(&self, step: u64, iterations: u64) -> f32 {
        if !self.enabled() {
            return 0.0;
        }
        ramp_weight(
            self.weight,
            self.final_weight,
            self.start_step,
            step,
            iterations,
        )
    }

    /// The first invalid field, as `(key, value, why)`.
    pub fn invalid(&self) -> Option<(&'static str, String, &'static str)> {
        let finite_nonneg = |v: f32| v.is_finite() && v >= 0.0;
        if !finite_nonneg(self.weight) {
            return Some((
                "train.multiview.weight",
                self.weight.to_string(),
                "must be ≥ 0",
            ));
        }
        if let Some(w) = self.final_weight.filter(|&w| !finite_nonneg(w)) {
            return Some(("train.multiview.final_weight", w.to_string(), "must be ≥ 0"));
        }
        if self.rays == 0 {
            return Some(("train.multiview.rays", "0".into(), "must be at least 1"));
        }
        if !(1..=10).contains(&self.patch_half) {
            return Some((
                "train.multiview.patch_half",
                self.patch_half.to_string(),
                "must be in 1..=10",
            ));
        }
        if !(self.patch_step.is_finite() && self.patch_step > 0.0) {
            return Some((
                "train.multiview.patch_step",
                self.patch_step.to_string(),
                "must be positive (pixels)",
            ));
        }
        if self.sources == 0 {
            return Some(("train.multiview.sources", "0".into(), "must be at least 1"));
        }
        if !(1..=self.sources).contains(&self.top_k) {
            return Some((
                "train.multiview.top_k",
                self.top_k.to_string(),
                "must be in 1..=sources",
            ));
        }
        if !(2..=4096).contains(&self.march_samples) {
            return Some((
                "train.multiview.march_samples",
                self.march_samples.to_string(),
                "must be in 2..=4096",
            ));
        }
        if !finite_nonneg(self.min_std) {
            return Some((
                "train.multiview.min_std",
                self.min_std.to_string(),
                "must be ≥ 0",
            ));
        }
        if !(self.min_cos.is_finite() && (0.0..1.0).contains(&self.min_cos)) {
            return Some((
                "train.multiview.min_cos",
                self.min_cos.to_string(),
                "must be in [0, 1)",
            ));
        }
        if let Some(c) = &self.carve {
            return c.invalid(self.sources);
        }
        None
    }
}

/// What the prior did at one step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MultiViewStep {
    /// The weighted loss `L`.
    pub loss: f64,
    /// Rays the step looked at.
    pub rays: usize,
    /// Rays with a surface point (step 1 of the module doc).
    pub hits: usize,
    /// Rays that contributed a cost (a textured patch and at least one valid source).
    pub used: usize,
    /// Mean cost `1 − NCC` over the used rays (unweighted; 0 when none).
    pub mean_cost: f64,
    /// Seconds of the step in the surface search, the patch costs and the gradient.
    pub seconds: [f64; 3],
    /// Depth-sweep carving (`carve`): rays swept, rays carved, their weighted loss, and the
    /// mean distance `t_b − t*` of the carved rays (normalised units).
    #[serde(default)]
    pub carve: CarveStep,
}

/// What the depth-sweep carving did at one step ([`CarveConfig`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CarveStep {
    /// Rays whose sweep ran (a surface point costing at least `min_gain`).
    pub swept: usize,
    /// Rays carved (a hypothesis behind passed both tests).
    pub carved: usize,
    /// The weighted loss.
    pub loss: f64,
    /// Mean `t_b − t*` over the carved rays (0 when none).
    pub mean_depth: f64,
}

type M3 = [[f64; 3]; 3];

fn mul(m: &M3, v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn m3(m: &nalgebra::Matrix3<f64>) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

/// A training view as the prior reads it: grey pixels and the camera (normalised space).
#[derive(Clone, Debug)]
struct GreyView {
    width: usize,
    height: usize,
    /// `[height][width]` grey values in `[0, 1]`.
    grey: Vec<f32>,
    /// `K·R`: a point `X` projects to `h = K·R·(X − C)`, pixel `(h₀/h₂, h₁/h₂)`.
    kr: M3,
    /// `Rᵀ·K⁻¹`: the (unnormalised) direction of the ray through pixel coordinates `(u, v)` is
    /// `M·[u, v, 1]`.
    m: M3,
    /// Camera centre `C`.
    c: [f64; 3],
    /// Optical axis (unit, world frame): the third row of `R`.
    axis: [f64; 3],
}

impl GreyView {
    fn new(cam: &Camera, img: &RgbImage) -> Self {
        let grey = img
            .data
            .chunks_exact(3)
            .map(|p| luma([p[0], p[1], p[2]]))
            .collect();
        let k_inv = cam.k.try_inverse().expect("K has a positive diagonal");
        Self {
            width: img.width,
            height: img.height,
            grey,
            kr: m3(&(cam.k * cam.r)),
            m: m3(&(cam.r.transpose() * k_inv)),
            c: [cam.center.x, cam.center.y, cam.center.z],
            axis: [cam.r[(2, 0)], cam.r[(2, 1)], cam.r[(2, 2)]],
        }
    }

    /// Bilinear grey value and its gradient `(∂/∂u, ∂/∂v)` at continuous pixel coordinates
    /// `(u, v)` (pixel `(x, y)`'s centre is `(x + 0.5, y + 0.5)`, `scene::camera`); `None`
    /// outside the rectangle of pixel centres (or for a non-finite coordinate).
    fn sample(&self, u: f64, v: f64) -> Option<(f64, f64, f64)> {
        let (x, y) = (u - 0.5, v - 0.5);
        if !(x >= 0.0 && y >= 0.0) {
            return None;
        }
        let (x0, y0) = (x.floor(), y.floor());
        if x0 + 1.0 >= self.width as f64 || y0 + 1.0 >= self.height as f64 {
            return None;
        }
        let (fx, fy) = (x - x0, y - y0);
        let i = y0 as usize * self.width + x0 as usize;
        let g = &self.grey;
        let (a, b) = (g[i] as f64, g[i + 1] as f64);
        let (c, d) = (g[i + self.width] as f64, g[i + self.width + 1] as f64);
        let val = (1.0 - fy) * ((1.0 - fx) * a + fx * b) + fy * ((1.0 - fx) * c + fx * d);
        let du = (1.0 - fy) * (b - a) + fy * (d - c);
        let dv = (1.0 - fx) * (c - a) + fx * (d - b);
        Some((val, du, dv))
    }
}

/// The normalised cross-correlation of patches `a` and `b` and `∂NCC/∂b_k`:
/// `NCC = S_ab / √(S_aa·S_bb + ε)` with the sums of the centred values
/// (`S_ab = Σ (a − ā)(b − b̄)`), so `∂NCC/∂b_k = (a_k − ā)/D − S_ab·S_aa·(b_k − b̄)/D³`.
fn ncc(a: &[f64], b: &[f64], d_b: &mut [f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut saa, mut sbb, mut sab) = (0.0, 0.0, 0.0);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (x - ma, y - mb);
        saa += x * x;
        sbb += y * y;
        sab += x * y;
    }
    let dd = (saa * sbb + 1e-12).sqrt();
    let k = sab * saa / (dd * dd * dd);
    for ((g, &x), &y) in d_b.iter_mut().zip(a).zip(b) {
        *g = (x - ma) / dd - k * (y - mb);
    }
    sab / dd
}

/// The multi-view patch consistency prior of a run (module doc).
pub struct MultiViewPrior {
    cfg: MultiViewConfig,
    views: Vec<GreyView>,
    /// `[view]` its source views, nearest first.
    sources: Vec<Vec<usize>>,
}

impl MultiViewPrior {
    /// The prior over the training views: `cameras[i]` (normalised space) took `images[i]`.
    pub fn new(cfg: MultiViewConfig, cameras: &[Camera], images: &[RgbImage]) -> Self {
        assert_eq!(cameras.len(), images.len(), "one image per camera");
        let views: Vec<GreyView> = cameras
            .iter()
            .zip(images)
            .map(|(c, i)| GreyView::new(c, i))
            .collect();
        let sources = (0..views.len())
            .map(|i| {
                let mut others: Vec<(f64, usize)> = (0..views.len())
                    .filter(|&j| j != i)
                    .map(|j| (-dot(views[i].axis, views[j].axis), j))
                    .collect();
                others.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                others.iter().take(cfg.sources).map(|&(_, j)| j).collect()
            })
            .collect();
        Self {
            cfg,
            views,
            sources,
        }
    }

    /// The cost `1 − NCC` (mean of the `top_k` best sources) of the patch around pixel
    /// coordinates `(u0, v0)` of view `view`, on the plane through the point at distance `t`
    /// along that pixel's unit ray with unit normal `n` (normalised space), and `∂cost/∂t`.
    /// `None` when the reference patch leaves the image or has no texture, the plane is seen
    /// edge-on, or no source sees the whole patch.
    fn patch_cost(&self, view: usize, u0: f64, v0: f64, t: f64, n: [f64; 3]) -> Option<(f64, f64)> {
        self.patch_cost_k(view, u0, v0, t, n, self.cfg.top_k)
    }

    /// [`Self::patch_cost`] with the mean over the `top_k` best sources.
    fn patch_cost_k(
        &self,
        view: usize,
        u0: f64,
        v0: f64,
        t: f64,
        n: [f64; 3],
        top_k: usize,
    ) -> Option<(f64, f64)> {
        let cfg = &self.cfg;
        let rv = &self.views[view];
        let h = cfg.patch_half as i64;
        let step = cfg.patch_step as f64;
        let d0 = mul(&rv.m, [u0, v0, 1.0]);
        let d0_len = dot(d0, d0).sqrt();
        let nd0 = dot(n, d0) / d0_len;
        if nd0.is_nan() || nd0.abs() < 1e-3 {
            return None;
        }
        // Reference values and each sample's direction `a_m` on the plane: X_m(t) = C + t·a_m.
        let mut a = Vec::with_capacity(((2 * h + 1) * (2 * h + 1)) as usize);
        let mut dirs = Vec::with_capacity(a.capacity());
        for j in -h..=h {
            for i in -h..=h {
                let (u, v) = (u0 + i as f64 * step, v0 + j as f64 * step);
                let (val, _, _) = rv.sample(u, v)?;
                let dm = mul(&rv.m, [u, v, 1.0]);
                let ndm = dot(n, dm);
                if ndm.abs() < 1e-3 * dot(dm, dm).sqrt() {
                    return None;
                }
                let s = nd0 / ndm;
                if s <= 0.0 {
                    // The plane meets this sample's ray behind the camera.
                    return None;
                }
                a.push(val);
                dirs.push(dm.map(|x| s * x));
            }
        }
        let na = a.len() as f64;
        let mean = a.iter().sum::<f64>() / na;
        let var = a.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / na;
        if !var.is_finite() || var.sqrt() < cfg.min_std as f64 {
            return None;
        }
        let mut b = vec![0.0; a.len()];
        let mut db_dt = vec![0.0; a.len()];
        let mut d_ncc = vec![0.0; a.len()];
        let mut costs: Vec<(f64, f64)> = Vec::with_capacity(cfg.sources);
        'src: for &s in &self.sources[view] {
            let sv = &self.views[s];
            for (k, am) in dirs.iter().enumerate() {
                let x = [0, 1, 2].map(|q| rv.c[q] + t * am[q] - sv.c[q]);
                let hh = mul(&sv.kr, x);
                let dh = mul(&sv.kr, *am);
                if hh[2].is_nan() || hh[2] <= 1e-9 {
                    continue 'src;
                }
                let (pu, pv) = (hh[0] / hh[2], hh[1] / hh[2]);
                let Some((val, gu, gv)) = sv.sample(pu, pv) else {
                    continue 'src;
                };
                let iz2 = 1.0 / (hh[2] * hh[2]);
                let dpu = (dh[0] * hh[2] - hh[0] * dh[2]) * iz2;
                let dpv = (dh[1] * hh[2] - hh[1] * dh[2]) * iz2;
                b[k] = val;
                db_dt[k] = gu * dpu + gv * dpv;
            }
            let c = ncc(&a, &b, &mut d_ncc);
            let dc: f64 = -d_ncc.iter().zip(&db_dt).map(|(g, d)| g * d).sum::<f64>();
            // A non-finite pixel in the source (or a degenerate projection) drops the source.
            if c.is_finite() && dc.is_finite() {
                costs.push((1.0 - c, dc));
            }
        }
        if costs.is_empty() {
            return None;
        }
        costs.sort_by(|x, y| x.0.total_cmp(&y.0));
        let k = top_k.min(costs.len());
        let inv = 1.0 / k as f64;
        let (c, dc) = costs[..k]
            .iter()
            .fold((0.0, 0.0), |(c, d), &(x, y)| (c + x, d + y));
        Some((c * inv, dc * inv))
    }

    /// Adds the prior's gradient at step `step` of `iterations` into `grads` for rays of `batch`
    /// (the step's training batch, its `views` indexing the cameras given to
    /// [`MultiViewPrior::new`]): the first `rays` rays inside the mask (every ray without
    /// masks), at the weight [`MultiViewConfig::weight_at`]. `None` when off or before its
    /// start step.
    #[allow(clippy::too_many_arguments)]
    pub fn add_grad(
        &self,
        model: &NeusModel,
        params: &[f32],
        step: u64,
        iterations: u64,
        active: usize,
        batch: &Batch,
        grads: &mut [f32],
    ) -> Option<MultiViewStep> {
        let cfg = &self.cfg;
        if !cfg.enabled() || step < cfg.start_step {
            return None;
        }
        let weight = cfg.weight_at(step, iterations) as f64;
        let first = |count: usize| masked_rays(batch, count);
        let rays = first(cfg.rays);
        let sdf = sdf_f64(model, params, active);
        let eps = model.fd_eps(active);
        let (mut out, _, hits) =
            self.loss_grad_hits(weight, model, params, &sdf, active, eps, &rays, None, grads);
        if let Some(cv) = cfg.carve.as_ref() {
            if cv.weight > 0.0 && step >= cv.start_step && cv.end_step.is_none_or(|e| step <= e) {
                // The carve's rays are the first `cv.rays` of the same list: when they are no
                // more than the prior's, its crossings are theirs.
                out.carve = if cv.rays <= cfg.rays {
                    let n = cv.rays.min(rays.len());
                    let (r, h) = (&rays[..n], &hits[..n]);
                    self.carve_grad(model, params, &sdf, active, eps, r, Some(h), grads)
                } else {
                    let carve_rays = first(cv.rays);
                    self.carve_grad(model, params, &sdf, active, eps, &carve_rays, None, grads)
                };
            }
        }
        Some(out)
    }

    /// The prior's loss at the weight `weight` on explicit rays, in the precision `T` of
    /// `params`, and its gradient added into `grads`: `rays[i] = (view, [x, y])`, the ray
    /// through that pixel's centre. `sdf` evaluates the field (channel 0) at points, `eps` is
    /// the normal's difference step. `normals`: hold each ray's plane normal at the given value
    /// (a gradient check's differences must not move it, since the gradient treats it as
    /// fixed); `None` computes them. Returns the step's summary and the normal each ray used
    /// (`None`: not used).
    #[allow(clippy::too_many_arguments, clippy::type_complexity)]
    pub fn loss_grad<T: Real>(
        &self,
        weight: f64,
        model: &NeusModel,
        params: &[T],
        sdf: &dyn Fn(&[[f64; 3]]) -> Vec<f64>,
        active: usize,
        eps: f64,
        rays: &[(usize, [u32; 2])],
        normals: Option<&[Option<[f64; 3]>]>,
        grads: &mut [T],
    ) -> (MultiViewStep, Vec<Option<[f64; 3]>>) {
        let (out, used, _) = self.loss_grad_hits(
            weight, model, params, sdf, active, eps, rays, normals, grads,
        );
        (out, used)
    }

    /// [`Self::loss_grad`], also returning each ray's surface crossing (the carving reuses them).
    #[allow(clippy::too_many_arguments, clippy::type_complexity)]
    fn loss_grad_hits<T: Real>(
        &self,
        weight: f64,
        model: &NeusModel,
        params: &[T],
        sdf: &dyn Fn(&[[f64; 3]]) -> Vec<f64>,
        active: usize,
        eps: f64,
        rays: &[(usize, [u32; 2])],
        normals: Option<&[Option<[f64; 3]>]>,
        grads: &mut [T],
    ) -> (MultiViewStep, Vec<Option<[f64; 3]>>, Vec<Option<Hit>>) {
        let cfg = &self.cfg;
        let lines = self.lines(rays);
        let r = model.config.render.radius;
        let clock = Instant::now();
        let hits = surface_hits(sdf, &lines, r, cfg.march_samples, cfg.refine, eps);
        let t_search = clock.elapsed().as_secs_f64();
        let costs: Vec<Option<(f64, f64, [f64; 3], [f64; 3])>> = hits
            .par_iter()
            .enumerate()
            .map(|(k, hit)| {
                let hit = (*hit)?;
                let (o, d) = lines[k];
                let gl = dot(hit.grad, hit.grad).sqrt();
                let gd = dot(hit.grad, d);
                if gl.is_nan() || gl <= 0.0 || -gd < cfg.min_cos as f64 * gl {
                    return None;
                }
                let n = match normals {
                    Some(ns) => ns[k]?,
                    None => hit.grad.map(|g| g / gl),
                };
                let (v, [x, y]) = rays[k];
                let (c, dc) = self.patch_cost(v, x as f64 + 0.5, y as f64 + 0.5, hit.t, n)?;
                let x = [0, 1, 2].map(|q| o[q] + hit.t * d[q]);
                Some((c, dc / gd, x, n))
            })
            .collect();
        let used: Vec<_> = costs.iter().flatten().collect();
        let t_patch = clock.elapsed().as_secs_f64() - t_search;
        let mut out = MultiViewStep {
            seconds: [t_search, t_patch, 0.0],
            rays: rays.len(),
            hits: hits.iter().flatten().count(),
            used: used.len(),
            ..Default::default()
        };
        let used_normals = costs.iter().map(|c| c.map(|c| c.3)).collect();
        if used.is_empty() {
            return (out, used_normals, hits);
        }
        let nu = used.len() as f64;
        let w = weight / nu;
        out.mean_cost = used.iter().map(|u| u.0).sum::<f64>() / nu;
        out.loss = weight * out.mean_cost;
        let pts: Vec<[T; 3]> = used.iter().map(|u| u.2.map(T::from_f64)).collect();
        // ∂L/∂f(x*) = (∂L/∂t*)·(∂t*/∂f) = (w·∂cost/∂t*)·(−1/(∇f·d)).
        let wts: Vec<T> = used.iter().map(|u| T::from_f64(-w * u.1)).collect();
        model.sdf_weighted_grad(params, &pts, &wts, active, grads);
        out.seconds[2] = clock.elapsed().as_secs_f64() - t_search - t_patch;
        (out, used_normals, hits)
    }
}

impl MultiViewPrior {
    /// The unit rays `(o, d)` through the centres of pixels `rays[i] = (view, [x, y])`.
    fn lines(&self, rays: &[(usize, [u32; 2])]) -> Vec<([f64; 3], [f64; 3])> {
        rays.iter()
            .map(|&(v, [x, y])| {
                let v = &self.views[v];
                let d = mul(&v.m, [x as f64 + 0.5, y as f64 + 0.5, 1.0]);
                let l = dot(d, d).sqrt();
                (v.c, d.map(|q| q / l))
            })
            .collect()
    }

    /// The sweep of [`CarveConfig`] on one ray: `Some(t_b)` when a hypothesis behind the
    /// surface point `t` (normal `n`) passes both tests, `None` when none does; the outer
    /// `None` when the surface point itself has no cost, or one under `min_gain` (no
    /// hypothesis could gain enough: not swept).
    fn sweep(
        &self,
        cv: &CarveConfig,
        view: usize,
        px: [u32; 2],
        t: f64,
        n: [f64; 3],
    ) -> Option<Option<f64>> {
        let (u, v) = (px[0] as f64 + 0.5, px[1] as f64 + 0.5);
        let (c0, _) = self.patch_cost_k(view, u, v, t, n, cv.top_k)?;
        if c0 < cv.min_gain as f64 {
            // No hypothesis can gain enough: not swept.
            return None;
        }
        let dt = cv.range as f64 / cv.hypotheses as f64;
        let best = (1..=cv.hypotheses)
            .filter_map(|j| {
                let tj = t + j as f64 * dt;
                self.patch_cost_k(view, u, v, tj, n, cv.top_k)
                    .map(|(c, _)| (c, tj))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0));
        Some(best.and_then(|(c, tb)| {
            (c < cv.max_cost as f64 && c0 - c >= cv.min_gain as f64).then_some(tb)
        }))
    }

    /// The depth-sweep carving ([`CarveConfig`]) on explicit rays, its gradient added into
    /// `grads` (arguments as [`Self::loss_grad`]; `hits`: the rays' surface crossings when the
    /// prior already found them): the plan of [`Self::carve_plan`], then [`carve_loss_grad`].
    /// Does nothing without a `carve` section.
    #[allow(clippy::too_many_arguments)]
    fn carve_grad<T: Real>(
        &self,
        model: &NeusModel,
        params: &[T],
        sdf: &dyn Fn(&[[f64; 3]]) -> Vec<f64>,
        active: usize,
        eps: f64,
        rays: &[(usize, [u32; 2])],
        hits: Option<&[Option<Hit>]>,
        grads: &mut [T],
    ) -> CarveStep {
        let Some(cv) = self.cfg.carve.as_ref() else {
            return CarveStep::default();
        };
        let lines = self.lines(rays);
        let found;
        let hits = match hits {
            Some(h) => h,
            None => {
                let r = model.config.render.radius;
                found = surface_hits(sdf, &lines, r, self.cfg.march_samples, self.cfg.refine, eps);
                &found
            }
        };
        let (mut out, plan) = self.carve_plan_from(cv, &lines, hits, rays);
        if !plan.is_empty() {
            out.loss = carve_loss_grad(cv, model, params, sdf, &plan, active, grads);
        }
        out
    }

    /// Which of `rays` the sweep carves, and where ([`CarveConfig`]): the step's counts (no
    /// loss yet) and one [`CarvedRay`] per carved ray. `r`: the half-size of the scene box.
    pub fn carve_plan(
        &self,
        r: f32,
        sdf: &dyn Fn(&[[f64; 3]]) -> Vec<f64>,
        eps: f64,
        rays: &[(usize, [u32; 2])],
    ) -> (CarveStep, Vec<CarvedRay>) {
        let Some(cv) = self.cfg.carve.as_ref() else {
            return (CarveStep::default(), Vec::new());
        };
        let lines = self.lines(rays);
        let hits = surface_hits(sdf, &lines, r, self.cfg.march_samples, self.cfg.refine, eps);
        self.carve_plan_from(cv, &lines, &hits, rays)
    }

    /// [`Self::carve_plan`] from the rays' unit lines and surface crossings.
    fn carve_plan_from(
        &self,
        cv: &CarveConfig,
        lines: &[([f64; 3], [f64; 3])],
        hits: &[Option<Hit>],
        rays: &[(usize, [u32; 2])],
    ) -> (CarveStep, Vec<CarvedRay>) {
        let mut out = CarveStep::default();
        let min_cos = self.cfg.min_cos as f64;
        let swept: Vec<Option<Option<(f64, f64)>>> = hits
            .par_iter()
            .enumerate()
            .map(|(k, hit)| {
                let hit = (*hit)?;
                let d = lines[k].1;
                let gl = dot(hit.grad, hit.grad).sqrt();
                if gl.is_nan() || gl <= 0.0 || -dot(hit.grad, d) < min_cos * gl {
                    return None;
                }
                let n = hit.grad.map(|g| g / gl);
                let (v, px) = rays[k];
                self.sweep(cv, v, px, hit.t, n)
                    .map(|b| b.map(|tb| (hit.t, tb)))
            })
            .collect();
        out.swept = swept.iter().flatten().count();
        let dt = cv.range as f64 / cv.hypotheses as f64;
        let plan: Vec<CarvedRay> = swept
            .iter()
            .enumerate()
            .filter_map(|(k, s)| {
                let (t, tb) = s.flatten()?;
                let (o, d) = lines[k];
                let at = |s: f64| [0, 1, 2].map(|q| o[q] + s * d[q]);
                let end = (t + cv.span as f64 * (tb - t)).min(tb - 2.0 * dt);
                let mut free = Vec::new();
                let mut s = t;
                while s <= end {
                    free.push((at(s), (cv.tau as f64).min(0.5 * (tb - s))));
                    s += dt;
                }
                Some(CarvedRay {
                    t,
                    t_b: tb,
                    free,
                    surface: at(tb),
                })
            })
            .collect();
        out.carved = plan.len();
        if !plan.is_empty() {
            out.mean_depth = plan.iter().map(|c| c.t_b - c.t).sum::<f64>() / plan.len() as f64;
        }
        (out, plan)
    }
}

/// One ray the depth sweep carves ([`CarveConfig`]); points in the normalised frame.
#[derive(Clone, Debug, PartialEq)]
pub struct CarvedRay {
    /// The surface point's distance `t*` along the unit ray.
    pub t: f64,
    /// The best hypothesis's distance `t_b`.
    pub t_b: f64,
    /// The carved span's points and the SDF the hinge asks for at each.
    pub free: Vec<([f64; 3], f64)>,
    /// The point at `t_b`.
    pub surface: [f64; 3],
}

/// The carving loss on fixed points (the plan's positions are held, as the sample points of
/// the other SDF priors are): `L = weight · mean over rays of (mean over the ray's free points
/// of max(0, τ − f) + surface_weight·|f(x_b)|)`; `∂L/∂θ` added into `grads` (SDF network and
/// hash grid only). `sdf` evaluates the field at points in the precision of `params`. Returns
/// `L` (0 for an empty plan).
pub fn carve_loss_grad<T: Real>(
    cv: &CarveConfig,
    model: &NeusModel,
    params: &[T],
    sdf: &dyn Fn(&[[f64; 3]]) -> Vec<f64>,
    plan: &[CarvedRay],
    active: usize,
    grads: &mut [T],
) -> f64 {
    if plan.is_empty() {
        return 0.0;
    }
    let mut pts: Vec<[f64; 3]> = Vec::new();
    for c in plan {
        pts.extend(c.free.iter().map(|(x, _)| *x));
        pts.push(c.surface);
    }
    let f = sdf(&pts);
    let w = cv.weight as f64 / plan.len() as f64;
    let mut loss = 0.0;
    let mut wts = Vec::with_capacity(pts.len());
    let mut i = 0;
    for c in plan {
        let m = w / c.free.len().max(1) as f64;
        for &(_, tau) in &c.free {
            let fv = f[i];
            i += 1;
            if fv < tau {
                loss += m * (tau - fv);
                wts.push(T::from_f64(-m));
            } else {
                wts.push(T::ZERO);
            }
        }
        let fv = f[i];
        i += 1;
        let ms = w * cv.surface_weight as f64;
        loss += ms * fv.abs();
        wts.push(T::from_f64(ms * fv.signum()));
    }
    let pts: Vec<[T; 3]> = pts.iter().map(|x| x.map(T::from_f64)).collect();
    model.sdf_weighted_grad(params, &pts, &wts, active, grads);
    loss
}

/// A loss weight at `step` of a run of `iterations` steps: 0 before `start`, then `weight`, or
/// the linear ramp from `weight` at `start` to `end` at step `iterations − 1` when `end` is set.
pub(crate) fn ramp_weight(
    weight: f32,
    end: Option<f32>,
    start: u64,
    step: u64,
    iterations: u64,
) -> f32 {
    if step < start {
        return 0.0;
    }
    match end {
        None => weight,
        Some(end) => {
            let last = iterations.saturating_sub(1);
            if last <= start {
                return weight;
            }
            let f = (step.min(last) - start) as f64 / (last - start) as f64;
            (weight as f64 + (end as f64 - weight as f64) * f) as f32
        }
    }
}

/// The first `count` rays of `batch` inside the mask (all of them without masks), as
/// `(view, [x, y])`.
pub(crate) fn masked_rays(batch: &Batch, count: usize) -> Vec<(usize, [u32; 2])> {
    (0..batch.len())
        .filter(|&i| batch.mask.get(i).is_none_or(|&m| m >= 0.5))
        .take(count)
        .map(|i| (batch.views[i] as usize, batch.pixels[i]))
        .collect()
}

/// The field's SDF (channel 0, `active` hash levels) at f64 points, evaluated in f32.
pub(crate) fn sdf_f64<'a>(
    model: &'a NeusModel,
    params: &'a [f32],
    active: usize,
) -> impl Fn(&[[f64; 3]]) -> Vec<f64> + 'a {
    move |pts: &[[f64; 3]]| -> Vec<f64> {
        let p32: Vec<[f32; 3]> = pts.iter().map(|p| p.map(|v| v as f32)).collect();
        model
            .sdf(params, &p32, active)
            .into_iter()
            .map(|v| v as f64)
            .collect()
    }
}

/// A ray's first surface crossing: distance `t` along the unit direction, and the SDF gradient
/// there (central differences).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Hit {
    /// Distance along the unit ray.
    pub(crate) t: f64,
    /// The SDF gradient there (central differences).
    pub(crate) grad: [f64; 3],
}

/// The first `+ → −` crossing of `sdf` along each ray `(o, d)` (unit `d`) inside the box
/// `[-r, r]³`: `samples` evenly spaced values over the ray's span of the box, then `refine`
/// Illinois steps on the bracket, then the gradient by central differences of step `eps`.
/// `sdf` evaluates a batch of points. `None` for a ray that misses the box, starts inside
/// (`f < 0` at its first sample) or finds no crossing.
pub(crate) fn surface_hits(
    sdf: &dyn Fn(&[[f64; 3]]) -> Vec<f64>,
    rays: &[([f64; 3], [f64; 3])],
    r: f32,
    samples: usize,
    refine: usize,
    eps: f64,
) -> Vec<Option<Hit>> {
    let at = |(o, d): ([f64; 3], [f64; 3]), t: f64| [0, 1, 2].map(|q| o[q] + t * d[q]);
    let spans: Vec<Option<(f64, f64)>> = rays
        .iter()
        .map(|&(o, d)| {
            ray_aabb(o.map(|v| v as f32), d.map(|v| v as f32), r).map(|(a, b)| (a as f64, b as f64))
        })
        .collect();
    let mut pts = Vec::with_capacity(rays.len() * samples);
    for (k, span) in spans.iter().enumerate() {
        if let Some((t0, t1)) = *span {
            let dt = (t1 - t0) / samples as f64;
            for s in 0..samples {
                pts.push(at(rays[k], t0 + (s as f64 + 0.5) * dt));
            }
        }
    }
    let f = sdf(&pts);
    // Brackets `(t_a, f_a, t_b, f_b)` with `f_a > 0 ≥ f_b`.
    let mut brackets: Vec<Option<(f64, f64, f64, f64)>> = Vec::with_capacity(rays.len());
    let mut off = 0;
    for span in &spans {
        let Some((t0, t1)) = *span else {
            brackets.push(None);
            continue;
        };
        let dt = (t1 - t0) / samples as f64;
        let fs = &f[off..off + samples];
        off += samples;
        let b = if fs[0] < 0.0 {
            None
        } else {
            (0..samples - 1)
                .find(|&s| fs[s] > 0.0 && fs[s + 1] <= 0.0)
                .map(|s| {
                    let ta = t0 + (s as f64 + 0.5) * dt;
                    (ta, fs[s], ta + dt, fs[s + 1])
                })
        };
        brackets.push(b);
    }
    // Illinois: the regula-falsi point, halving the kept end's value when an end is kept twice.
    let mut side = vec![0i8; rays.len()];
    for _ in 0..refine {
        let live: Vec<usize> = (0..rays.len())
            .filter(|&k| brackets[k].is_some_and(|b| b.3 < 0.0))
            .collect();
        if live.is_empty() {
            break;
        }
        let ts: Vec<f64> = live
            .iter()
            .map(|&k| {
                let (ta, fa, tb, fb) = brackets[k].expect("live");
                ta + (tb - ta) * fa / (fa - fb)
            })
            .collect();
        let p: Vec<[f64; 3]> = live
            .iter()
            .zip(&ts)
            .map(|(&k, &t)| at(rays[k], t))
            .collect();
        let fm = sdf(&p);
        for ((&k, &t), &v) in live.iter().zip(&ts).zip(&fm) {
            let b = brackets[k].as_mut().expect("live");
            if v > 0.0 {
                *b = (t, v, b.2, if side[k] == 1 { b.3 * 0.5 } else { b.3 });
                side[k] = 1;
            } else {
                *b = (b.0, if side[k] == -1 { b.1 * 0.5 } else { b.1 }, t, v);
                side[k] = -1;
            }
        }
    }
    // The crossing: the last regula-falsi point of the bracket (exact when `f_b = 0`).
    let ts: Vec<Option<f64>> = brackets
        .iter()
        .map(|b| b.map(|(ta, fa, tb, fb)| ta + (tb - ta) * fa / (fa - fb)))
        .collect();
    let mut taps = Vec::new();
    for (k, t) in ts.iter().enumerate() {
        if let Some(t) = *t {
            let x = at(rays[k], t);
            for q in 0..3 {
                for s in [1.0, -1.0] {
                    let mut y = x;
                    y[q] += s * eps;
                    taps.push(y);
                }
            }
        }
    }
    let ft = sdf(&taps);
    let mut i = 0;
    ts.iter()
        .map(|t| {
            t.map(|t| {
                let g = [0, 1, 2].map(|q| (ft[i + 2 * q] - ft[i + 2 * q + 1]) / (2.0 * eps));
                i += 6;
                Hit { t, grad: g }
            })
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// A camera at `c` looking at `target`, `w×h` pixels, focal `f` pixels (`sim::rig::look_at`,
    /// with `+z` up).
    pub(crate) fn look_at(c: Vector3<f64>, target: Vector3<f64>, w: u32, h: u32, f: f64) -> Camera {
        let k = crate::sim::rig::centred_intrinsics(f, w, h);
        crate::sim::rig::look_at(c, target, Vector3::z(), k, w, h)
    }

    /// A smooth texture on the plane `z = 0`.
    fn texture(x: f64, y: f64) -> f64 {
        0.5 + 0.2 * (9.0 * x).sin() * (7.0 * y + 0.3).cos() + 0.15 * (13.0 * x - 5.0 * y).sin()
    }

    /// The image of the textured plane `z = 0` from `cam` (grey in every channel).
    pub(crate) fn render_plane(cam: &Camera) -> RgbImage {
        let mut img = RgbImage::new(cam.width as usize, cam.height as usize);
        for y in 0..cam.height as usize {
            for x in 0..cam.width as usize {
                let (o, d) = cam.ray(x as f64 + 0.5, y as f64 + 0.5);
                let t = -o.z / d.z;
                let p = o + t * d;
                let g = texture(p.x, p.y) as f32;
                img.set(x, y, [g, g, g]);
            }
        }
        img
    }

    fn plane_rig() -> (Vec<Camera>, Vec<RgbImage>) {
        let cams: Vec<Camera> = [
            Vector3::new(0.0, -0.4, 2.0),
            Vector3::new(0.5, -0.3, 1.9),
            Vector3::new(-0.5, -0.2, 1.9),
            Vector3::new(0.1, 0.5, 1.9),
        ]
        .into_iter()
        .map(|c| look_at(c, Vector3::zeros(), 96, 80, 90.0))
        .collect();
        let imgs = cams.iter().map(render_plane).collect();
        (cams, imgs)
    }

    fn prior(cfg: MultiViewConfig) -> (MultiViewPrior, Vec<Camera>) {
        let (cams, imgs) = plane_rig();
        (MultiViewPrior::new(cfg, &cams, &imgs), cams)
    }

    /// The true distance along the ray of view 0 through pixel `(u, v)` to the plane `z = 0`.
    pub(crate) fn true_t(cam: &Camera, u: f64, v: f64) -> f64 {
        let (o, d) = cam.ray(u, v);
        -o.z / d.z
    }

    #[test]
    fn ncc_gradient_matches_central_differences() {
        let a: Vec<f64> = (0..9).map(|i| ((i * 7) % 5) as f64 * 0.1 + 0.2).collect();
        let b: Vec<f64> = (0..9).map(|i| ((i * 3) % 4) as f64 * 0.13 + 0.1).collect();
        let mut g = vec![0.0; 9];
        let c = ncc(&a, &b, &mut g);
        assert!(c.abs() <= 1.0);
        for k in 0..9 {
            let h = 1e-6;
            let mut bp = b.clone();
            bp[k] += h;
            let mut bm = b.clone();
            bm[k] -= h;
            let mut tmp = vec![0.0; 9];
            let num = (ncc(&a, &bp, &mut tmp) - ncc(&a, &bm, &mut tmp)) / (2.0 * h);
            assert!((num - g[k]).abs() < 1e-7, "k {k}: {num} vs {}", g[k]);
        }
        // A gain and an offset do not change it; an identical patch scores 1.
        let b2: Vec<f64> = a.iter().map(|x| 0.3 * x + 0.1).collect();
        assert!((ncc(&a, &b2, &mut g) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn patch_cost_is_lowest_at_the_true_depth_and_its_derivative_is_right() {
        let (p, cams) = prior(MultiViewConfig {
            weight: 1.0,
            sources: 3,
            top_k: 3,
            ..Default::default()
        });
        let n = [0.0, 0.0, 1.0];
        for (u, v) in [(48.5, 40.5), (40.5, 33.5), (57.5, 47.5)] {
            let t0 = true_t(&cams[0], u, v);
            let (c0, _) = p.patch_cost(0, u, v, t0, n).expect("seen");
            assert!(c0 < 0.02, "cost at the truth {c0}");
            for dt in [-0.15, -0.05, 0.05, 0.15] {
                let t = t0 + dt;
                let (c, g) = p.patch_cost(0, u, v, t, n).expect("seen");
                assert!(c > c0, "cost {c} at offset {dt} not above {c0}");
                // Descent moves towards the truth.
                assert!(g * dt > 0.0, "slope {g} at offset {dt}");
                let h = 1e-7;
                let cp = p.patch_cost(0, u, v, t + h, n).unwrap().0;
                let cm = p.patch_cost(0, u, v, t - h, n).unwrap().0;
                let num = (cp - cm) / (2.0 * h);
                assert!(
                    (num - g).abs() <= 1e-4 * (1.0 + g.abs()),
                    "∂cost/∂t {g} against {num} at ({u}, {v}) offset {dt}"
                );
            }
        }
    }

    #[test]
    fn untextured_patches_edge_on_planes_and_patches_off_the_image_are_refused() {
        let (cams, mut imgs) = plane_rig();
        for p in &mut imgs[0].data {
            *p = 0.4;
        }
        let flat = MultiViewPrior::new(MultiViewConfig::default(), &cams, &imgs);
        let t = true_t(&cams[0], 48.5, 40.5);
        assert!(flat.patch_cost(0, 48.5, 40.5, t, [0.0, 0.0, 1.0]).is_none());
        let (p, cams) = prior(MultiViewConfig::default());
        let t = true_t(&cams[0], 48.5, 40.5);
        assert!(p.patch_cost(0, 1.5, 40.5, t, [0.0, 0.0, 1.0]).is_none());
        // A plane containing the ray: every patch point's ray is parallel to it.
        let (_, d) = cams[0].ray(48.5, 40.5);
        let side = Vector3::new(1.0, 0.0, 0.0).cross(&d).normalize();
        assert!(p
            .patch_cost(0, 48.5, 40.5, t, [side.x, side.y, side.z])
            .is_none_or(|(c, g)| c.is_finite() && g.is_finite()));
        // NaN pixels: in the reference, no value; in a source, that source drops out.
        let (cams, mut imgs) = plane_rig();
        let cfg3 = MultiViewConfig {
            sources: 3,
            top_k: 3,
            ..Default::default()
        };
        let clean = MultiViewPrior::new(cfg3.clone(), &cams, &imgs);
        let c_clean = clean.patch_cost(0, 48.5, 40.5, t + 0.05, [0.0, 0.0, 1.0]);
        for v in &mut imgs[1].data {
            *v = f32::NAN;
        }
        let src_nan = MultiViewPrior::new(cfg3, &cams, &imgs);
        let (c, g) = src_nan
            .patch_cost(0, 48.5, 40.5, t + 0.05, [0.0, 0.0, 1.0])
            .expect("two clean sources left");
        assert!(c.is_finite() && g.is_finite());
        assert_ne!(Some((c, g)), c_clean, "the NaN source still counted");
        imgs[0].set(48, 40, [f32::NAN; 3]);
        let ref_nan = MultiViewPrior::new(MultiViewConfig::default(), &cams, &imgs);
        assert!(ref_nan
            .patch_cost(0, 48.5, 40.5, t, [0.0, 0.0, 1.0])
            .is_none());
        // NaN depth: no panic, no value.
        assert!(p
            .patch_cost(0, 48.5, 40.5, f64::NAN, [0.0, 0.0, 1.0])
            .is_none());
    }

    /// The depth sweep, on the textured plane `z = 0` seen by four views from `z ≈ 2`: a false
    /// sheet at `z = 0.8` (the field `f = z − 0.8`; 8–17 pixels of disparity between the views,
    /// so its patches do not match) is carved down to the plane, every carved point
    /// lies in the empty space above it, and the true field (`f = z`) is left alone.
    #[test]
    fn carve_sweep_finds_the_true_plane_behind_a_false_sheet_and_spares_the_truth() {
        let cv = CarveConfig {
            range: 1.2,
            hypotheses: 120,
            top_k: 2,
            ..Default::default()
        };
        let dt = cv.range as f64 / cv.hypotheses as f64;
        let (p, cams) = prior(MultiViewConfig {
            weight: 1.0,
            sources: 3,
            top_k: 3,
            carve: Some(cv.clone()),
            ..Default::default()
        });
        let rays: Vec<(usize, [u32; 2])> = (0..4)
            .flat_map(|v| (0..5).map(move |i| (v, [36 + 6 * i, 30 + 4 * i])))
            .collect();
        let false_sheet = |pts: &[[f64; 3]]| pts.iter().map(|x| x[2] - 0.8).collect::<Vec<_>>();
        let (out, plan) = p.carve_plan(3.0, &false_sheet, 1e-5, &rays);
        assert_eq!(
            out.swept,
            rays.len(),
            "every false patch costs more than min_gain"
        );
        assert!(
            plan.len() >= rays.len() - 2,
            "{} of {} carved",
            plan.len(),
            rays.len()
        );
        for c in &plan {
            assert!(
                c.surface[2].abs() < 1.5 * dt,
                "best hypothesis at z {}",
                c.surface[2]
            );
            assert!(!c.free.is_empty() && c.t_b > c.t);
            for &(x, tau) in &c.free {
                assert!(
                    x[2] > 0.0 && x[2] <= 0.8 + 1e-6,
                    "carved point at z {}",
                    x[2]
                );
                assert!(tau > 0.0 && tau <= cv.tau as f64 + 1e-12);
            }
        }
        assert!(
            (out.mean_depth - plan.iter().map(|c| c.t_b - c.t).sum::<f64>() / plan.len() as f64)
                .abs()
                < 1e-12
        );
        // The truth: its patches match, so nothing is swept or carved.
        let truth = |pts: &[[f64; 3]]| pts.iter().map(|x| x[2]).collect::<Vec<_>>();
        let (out, plan) = p.carve_plan(3.0, &truth, 1e-5, &rays);
        assert_eq!((out.swept, plan.len()), (0, 0), "{out:?}");
        // Without a carve section: nothing at all.
        let (p0, _) = prior(MultiViewConfig::default());
        assert!(p0.carve_plan(3.0, &false_sheet, 1e-5, &rays).1.is_empty());
        let _ = cams;
    }

    #[test]
    fn surface_search_finds_the_first_crossing() {
        // Two spheres along the x axis: the ray from −3 meets the nearer one first.
        let sdf = |pts: &[[f64; 3]]| -> Vec<f64> {
            pts.iter()
                .map(|p| {
                    let a = ((p[0] + 0.5).powi(2) + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.2;
                    let b = ((p[0] - 0.5).powi(2) + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.2;
                    a.min(b)
                })
                .collect()
        };
        let rays = [
            ([-3.0, 0.0, 0.0], [1.0, 0.0, 0.0]),
            ([-3.0, 0.1, 0.0], [1.0, 0.0, 0.0]),
            ([-3.0, 0.9, 0.0], [1.0, 0.0, 0.0]),
            ([0.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        ];
        let hits = surface_hits(&sdf, &rays, 1.0, 64, 20, 1e-5);
        let h0 = hits[0].expect("hit");
        assert!((h0.t - 2.3).abs() < 1e-9, "{}", h0.t);
        assert!((h0.grad[0] + 1.0).abs() < 1e-6);
        let h1 = hits[1].expect("hit");
        let want = 2.5 - (0.04f64 - 0.01).sqrt();
        assert!((h1.t - want).abs() < 1e-8, "{} vs {want}", h1.t);
        assert!(hits[2].is_none(), "a miss");
        assert!(hits[3].is_none(), "outside at the start but never crossing");
        let inside = surface_hits(
            &sdf,
            &[([-0.5, 0.0, 0.0], [1.0, 0.0, 0.0])],
            1.0,
            64,
            4,
            1e-5,
        );
        assert!(inside[0].is_none(), "starts inside");
    }

    #[test]
    fn config_checks_name_the_key() {
        assert!(MultiViewConfig::default().invalid().is_none());
        assert!(!MultiViewConfig::default().enabled());
        let bad = [
            MultiViewConfig {
                weight: f32::NAN,
                ..Default::default()
            },
            MultiViewConfig {
                top_k: 9,
                ..Default::default()
            },
            MultiViewConfig {
                min_cos: 1.0,
                ..Default::default()
            },
            MultiViewConfig {
                patch_step: 0.0,
                ..Default::default()
            },
            MultiViewConfig {
                march_samples: 1 << 20,
                ..Default::default()
            },
            MultiViewConfig {
                final_weight: Some(-1.0),
                ..Default::default()
            },
        ];
        let keys = [
            "weight",
            "top_k",
            "min_cos",
            "patch_step",
            "march_samples",
            "final_weight",
        ];
        for (c, k) in bad.iter().zip(keys) {
            let (key, _, _) = c.invalid().expect("refused");
            assert_eq!(key, format!("train.multiview.{k}"));
        }
        let carve = |c: CarveConfig| MultiViewConfig {
            carve: Some(c),
            ..Default::default()
        };
        assert!(carve(CarveConfig::default()).invalid().is_none());
        type Edit = fn(&mut CarveConfig);
        let edits: [(&str, Edit); 8] = [
            ("weight", |c| c.weight = -1.0),
            ("top_k", |c| c.top_k = 9),
            ("hypotheses", |c| c.hypotheses = 1),
            ("range", |c| c.range = f32::NAN),
            ("max_cost", |c| c.max_cost = 0.0),
            ("min_gain", |c| c.min_gain = -0.1),
            ("span", |c| c.span = 0.0),
            ("tau", |c| c.tau = 0.0),
        ];
        for (k, edit) in edits {
            let mut c = CarveConfig::default();
            edit(&mut c);
            let (key, _, _) = carve(c).invalid().expect("refused");
            assert_eq!(key, format!("train.multiview.carve.{k}"));
        }
    }

    #[test]
    fn weight_ramps_from_the_start_step_to_the_last_step() {
        let constant = MultiViewConfig {
            weight: 2.0,
            start_step: 10,
            ..Default::default()
        };
        assert_eq!(constant.weight_at(9, 101), 0.0, "before the start");
        assert_eq!(constant.weight_at(10, 101), 2.0);
        assert_eq!(constant.weight_at(100, 101), 2.0);
        let ramp = MultiViewConfig {
            final_weight: Some(0.5),
            ..constant.clone()
        };
        assert_eq!(ramp.weight_at(9, 101), 0.0);
        assert_eq!(ramp.weight_at(10, 101), 2.0);
        // Step 55 is halfway from step 10 to the last step, 100.
        assert!((ramp.weight_at(55, 101) - 1.25).abs() < 1e-6);
        assert!((ramp.weight_at(100, 101) - 0.5).abs() < 1e-6);
        assert!(
            (ramp.weight_at(500, 101) - 0.5).abs() < 1e-6,
            "past the end"
        );
        // A run too short for a ramp keeps the start weight; off stays off.
        assert_eq!(ramp.weight_at(10, 11), 2.0);
        let off = MultiViewConfig {
            weight: 0.0,
            final_weight: Some(3.0),
            ..Default::default()
        };
        assert_eq!(off.weight_at(50, 101), 0.0);
    }
}
