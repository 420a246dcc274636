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
//! - a gate before any camera moves (`gate`, [`gate`](self::gate)): the pose gradient is heard
//!   with the cameras still, and they are refined only when it points one way; exact and
//!   bundle-adjusted poses are then left as imported instead of walking to refinement's own
//!   floor (a fraction of a pixel);
//!
//! - optionally (`focal = true`), one focal-length scale `e^φ` per camera model (the training
//!   views that share an intrinsic matrix), learned the same way ([`apply_focal`]), for
//!   intrinsics that came from self-calibration; not part of the gauge.
//!
//! The corrected rays replace the batch's rays before rendering, so the depth prior, when on,
//! sees them too. Units: `ω` in radians, `t` in the normalised frame's length (the object's
//! bounding sphere has radius 1).

use super::pose::{apply_focal, exp_so3, focal_backward, PoseCorrection};
use crate::render::{mark_ray_grad, ray_grad, RayGradCell};
use crate::scene::Camera;
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

mod gate;
mod snapshot;
pub use gate::{Gate, GateSummary, GATE_CHI2};
pub use snapshot::PoseSnapshot;

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
    /// Share of the run before refinement starts (0.1: the field has its coarse shape by then;
    /// from step 0 the corrections fit the initial sphere's silhouette): the gate's listening,
    /// then the corrections' moves.
    pub start: f64,
    /// Share of the run after which the corrections stop moving (1.0: to the end).
    pub until: f64,
    /// Weight of the L2 penalty on `(ω, t)` (1e-3), and on `φ` when the focal is learned.
    pub weight: f64,
    /// Also learn one focal-length scale per camera model (false).
    pub focal: bool,
    /// Adam's learning rate of the focal's log scale `φ` at the start (1e-3), decaying like
    /// `lr`: ten times `lr`, so that a focal 10 % off (φ ≈ 0.1) is within reach of a `quick`
    /// run.
    pub focal_lr: f64,
    /// Differentiate one ray in `ray_every` of each batch (4; 1: every ray). The rays'
    /// gradient costs most of refinement's time; Adam's steps do not depend on the gradient's
    /// scale, so a subset of the batch's rays (the batch is itself random) gives the same
    /// update in expectation, noisier. On `blob` at `quick` with every pose off by 0.5° and
    /// 3 mm, one ray in four left the cameras 0.68 px from the truth (every ray: 0.67 px) at
    /// 1.17× the training time without refinement (every ray: 1.72×).
    pub ray_every: u32,
    /// Share of the run, from `start`, during which the cameras stay still while each view's
    /// pose gradient is listened to (0.1; 0: off, every view refined from `start`). Then
    /// every view is refined when the gradients point one way for most views, only the views
    /// whose own gradient does otherwise, and none when it is noise ([`gate`](self::gate)); the
    /// learning rate's schedule runs from `start + gate` to `until`. On exact and on COLMAP's
    /// cameras of `blob` the gradient is noise and the cameras stay where they were imported;
    /// with every pose off by 0.5° and 3 mm every view is refined (docs/pose-refinement.md).
    /// At `quick` (1,400 steps) the default listens for 140 steps, which hears 6 px clearly
    /// (the median view's statistic 57 against a bar of 22.5) and exact cameras as noise (5–7).
    pub gate: f64,
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
            focal: false,
            focal_lr: 1e-3,
            ray_every: 4,
            gate: 0.1,
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
        if !pos(self.focal_lr) {
            return Some((
                "train.pose_refine.focal_lr",
                self.focal_lr,
                "must be finite and > 0",
            ));
        }
        if self.ray_every == 0 {
            return Some(("train.pose_refine.ray_every", 0.0, "must be ≥ 1"));
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
        if !(self.gate >= 0.0 && self.start + self.gate < self.until) {
            return Some((
                "train.pose_refine.gate",
                self.gate,
                "must be ≥ 0, and start + gate below until",
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
    /// refined share of the run `[start + gate, until)`, 0 outside it (the gate listens over
    /// `[start, start + gate)`).
    pub fn lr_at(&self, step: u64, iterations: u64) -> f64 {
        let n = iterations as f64;
        let (a, b) = ((self.start + self.gate) * n, (self.until * n).max(1.0));
        let s = (step as f64 - a) / (b - a).max(1.0);
        if !(0.0..1.0).contains(&s) {
            return 0.0;
        }
        self.lr * (self.lr_end / self.lr).powf(s)
    }

    /// Whether `step` of `iterations` lies in `[start, until)`, where the gate (when on) may
    /// listen.
    fn within(&self, step: u64, iterations: u64) -> bool {
        let n = iterations as f64;
        let s = step as f64;
        s >= self.start * n && s < self.until * n
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
    /// `[camera models]` the focal's log scale `φ` and its Adam moments (empty when the focal
    /// is not learned).
    pub focal: Vec<[f64; 3]>,
    /// Adam steps taken.
    pub t: u64,
    /// The gate's evidence and verdict (`gate > 0`; `None` without the gate).
    pub gate: Option<Gate>,
}

impl PoseState {
    /// Zero corrections and moments for `views` views and `models` focal scales (0 when the
    /// focal is not learned).
    pub fn new(views: usize, models: usize) -> Self {
        Self {
            corrections: vec![PoseCorrection::default(); views],
            m: vec![[0.0; 6]; views],
            v: vec![[0.0; 6]; views],
            focal: vec![[0.0; 3]; models],
            t: 0,
            gate: None,
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

    /// `[models][3]` rows `φ, m, v` (the checkpoint's focal tensor; empty when not learned).
    pub fn focal_rows(&self) -> Vec<f64> {
        self.focal.concat()
    }

    /// The inverse of [`Self::to_rows`] and [`Self::focal_rows`]; `None` when a length is not
    /// a multiple of its row, or a value is not finite (or a second moment negative).
    pub fn from_rows(rows: &[f64], focal: &[f64], t: u64) -> Option<Self> {
        let bad =
            |r: &[f64], n: usize| !r.len().is_multiple_of(n) || r.iter().any(|v| !v.is_finite());
        if bad(rows, 18) || bad(focal, 3) || focal.chunks_exact(3).any(|f| f[2] < 0.0) {
            return None;
        }
        let mut s = Self::new(rows.len() / 18, focal.len() / 3);
        for (f, r) in s.focal.iter_mut().zip(focal.chunks_exact(3)) {
            f.copy_from_slice(r);
        }
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
    /// camera-to-world is `C2W·[R(ω) | t]`, [`PoseCorrection`]), and with the focal learned,
    /// `K`'s focal lengths and skew times `e^φ` of the camera's model ([`camera_models`]).
    /// `cameras` in the frame and order the corrections were learned in (the normalised one).
    pub fn corrected(&self, cameras: &[Camera]) -> Vec<Camera> {
        let (model, _) = camera_models(cameras);
        cameras
            .iter()
            .zip(&self.corrections)
            .zip(model)
            .map(|((c, p), m)| {
                let phi = self.focal.get(m).map_or(0.0, |f| f[0]);
                Camera {
                    r: exp_so3(&p.omega).transpose() * c.r,
                    center: c.center + c.r.transpose() * p.t,
                    ..with_focal_scale(c, phi)
                }
            })
            .collect()
    }

    /// The focal scale `e^φ` learned for each camera model (empty when not learned).
    pub fn focal_scales(&self) -> Vec<f64> {
        self.focal.iter().map(|f| f[0].exp()).collect()
    }
}

/// The camera models of `cameras`: the index of each camera's model, and how many there are.
/// Cameras share a model when their image sizes and intrinsic matrices agree ([`same_model`]),
/// as the views of one physical camera do (COLMAP's `camera_id`).
pub fn camera_models(cameras: &[Camera]) -> (Vec<usize>, usize) {
    let mut firsts: Vec<&Camera> = Vec::new();
    let model = cameras
        .iter()
        .map(|c| {
            firsts
                .iter()
                .position(|f| same_model(f, c))
                .unwrap_or_else(|| {
                    firsts.push(c);
                    firsts.len() - 1
                })
        })
        .collect();
    (model, firsts.len())
}

/// Whether two cameras are views of one camera model: the same image size and intrinsic
/// matrices that agree to 1e-6 of the focal length (a `cameras_sphere.npz` stores `K·[R|t]`
/// per view, and decomposing it leaves each view's `K` a few ulps from the others').
pub fn same_model(a: &Camera, b: &Camera) -> bool {
    let tol = 1e-6 * a.k[(0, 0)].abs().max(a.k[(1, 1)].abs());
    (a.width, a.height) == (b.width, b.height)
        && a.k
            .iter()
            .zip(b.k.iter())
            .all(|(x, y)| (x - y).abs() <= tol)
}

/// `camera` with its focal lengths and skew multiplied by `e^φ` (principal point kept): the
/// camera [`apply_focal`] casts the rays of.
pub fn with_focal_scale(camera: &Camera, phi: f64) -> Camera {
    let mut c = camera.clone();
    if phi != 0.0 {
        let s = phi.exp();
        for (r, col) in [(0, 0), (0, 1), (1, 1)] {
            c.k[(r, col)] *= s;
        }
    }
    c
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
    /// `[views]` camera model of each view ([`camera_models`]) and `[models]` the focal's
    /// gradient (empty when the focal is not learned).
    model: Vec<usize>,
    focal_grads: Vec<f64>,
    /// Whether [`Self::correct`] asked for any ray's gradient in the batch it last saw.
    marked: bool,
}

impl PoseRefiner {
    /// For the training cameras `cameras` (normalised frame, training order).
    pub fn new(config: &PoseRefineConfig, cameras: &[Camera]) -> Self {
        let (model, models) = camera_models(cameras);
        Self {
            model,
            focal_grads: vec![0.0; if config.focal { models } else { 0 }],
            config: config.clone(),
            c2w: cameras.iter().map(|c| c.r.transpose()).collect(),
            centres: cameras.iter().map(|c| c.center).collect(),
            origins: Vec::new(),
            dirs: Vec::new(),
            cells: Vec::new(),
            grads: vec![[0.0; 6]; cameras.len()],
            marked: false,
        }
    }

    /// The state refinement starts from: zero corrections and moments, and with the gate on,
    /// nothing heard yet.
    pub fn new_state(&self) -> PoseState {
        PoseState {
            gate: self.gated().then(|| Gate::new(self.n_views())),
            ..PoseState::new(self.n_views(), self.n_focal())
        }
    }

    /// Whether the gate is on (`gate > 0`): the state then carries its sums.
    pub fn gated(&self) -> bool {
        self.config.gate > 0.0
    }

    /// Steps the gate listens for in a run of `iterations` (at least 1).
    fn listen_steps(&self, iterations: u64) -> u64 {
        ((self.config.gate * iterations as f64).round() as u64).max(1)
    }

    /// Number of views.
    pub fn n_views(&self) -> usize {
        self.c2w.len()
    }

    /// Number of focal scales learned (0 when the focal is not).
    pub fn n_focal(&self) -> usize {
        self.focal_grads.len()
    }

    /// The camera-frame direction of view `v`'s uncorrected direction `d` after its model's
    /// focal scale (`Cᵀd` itself when the focal is not learned), unit length.
    fn focal_dir(&self, state: &PoseState, v: usize, d: &Vector3<f64>) -> Vector3<f64> {
        let local = self.c2w[v].transpose() * d;
        match state.focal.get(self.model[v]) {
            Some(f) => apply_focal(f[0], &local),
            None => local,
        }
    }

    /// Replaces each ray of view `views[i]` by its corrected ray (keeping the uncorrected one
    /// for the update), and readies one gradient cell per ray for step `step` of `iterations`:
    /// one ray in `ray_every` is asked for, none while the learning rate is 0 (before `start`,
    /// after `until`) and the gate does not listen, and after the gate's verdict none of a
    /// view held still.
    pub fn correct(
        &mut self,
        state: &PoseState,
        views: &[u32],
        origins: &mut [[f32; 3]],
        dirs: &mut [[f32; 3]],
        (step, iterations): (u64, u64),
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
            let d2 = c * (rot[v as usize] * self.focal_dir(state, v as usize, &d));
            origins[i] = [o2.x as f32, o2.y as f32, o2.z as f32];
            dirs[i] = [d2.x as f32, d2.y as f32, d2.z as f32];
        }
        if self.cells.len() < views.len() {
            self.cells.resize_with(views.len(), Default::default);
        }
        let listening = state.gate.as_ref().is_some_and(Gate::listening);
        let on = if listening {
            self.config.within(step, iterations)
        } else {
            self.config.lr_at(step, iterations) > 0.0
        };
        let every = self.config.ray_every.max(1) as usize;
        let hears = |v: u32| state.gate.as_ref().is_none_or(|g| g.hears(v as usize));
        self.marked = false;
        for (i, cell) in self.cells[..views.len()].iter().enumerate() {
            let want = on && i % every == 0 && hears(views[i]);
            mark_ray_grad(cell, want);
            self.marked |= want;
        }
    }

    /// The gradient cells of the batch [`Self::correct`] last saw, when it asked for any ray's
    /// gradient (`None` otherwise: the renderer then skips the input gradient's extra columns,
    /// which every ray pays for once any cell is passed).
    pub fn wanted_cells(&self) -> Option<&[RayGradCell]> {
        self.marked.then(|| self.cells())
    }

    /// The gradient cells of the batch [`Self::correct`] last saw.
    pub fn cells(&self) -> &[RayGradCell] {
        &self.cells[..self.origins.len()]
    }

    /// Sums the cells' ray gradients of the batch into each view's `(ω, t)` gradient and each
    /// camera model's focal gradient (`self.grads`, `self.focal_grads`). Whether every ray
    /// gradient was finite.
    fn gradients(&mut self, state: &PoseState, views: &[u32]) -> bool {
        self.grads.iter_mut().for_each(|g| *g = [0.0; 6]);
        self.focal_grads.iter_mut().for_each(|g| *g = 0.0);
        let mut finite = true;
        // Each view's R(ω)ᵀ, for the focal's chain (computed once per view, not per ray).
        let rot_t: Vec<Matrix3<f64>> = if self.focal_grads.is_empty() {
            Vec::new()
        } else {
            let r = state.corrections.iter();
            r.map(|p| exp_so3(&p.omega).transpose()).collect()
        };
        for (i, &v) in views.iter().enumerate() {
            let (go, gd) = ray_grad(&self.cells[i]);
            if go.iter().chain(&gd).all(|&x| x == 0.0) {
                // A ray left out (`ray_every`) or without samples adds nothing.
                continue;
            }
            let v = v as usize;
            let (c, gd) = (&self.c2w[v], Vector3::from(gd));
            let d = Vector3::from(self.dirs[i].map(f64::from));
            // The rotation acts on the focal-scaled direction: d' = C R(ω) F_φ(Cᵀd).
            let scaled = state
                .focal
                .get(self.model[v])
                .map(|f| c * apply_focal(f[0], &(c.transpose() * d)));
            let d_rot = scaled.as_ref().unwrap_or(&d);
            let g = state.corrections[v].backward(c, d_rot, &Vector3::from(go), &gd);
            for k in 0..3 {
                self.grads[v][k] += g.omega[k];
                self.grads[v][3 + k] += g.t[k];
            }
            if let Some(fg) = self.focal_grads.get_mut(self.model[v]) {
                let phi = state.focal[self.model[v]][0];
                let g_local = rot_t[v] * (c.transpose() * gd);
                *fg += focal_backward(phi, &(c.transpose() * d), &g_local);
            }
            finite &= go.iter().all(|x| x.is_finite()) && gd.iter().all(|x| x.is_finite());
        }
        finite
    }

    /// One Adam step of the corrections from the cells' gradients (and the L2 penalty) at
    /// `step` of `iterations`. A batch with a non-finite ray gradient changes nothing. With the
    /// gate, the step is heard and nothing moves until the verdict; after it only the refined
    /// views (and the focal of a camera model with a refined view) move, and the common
    /// similarity is removed only when every view is refined: a view held still fixes the
    /// frame itself, and removing the similarity of a few refined views would take away their
    /// own corrections (one view's correction is all similarity).
    pub fn update(
        &mut self,
        state: &mut PoseState,
        views: &[u32],
        step: u64,
        iterations: u64,
    ) -> PoseStep {
        let lr = self.config.lr_at(step, iterations);
        let n = state.corrections.len();
        let listening = state.gate.as_ref().is_some_and(Gate::listening);
        if listening && self.config.within(step, iterations) {
            let finite = self.gradients(state, views);
            let listen = self.listen_steps(iterations);
            if let Some(g) = state.gate.as_mut().filter(|_| finite) {
                g.listen(&self.grads, listen);
            }
        } else if lr > 0.0 && !listening {
            let moves: Vec<bool> = match &state.gate {
                Some(g) => (0..n).map(|v| g.moves(v)).collect(),
                None => vec![true; n],
            };
            // Held still by the gate, no view needs its gradient summed (none was asked for).
            if !moves.contains(&true) || !self.gradients(state, views) {
                return self.report(state, lr);
            }
            adam_step(&self.config, state, &self.grads, lr, &moves);
            let focal_lr = lr * self.config.focal_lr / self.config.lr;
            let mut models = vec![false; state.focal.len()];
            for (v, _) in moves.iter().enumerate().filter(|m| *m.1) {
                if let Some(m) = models.get_mut(self.model[v]) {
                    *m = true;
                }
            }
            focal_adam_step(&self.config, state, &self.focal_grads, focal_lr, &models);
            if moves.iter().all(|&m| m) {
                remove_gauge(&self.c2w, &self.centres, &mut state.corrections);
            }
        }
        self.report(state, lr)
    }

    /// What an update at learning rate `lr` left: the corrections' mean size.
    fn report(&self, state: &PoseState, lr: f64) -> PoseStep {
        let n = state.corrections.len().max(1) as f64;
        let mut report = PoseStep {
            lr,
            ..Default::default()
        };
        for p in &state.corrections {
            report.mean_rotation += p.omega.norm() / n;
            report.mean_translation += p.t.norm() / n;
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

/// The same Adam on each model's focal log scale `φ` with gradient `grads + 2·weight·φ`, after
/// [`adam_step`] (which counts the step); only the models where `moves` holds.
fn focal_adam_step(
    cfg: &PoseRefineConfig,
    s: &mut PoseState,
    grads: &[f64],
    lr: f64,
    moves: &[bool],
) {
    let (b1, b2, eps) = (0.9f64, 0.999f64, 1e-15);
    let c1 = 1.0 - b1.powi(s.t as i32);
    let c2 = 1.0 - b2.powi(s.t as i32);
    for ((f, &g), _) in s.focal.iter_mut().zip(grads).zip(moves).filter(|x| *x.1) {
        let gk = g + 2.0 * cfg.weight * f[0];
        f[1] = b1 * f[1] + (1.0 - b1) * gk;
        f[2] = b2 * f[2] + (1.0 - b2) * gk * gk;
        f[0] -= lr * (f[1] / c1) / ((f[2] / c2).sqrt() + eps);
    }
}

/// Adam (Kingma and Ba 2015, β = 0.9, 0.999, ε = 1e-15 as nerfstudio's camera optimizer) on
/// the `(ω, t)` of every view where `moves` holds, with gradient `grads + 2·weight·(ω, t)`.
fn adam_step(
    cfg: &PoseRefineConfig,
    s: &mut PoseState,
    grads: &[[f64; 6]],
    lr: f64,
    moves: &[bool],
) {
    let (b1, b2, eps) = (0.9f64, 0.999f64, 1e-15);
    s.t += 1;
    let c1 = 1.0 - b1.powi(s.t as i32);
    let c2 = 1.0 - b2.powi(s.t as i32);
    for (v, g) in grads.iter().enumerate().filter(|(v, _)| moves[*v]) {
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
mod tests;
