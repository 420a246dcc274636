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
        if !self.enabled() || step < self.start_step {
            return 0.0;
        }
        match self.final_weight {
            None => self.weight,
            Some(end) => {
                let last = iterations.saturating_sub(1);
                if last <= self.start_step {
                    return self.weight;
                }
                let f = (step.min(last) - self.start_step) as f64 / (last - self.start_step) as f64;
                (self.weight as f64 + (end as f64 - self.weight as f64) * f) as f32
            }
        }
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
        let k = cfg.top_k.min(costs.len());
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
        let rays: Vec<(usize, [u32; 2])> = (0..batch.len())
            .filter(|&i| batch.mask.get(i).is_none_or(|&m| m >= 0.5))
            .take(cfg.rays)
            .map(|i| (batch.views[i] as usize, batch.pixels[i]))
            .collect();
        let sdf = |pts: &[[f64; 3]]| -> Vec<f64> {
            let p32: Vec<[f32; 3]> = pts.iter().map(|p| p.map(|v| v as f32)).collect();
            model
                .sdf(params, &p32, active)
                .into_iter()
                .map(|v| v as f64)
                .collect()
        };
        let eps = model.fd_eps(active);
        let (out, _) = self.loss_grad(weight, model, params, &sdf, active, eps, &rays, None, grads);
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
        let cfg = &self.cfg;
        let lines: Vec<([f64; 3], [f64; 3])> = rays
            .iter()
            .map(|&(v, [x, y])| {
                let v = &self.views[v];
                let d = mul(&v.m, [x as f64 + 0.5, y as f64 + 0.5, 1.0]);
                let l = dot(d, d).sqrt();
                (v.c, d.map(|q| q / l))
            })
            .collect();
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
            return (out, used_normals);
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
        (out, used_normals)
    }
}

/// A ray's first surface crossing: distance `t` along the unit direction, and the SDF gradient
/// there (central differences).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Hit {
    t: f64,
    grad: [f64; 3],
}

/// The first `+ → −` crossing of `sdf` along each ray `(o, d)` (unit `d`) inside the box
/// `[-r, r]³`: `samples` evenly spaced values over the ray's span of the box, then `refine`
/// Illinois steps on the bracket, then the gradient by central differences of step `eps`.
/// `sdf` evaluates a batch of points. `None` for a ray that misses the box, starts inside
/// (`f < 0` at its first sample) or finds no crossing.
fn surface_hits(
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
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// A camera at `c` looking at `target`, `w×h` pixels, focal `f` pixels (`sim::rig::look_at`,
    /// with `+z` up).
    fn look_at(c: Vector3<f64>, target: Vector3<f64>, w: u32, h: u32, f: f64) -> Camera {
        let k = crate::sim::rig::centred_intrinsics(f, w, h);
        crate::sim::rig::look_at(c, target, Vector3::z(), k, w, h)
    }

    /// A smooth texture on the plane `z = 0`.
    fn texture(x: f64, y: f64) -> f64 {
        0.5 + 0.2 * (9.0 * x).sin() * (7.0 * y + 0.3).cos() + 0.15 * (13.0 * x - 5.0 * y).sin()
    }

    /// The image of the textured plane `z = 0` from `cam` (grey in every channel).
    fn render_plane(cam: &Camera) -> RgbImage {
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
    fn true_t(cam: &Camera, u: f64, v: f64) -> f64 {
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
