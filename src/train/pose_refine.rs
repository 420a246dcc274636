//! Pose refinement while training (`[train.pose_refine]`, off by default): one
//! [`PoseCorrection`] per training view, learned with the field from the loss's gradient with
//! respect to the rays ([`crate::render::NeusModel::forward_backward_rays`]).
//!
//! What it follows:
//! - the parametrisation and its place (a correction per frame in SO(3)×R³, zero at the start,
//!   its own Adam) from nerfstudio's camera optimizer (`nerfstudio/cameras/camera_optimizers.py`);
//! - an exponentially decaying learning rate, as BARF's (Lin et al. 2021, §4: `1e-3` to
//!   `1e-5`), a tenth of it here (`1e-4` to `1e-6`): on the `blob` scene at `quick` with every
//!   pose off by 0.5° and 3 mm, BARF's rates left the cameras 3.3 px from the truth on average,
//!   these 0.7 px (from 6.2; docs/pose-refinement.md). BARF's coarse-to-fine argument holds
//!   here through the hash grid's progressive levels (`model.field.hash_grid.progressive`);
//! - a small L2 penalty `weight·(|ω|² + |t|²)` on each correction;
//! - the gauge held fixed: the images cannot tell the cameras and the object moved together
//!   (a similarity of the whole scene), and a free drift of that kind moves the mesh away from
//!   the imported frame, which is the one a user evaluates in. After each update the
//!   corrections' common part, the small similarity `(θ, δ, σ)` (rotation, translation, scale
//!   about the origin) that best explains them in least squares, is removed ([`remove_gauge`]),
//!   so the refined cameras keep the imported ones' mean frame, as BARF's evaluation aligns
//!   them to it after the fact (Lin et al. 2021, §4, Procrustes).
//!
//! The corrected rays replace the batch's rays before rendering, so the depth prior, when on,
//! sees them too. Units: `ω` in radians, `t` in the normalised frame's length (the object's
//! bounding sphere has radius 1).

use super::pose::{exp_so3, PoseCorrection};
use crate::render::{ray_grad, RayGradCell};
use crate::scene::Camera;
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Settings of pose refinement (`[train.pose_refine]`). Written into a run's configuration only
/// when on, so the configurations and training hashes of runs without it stay what they were.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PoseRefineConfig {
    /// Learn a correction of every training view's pose (false).
    pub enabled: bool,
    /// Adam's learning rate at the start of refinement (1e-4; see the module doc).
    pub lr: f64,
    /// Its value at the end, reached exponentially (1e-6).
    pub lr_end: f64,
    /// Share of the run before the corrections start moving (0.1: the field has its coarse
    /// shape by then; from step 0 the corrections fit the initial sphere's silhouette).
    pub start: f64,
    /// Share of the run after which the corrections stop moving (1.0: to the end).
    pub until: f64,
    /// Weight of the L2 penalty on `(ω, t)` (1e-3).
    pub weight: f64,
}

impl Default for PoseRefineConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            lr: 1e-4,
            lr_end: 1e-6,
            start: 0.1,
            until: 1.0,
            weight: 1e-3,
        }
    }
}

impl PoseRefineConfig {
    /// Whether every field is at its default (refinement off): the configuration leaves it out.
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// The first invalid field as `(key, value, why)`.
    pub fn invalid(&self) -> Option<(&'static str, f64, &'static str)> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !pos(self.lr) {
            return Some(("train.pose_refine.lr", self.lr, "must be finite and > 0"));
        }
        if !pos(self.lr_end) {
            return Some((
                "train.pose_refine.lr_end",
                self.lr_end,
                "must be finite and > 0",
            ));
        }
        if !(self.until > 0.0 && self.until <= 1.0) {
            return Some(("train.pose_refine.until", self.until, "must be in (0, 1]"));
        }
        if !(self.start >= 0.0 && self.start < self.until) {
            return Some((
                "train.pose_refine.start",
                self.start,
                "must be in [0, until)",
            ));
        }
        if !(self.weight.is_finite() && self.weight >= 0.0) {
            return Some((
                "train.pose_refine.weight",
                self.weight,
                "must be finite and ≥ 0",
            ));
        }
        None
    }

    /// The learning rate at `step` of `iterations`: exponential from `lr` to `lr_end` over the
    /// refined share of the run `[start, until)`, 0 outside it.
    pub fn lr_at(&self, step: u64, iterations: u64) -> f64 {
        let n = iterations as f64;
        let (a, b) = (self.start * n, (self.until * n).max(1.0));
        let s = (step as f64 - a) / (b - a).max(1.0);
        if !(0.0..1.0).contains(&s) {
            return 0.0;
        }
        self.lr * (self.lr_end / self.lr).powf(s)
    }
}

/// The corrections and their Adam moments: the part of the training state that refinement adds
/// (checkpointed as `pose.state`).
#[derive(Clone, Debug, PartialEq)]
pub struct PoseState {
    /// `[views]` corrections, in training-camera order.
    pub corrections: Vec<PoseCorrection>,
    /// `[views][6]` Adam's first and second moments of `(ω, t)`.
    pub m: Vec<[f64; 6]>,
    pub v: Vec<[f64; 6]>,
    /// Adam steps taken.
    pub t: u64,
}

impl PoseState {
    /// Zero corrections and moments for `views` views.
    pub fn new(views: usize) -> Self {
        Self {
            corrections: vec![PoseCorrection::default(); views],
            m: vec![[0.0; 6]; views],
            v: vec![[0.0; 6]; views],
            t: 0,
        }
    }

    /// `[views][18]` rows `ω, t, m, v` (the checkpoint's tensor).
    pub fn to_rows(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.corrections.len() * 18);
        for (i, c) in self.corrections.iter().enumerate() {
            out.extend(c.omega.iter().chain(c.t.iter()));
            out.extend(self.m[i]);
            out.extend(self.v[i]);
        }
        out
    }

    /// The inverse of [`Self::to_rows`]; `None` when the length is not a multiple of 18 or a
    /// value is not finite (or a second moment negative).
    pub fn from_rows(rows: &[f64], t: u64) -> Option<Self> {
        if !rows.len().is_multiple_of(18) || rows.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let mut s = Self::new(rows.len() / 18);
        for (i, r) in rows.chunks_exact(18).enumerate() {
            s.corrections[i] = PoseCorrection {
                omega: Vector3::new(r[0], r[1], r[2]),
                t: Vector3::new(r[3], r[4], r[5]),
            };
            s.m[i].copy_from_slice(&r[6..12]);
            s.v[i].copy_from_slice(&r[12..18]);
            if s.v[i].iter().any(|&v| v < 0.0) {
                return None;
            }
        }
        s.t = t;
        Some(s)
    }

    /// The cameras with the corrections applied: `R' = R(ω)ᵀ·R`, `C' = C + Rᵀ·t` (the corrected
    /// camera-to-world is `C2W·[R(ω) | t]`, [`PoseCorrection`]). `cameras` in the frame the
    /// corrections were learned in (the normalised one).
    pub fn corrected(&self, cameras: &[Camera]) -> Vec<Camera> {
        cameras
            .iter()
            .zip(&self.corrections)
            .map(|(c, p)| Camera {
                r: exp_so3(&p.omega).transpose() * c.r,
                center: c.center + c.r.transpose() * p.t,
                ..c.clone()
            })
            .collect()
    }
}

/// What one refinement update did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PoseStep {
    /// Learning rate used (0 after `until`).
    pub lr: f64,
    /// Mean over views of `|ω|` (radians) and `|t|` (normalised units) after the update.
    pub mean_rotation: f64,
    pub mean_translation: f64,
}

/// The trainer's side of refinement: the cameras' rotations, the batch's uncorrected rays and
/// the per-ray gradient cells, reused between steps.
pub struct PoseRefiner {
    config: PoseRefineConfig,
    /// `[views]` camera-to-world rotations `Rᵀ` and centres (normalised frame).
    c2w: Vec<Matrix3<f64>>,
    centres: Vec<Vector3<f64>>,
    origins: Vec<[f32; 3]>,
    dirs: Vec<[f32; 3]>,
    cells: Vec<RayGradCell>,
    grads: Vec<[f64; 6]>,
}

impl PoseRefiner {
    /// For the training cameras `cameras` (normalised frame, training order).
    pub fn new(config: &PoseRefineConfig, cameras: &[Camera]) -> Self {
        Self {
            config: config.clone(),
            c2w: cameras.iter().map(|c| c.r.transpose()).collect(),
            centres: cameras.iter().map(|c| c.center).collect(),
            origins: Vec::new(),
            dirs: Vec::new(),
            cells: Vec::new(),
            grads: vec![[0.0; 6]; cameras.len()],
        }
    }

    /// Number of views.
    pub fn n_views(&self) -> usize {
        self.c2w.len()
    }

    /// Replaces each ray of view `views[i]` by its corrected ray (keeping the uncorrected one
    /// for the update), and readies one gradient cell per ray.
    pub fn correct(
        &mut self,
        state: &PoseState,
        views: &[u32],
        origins: &mut [[f32; 3]],
        dirs: &mut [[f32; 3]],
    ) {
        self.origins.clear();
        self.origins.extend_from_slice(origins);
        self.dirs.clear();
        self.dirs.extend_from_slice(dirs);
        let rot: Vec<Matrix3<f64>> = state
            .corrections
            .iter()
            .map(|p| exp_so3(&p.omega))
            .collect();
        for (i, &v) in views.iter().enumerate() {
            let (c, p) = (&self.c2w[v as usize], &state.corrections[v as usize]);
            let o = Vector3::from(origins[i].map(f64::from));
            let d = Vector3::from(dirs[i].map(f64::from));
            let o2 = o + c * p.t;
            let d2 = c * (rot[v as usize] * (c.transpose() * d));
            origins[i] = [o2.x as f32, o2.y as f32, o2.z as f32];
            dirs[i] = [d2.x as f32, d2.y as f32, d2.z as f32];
        }
        if self.cells.len() < views.len() {
            self.cells.resize_with(views.len(), Default::default);
        }
    }

    /// The gradient cells of the batch [`Self::correct`] last saw.
    pub fn cells(&self) -> &[RayGradCell] {
        &self.cells[..self.origins.len()]
    }

    /// One Adam step of the corrections from the cells' gradients (and the L2 penalty) at
    /// `step` of `iterations`. A batch with a non-finite ray gradient changes nothing.
    pub fn update(
        &mut self,
        state: &mut PoseState,
        views: &[u32],
        step: u64,
        iterations: u64,
    ) -> PoseStep {
        let lr = self.config.lr_at(step, iterations);
        let mut report = PoseStep {
            lr,
            ..Default::default()
        };
        let n = state.corrections.len();
        if lr > 0.0 {
            self.grads.iter_mut().for_each(|g| *g = [0.0; 6]);
            let mut finite = true;
            for (i, &v) in views.iter().enumerate() {
                let (go, gd) = ray_grad(&self.cells[i]);
                let v = v as usize;
                let g = state.corrections[v].backward(
                    &self.c2w[v],
                    &Vector3::from(self.dirs[i].map(f64::from)),
                    &Vector3::from(go),
                    &Vector3::from(gd),
                );
                for k in 0..3 {
                    self.grads[v][k] += g.omega[k];
                    self.grads[v][3 + k] += g.t[k];
                }
                finite &= go.iter().chain(&gd).all(|x| x.is_finite());
            }
            if finite {
                adam_step(&self.config, state, &self.grads, lr);
                remove_gauge(&self.c2w, &self.centres, &mut state.corrections);
            }
        }
        for p in &state.corrections {
            report.mean_rotation += p.omega.norm() / n.max(1) as f64;
            report.mean_translation += p.t.norm() / n.max(1) as f64;
        }
        report
    }
}

/// Removes the corrections' common similarity (see the module doc). To first order, moving the
/// whole scene by a rotation `θ` about the origin, a translation `δ` and a scale `1 + σ` is the
/// per-view correction `ω_i = Cᵢᵀθ`, `Cᵢ t_i = θ × c_i + δ + σ c_i` (camera `i` with
/// camera-to-world rotation `Cᵢ` and centre `c_i`). The `(θ, δ, σ)` that best explains the
/// corrections in least squares (radians and normalised units weighed alike) is subtracted.
pub fn remove_gauge(c2w: &[Matrix3<f64>], centres: &[Vector3<f64>], p: &mut [PoseCorrection]) {
    use nalgebra::{SMatrix, SVector};
    // Each view gives six rows of A·x ≈ b with x = (θ, δ, σ), in the world frame:
    // Cᵢ ω_i = θ, Cᵢ t_i = −[c_i]× θ + δ + σ c_i.
    let mut ata = SMatrix::<f64, 7, 7>::zeros();
    let mut atb = SVector::<f64, 7>::zeros();
    for ((c, x), q) in c2w.iter().zip(centres).zip(p.iter()) {
        let mut a = SMatrix::<f64, 6, 7>::zeros();
        a.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&Matrix3::identity());
        let hat = Matrix3::new(0.0, -x.z, x.y, x.z, 0.0, -x.x, -x.y, x.x, 0.0);
        a.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-hat));
        a.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&Matrix3::identity());
        a.fixed_view_mut::<3, 1>(3, 6).copy_from(x);
        let mut b = SVector::<f64, 6>::zeros();
        b.fixed_rows_mut::<3>(0).copy_from(&(c * q.omega));
        b.fixed_rows_mut::<3>(3).copy_from(&(c * q.t));
        ata += a.transpose() * a;
        atb += a.transpose() * b;
    }
    // The minimum-norm solution (pseudo-inverse): with too few views to tell the motions apart
    // (one view's correction is all gauge) it still explains what it can.
    let scale = ata.norm().max(1e-300);
    let Ok(g) = ata.svd(true, true).solve(&atb, 1e-12 * scale) else {
        return;
    };
    let (theta, delta, sigma) = (
        Vector3::new(g[0], g[1], g[2]),
        Vector3::new(g[3], g[4], g[5]),
        g[6],
    );
    for ((c, x), q) in c2w.iter().zip(centres).zip(p.iter_mut()) {
        q.omega -= c.transpose() * theta;
        q.t -= c.transpose() * (theta.cross(x) + delta + x * sigma);
    }
}

/// Adam (Kingma and Ba 2015, β = 0.9, 0.999, ε = 1e-15 as nerfstudio's camera optimizer) on
/// every view's `(ω, t)` with gradient `grads + 2·weight·(ω, t)`.
fn adam_step(cfg: &PoseRefineConfig, s: &mut PoseState, grads: &[[f64; 6]], lr: f64) {
    let (b1, b2, eps) = (0.9f64, 0.999f64, 1e-15);
    s.t += 1;
    let c1 = 1.0 - b1.powi(s.t as i32);
    let c2 = 1.0 - b2.powi(s.t as i32);
    for (v, g) in grads.iter().enumerate() {
        let p = &mut s.corrections[v];
        for (k, &gv) in g.iter().enumerate() {
            let x = if k < 3 { p.omega[k] } else { p.t[k - 3] };
            let gk = gv + 2.0 * cfg.weight * x;
            s.m[v][k] = b1 * s.m[v][k] + (1.0 - b1) * gk;
            s.v[v][k] = b2 * s.v[v][k] + (1.0 - b2) * gk * gk;
            let step = lr * (s.m[v][k] / c1) / ((s.v[v][k] / c2).sqrt() + eps);
            if k < 3 {
                p.omega[k] -= step;
            } else {
                p.t[k - 3] -= step;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_learning_rate_decays_from_lr_to_lr_end_and_stops_after_until() {
        let c = PoseRefineConfig {
            start: 0.1,
            until: 0.5,
            ..Default::default()
        };
        assert_eq!(c.lr_at(99, 1000), 0.0);
        assert_eq!(c.lr_at(100, 1000), 1e-4);
        assert!((c.lr_at(300, 1000) - 1e-5).abs() < 1e-15);
        assert!(c.lr_at(499, 1000) > 1e-6);
        assert_eq!(c.lr_at(500, 1000), 0.0);
        assert!(c.invalid().is_none());
        for bad in [
            PoseRefineConfig {
                lr: 0.0,
                ..c.clone()
            },
            PoseRefineConfig {
                lr_end: f64::NAN,
                ..c.clone()
            },
            PoseRefineConfig {
                until: 0.0,
                ..c.clone()
            },
            PoseRefineConfig {
                weight: -1.0,
                ..c.clone()
            },
        ] {
            assert!(bad.invalid().is_some(), "{bad:?}");
        }
    }

    /// A pure similarity of the whole scene is removed entirely; corrections with no common
    /// part are left alone; a mix keeps exactly its own part.
    #[test]
    fn the_common_similarity_is_removed_and_nothing_else() {
        use crate::scene::camera::tests::orbit;
        let cams = orbit(12, 0.5, |i| 1.0 + (i % 3) as f64 * 0.4);
        let c2w: Vec<Matrix3<f64>> = cams.iter().map(|c| c.r.transpose()).collect();
        let ctr: Vec<Vector3<f64>> = cams.iter().map(|c| c.center).collect();
        let (theta, delta, sigma) = (
            Vector3::new(0.01, -0.02, 0.005),
            Vector3::new(0.1, 0.0, -0.05),
            0.02,
        );
        let common: Vec<PoseCorrection> = c2w
            .iter()
            .zip(&ctr)
            .map(|(c, x)| PoseCorrection {
                omega: c.transpose() * theta,
                t: c.transpose() * (theta.cross(x) + delta + x * sigma),
            })
            .collect();
        let mut p = common.clone();
        remove_gauge(&c2w, &ctr, &mut p);
        for q in &p {
            assert!(q.omega.norm() < 1e-12 && q.t.norm() < 1e-12, "{q:?}");
        }
        // Own parts: the residual of a least-squares fit is orthogonal to the common motions,
        // so removing the gauge from (own residual + common) leaves the residual.
        let mut own: Vec<PoseCorrection> = (0..12)
            .map(|i| PoseCorrection {
                omega: Vector3::new((i as f64).sin(), (i as f64 * 1.7).cos(), 0.3) * 0.01,
                t: Vector3::new(0.02, (i as f64 * 0.9).sin() * 0.03, -0.01),
            })
            .collect();
        remove_gauge(&c2w, &ctr, &mut own);
        let mut mixed: Vec<PoseCorrection> = own
            .iter()
            .zip(&common)
            .map(|(a, b)| PoseCorrection {
                omega: a.omega + b.omega,
                t: a.t + b.t,
            })
            .collect();
        remove_gauge(&c2w, &ctr, &mut mixed);
        for (a, b) in own.iter().zip(&mixed) {
            assert!((a.omega - b.omega).norm() < 1e-12 && (a.t - b.t).norm() < 1e-12);
        }
        assert!(
            own.iter().any(|q| q.omega.norm() > 1e-3),
            "the own part survives"
        );
        // One view: its correction is all gauge (the object can move instead), removed.
        let mut one = vec![own[3]];
        remove_gauge(&c2w[..1], &ctr[..1], &mut one);
        assert!(
            one[0].omega.norm() < 1e-9 && one[0].t.norm() < 1e-9,
            "{one:?}"
        );
    }

    #[test]
    fn the_state_round_trips_through_rows_and_refuses_bad_ones() {
        let mut s = PoseState::new(3);
        s.corrections[1].omega = Vector3::new(0.1, -0.2, 0.3);
        s.corrections[2].t = Vector3::new(1.0, 2.0, -3.0);
        s.m[0][4] = 0.5;
        s.v[2][5] = 0.25;
        s.t = 17;
        let rows = s.to_rows();
        assert_eq!(rows.len(), 54);
        assert_eq!(PoseState::from_rows(&rows, 17), Some(s));
        assert!(PoseState::from_rows(&rows[..53], 17).is_none());
        let mut bad = rows.clone();
        bad[3] = f64::NAN;
        assert!(PoseState::from_rows(&bad, 17).is_none());
        bad = rows;
        bad[17] = -1.0;
        assert!(PoseState::from_rows(&bad, 17).is_none());
    }

    /// A corrected camera casts the corrected rays: its centre is `o + C·t` and its ray through
    /// a pixel is the rotated ray of the uncorrected camera through the same pixel.
    #[test]
    fn the_corrected_camera_casts_the_corrected_rays() {
        use crate::scene::camera::{centred_intrinsics, look_at};
        let cam = look_at(
            Vector3::new(1.0, 2.0, 3.0),
            Vector3::zeros(),
            Vector3::z(),
            centred_intrinsics(300.0, 64, 48),
            64,
            48,
        );
        let p = PoseCorrection {
            omega: Vector3::new(0.01, -0.02, 0.03),
            t: Vector3::new(0.05, 0.01, -0.02),
        };
        let mut s = PoseState::new(1);
        s.corrections[0] = p;
        let fixed = s.corrected(std::slice::from_ref(&cam)).remove(0);
        let (o, d) = cam.ray(10.5, 30.5);
        let (o2, d2) = p.apply(&cam.r.transpose(), &o, &d);
        let (o3, d3) = fixed.ray(10.5, 30.5);
        assert!((o2 - o3).norm() < 1e-12, "{o2} {o3}");
        assert!(
            (d2.normalize() - d3.normalize()).norm() < 1e-12,
            "{d2} {d3}"
        );
    }
}
