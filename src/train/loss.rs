//! The training loss: colour L1 and MSE against the target pixels, the mask BCE of the opacity,
//! the weighted total, and the per-sample weights of the eikonal and curvature regularisers.
//!
//! The renderer's backward takes its loss through the [`RayLoss`] interface, which it defines
//! (`render` must not import `train`); this module is that interface's implementation
//! ([`PixelLoss`]) and [`TrainStep::train_step`], a training step of a [`NeusModel`] with it.
//! The settings ([`LossConfig`], [`MaskBce`]) are declared in [`crate::render::config`], because
//! they belong to the [`ModelConfig`](crate::render::ModelConfig) the model holds, and are
//! re-exported here; their values at a step ([`LossWeights`]) come from
//! [`ModelConfig::schedule`](crate::render::ModelConfig::schedule).

pub use crate::render::config::{LossConfig, MaskBce};
pub use crate::render::schedule::LossWeights;

use crate::field::Real;
use std::sync::atomic::{AtomicU32, Ordering};

use crate::render::{
    BatchCounts, ModelError, NeusModel, OccupancyGrid, PhaseTimes, RayBatch, RayGradCell, RayLoss,
    SampleWeights, Schedule,
};

/// Supervision of a batch.
#[derive(Debug, Clone, Copy)]
pub struct Targets<'a> {
    /// `[n][3]` target colours in `[0,1]` (already composited on the background where masked).
    pub rgb: &'a [[f32; 3]],
    /// `[n]` foreground mask in `[0,1]`, or `None` (no mask loss).
    pub mask: Option<&'a [f32]>,
}

/// Result of [`TrainStep::train_step`]. Loss terms are unweighted; `total` is the weighted sum
/// that was differentiated.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepOutput {
    /// Mean L1 colour error over valid rays (rays with at least one sample).
    pub rgb_l1: f64,
    /// Mean squared colour error over valid rays.
    pub rgb_mse: f64,
    /// Mean `(|∇f| − 1)²` over all samples.
    pub eikonal: f64,
    /// Mean BCE of the clamped or squashed opacity against the mask (0 without mask).
    pub mask: f64,
    /// Mean `|Δf|` over all samples (normalised units⁻¹; computed only when its weight is > 0).
    pub curvature: f64,
    /// Weighted total.
    pub total: f64,
    /// Mean squared colour error over **all** rays (for PSNR, as instant-nsr-pl's validation).
    pub mse_all: f64,
    pub n_rays: usize,
    pub n_valid_rays: usize,
    pub n_samples: usize,
    pub inv_s: f64,
    pub times: PhaseTimes,
}

/// `ε` of the mask BCE's clamp or squash (NeuS and instant-nsr-pl clip to `[1e-3, 1 − 1e-3]`).
const MASK_EPS: f64 = 1e-3;

impl MaskBce {
    /// The opacity `o' ∈ [ε, 1 − ε]` the BCE reads, and `∂o'/∂o` (see [`MaskBce`]).
    pub fn squash(self, o: f64) -> (f64, f64) {
        const E: f64 = MASK_EPS;
        match self {
            MaskBce::Clamp => (
                o.clamp(E, 1.0 - E),
                if (E..=1.0 - E).contains(&o) { 1.0 } else { 0.0 },
            ),
            MaskBce::Squash => (E + (1.0 - 2.0 * E) * o, 1.0 - 2.0 * E),
        }
    }
}

/// Binary cross-entropy of an opacity `o ∈ (0, 1)` against the mask value `m ∈ [0, 1]`.
pub fn bce(o: f64, m: f64) -> f64 {
    -(m * o.ln() + (1.0 - m) * (1.0 - o).ln())
}

/// `∂bce(o, m)/∂o`.
pub fn bce_grad(o: f64, m: f64) -> f64 {
    -m / o + (1.0 - m) / (1.0 - o)
}

/// The sign of `x` (0 at 0): the L1 gradient.
fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Per-shard sums of [`PixelLoss`]'s terms (f64).
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub struct PixelLossSums {
    /// `Σ m·|c − ĉ|` over valid rays and channels (`m` = 1 unless colour is taken in the mask).
    pub l1: f64,
    /// `Σ m·(c − ĉ)²` over valid rays and channels.
    pub sq_valid: f64,
    /// `Σ (c − ĉ)²` over all rays and channels.
    pub sq_all: f64,
    /// `Σ bce(o', mask)` over rays.
    pub mask: f64,
}

/// The training loss of one batch (instant-nsr-pl `systems/neus.py` `training_step`, NeuS
/// `exp_runner.py` for the in-mask colour): weights `w` at the step,
///
/// `L = w_l1·Σ m|c − ĉ|/(3N) + w_mse·Σ m(c − ĉ)²/(3N) + w_mask·Σ bce(o', mask)/n_rays
///      + w_eik·Σ(|∇f| − 1)²/n_samples + w_curv·Σ|Δf|/n_samples`,
///
/// `N` = valid rays, or `Σ mask` (NeuS style, [`LossConfig::color_in_mask`]).
#[derive(Debug, Clone, Copy)]
pub struct PixelLoss<'a> {
    pub weights: LossWeights,
    pub targets: Targets<'a>,
    pub mask_bce: MaskBce,
    /// Colour only inside the mask, normalised by `3·Σ mask`, no background composited (only
    /// when there is a mask).
    pub in_mask: bool,
    /// `Σ mask` over the batch (0 without mask).
    pub mask_sum: f64,
    /// `[n]` where each ray's mean absolute colour error `Σ_k |c_k − ĉ_k| / 3` is written (as
    /// `f32` bits), for the error map ([`crate::train::error_map`]); `None`: not recorded.
    pub ray_errors: Option<&'a [AtomicU32]>,
}

impl<'a> PixelLoss<'a> {
    /// The loss of `config` with the weights `weights` on `targets`.
    pub fn new(config: &LossConfig, weights: LossWeights, targets: Targets<'a>) -> Self {
        Self {
            weights,
            targets,
            mask_bce: config.mask_bce,
            in_mask: config.color_in_mask && targets.mask.is_some(),
            mask_sum: targets
                .mask
                .map_or(0.0, |m| m.iter().map(|&v| v as f64).sum()),
            ray_errors: None,
        }
    }

    /// The same loss, writing each ray's colour error into `sink` (`[n]`, one slot per ray).
    pub fn with_ray_errors(self, sink: &'a [AtomicU32]) -> Self {
        Self {
            ray_errors: Some(sink),
            ..self
        }
    }

    /// Normaliser `N` of the colour terms.
    fn color_norm(&self, counts: &BatchCounts) -> f64 {
        if self.in_mask {
            self.mask_sum.max(1e-5)
        } else {
            counts.n_valid.max(1) as f64
        }
    }

    /// The step's result from the summed terms: means and the weighted total.
    pub fn output(
        &self,
        sums: &PixelLossSums,
        eikonal_sum: f64,
        curvature_sum: f64,
        counts: &BatchCounts,
    ) -> StepOutput {
        let l = self.weights;
        let n = counts.n_rays;
        let ns = counts.n_samples.max(1) as f64;
        let cn = self.color_norm(counts);
        let out = StepOutput {
            rgb_l1: sums.l1 / (3.0 * cn),
            rgb_mse: sums.sq_valid / (3.0 * cn),
            eikonal: eikonal_sum / ns,
            curvature: curvature_sum / ns,
            mask: if self.targets.mask.is_some() {
                sums.mask / n.max(1) as f64
            } else {
                0.0
            },
            total: 0.0,
            mse_all: sums.sq_all / (3.0 * n.max(1) as f64),
            n_rays: n,
            n_valid_rays: counts.n_valid,
            n_samples: counts.n_samples,
            ..StepOutput::default()
        };
        StepOutput {
            total: l.rgb_l1 as f64 * out.rgb_l1
                + l.rgb_mse as f64 * out.rgb_mse
                + l.eikonal as f64 * out.eikonal
                + l.mask as f64 * out.mask
                + l.curvature as f64 * out.curvature,
            ..out
        }
    }
}

impl RayLoss for PixelLoss<'_> {
    type Sums = PixelLossSums;

    fn check(&self, n: usize) -> Result<(), ModelError> {
        if self.targets.rgb.len() != n {
            return Err(ModelError::Shape {
                what: "target rgb",
                expected: n,
                got: self.targets.rgb.len(),
            });
        }
        if let Some(m) = self.targets.mask {
            if m.len() != n {
                return Err(ModelError::Shape {
                    what: "mask",
                    expected: n,
                    got: m.len(),
                });
            }
        }
        if let Some(e) = self.ray_errors {
            if e.len() < n {
                return Err(ModelError::Shape {
                    what: "ray error sink",
                    expected: n,
                    got: e.len(),
                });
            }
        }
        Ok(())
    }

    fn background(&self, render_background: [f32; 3]) -> [f32; 3] {
        if self.in_mask {
            [0.0; 3]
        } else {
            render_background
        }
    }

    #[inline]
    fn ray(
        &self,
        counts: &BatchCounts,
        r: usize,
        rgb: [f64; 3],
        opacity: f64,
        valid: bool,
        sums: &mut PixelLossSums,
    ) -> ([f64; 3], f64) {
        let l = self.weights;
        let cnorm = 3.0 * self.color_norm(counts);
        let tgt = self.targets.rgb[r];
        let mw = match self.targets.mask {
            Some(m) if self.in_mask => m[r] as f64,
            _ => 1.0,
        };
        let mut g_rgb = [0.0; 3];
        let mut abs_err = 0.0;
        for k in 0..3 {
            let diff = rgb[k] - tgt[k] as f64;
            abs_err += diff.abs();
            sums.sq_all += diff * diff;
            if valid {
                sums.l1 += mw * diff.abs();
                sums.sq_valid += mw * diff * diff;
                g_rgb[k] =
                    mw * (l.rgb_l1 as f64 * sign(diff) + l.rgb_mse as f64 * 2.0 * diff) / cnorm;
            }
        }
        if let Some(sink) = self.ray_errors {
            // Each ray's slot is written once per step, by the shard that owns the ray.
            sink[r].store(((abs_err / 3.0) as f32).to_bits(), Ordering::Relaxed);
        }
        let mut g_op = 0.0;
        if let Some(mask) = self.targets.mask {
            let m = mask[r] as f64;
            let (oc, doc) = self.mask_bce.squash(opacity);
            sums.mask += bce(oc, m);
            if doc != 0.0 {
                g_op = l.mask as f64 * doc * bce_grad(oc, m) / counts.n_rays.max(1) as f64;
            }
        }
        (g_rgb, g_op)
    }

    fn sample_weights(&self, counts: &BatchCounts) -> SampleWeights {
        let ns = counts.n_samples.max(1) as f64;
        SampleWeights {
            eikonal: self.weights.eikonal as f64 / ns,
            curvature: self.weights.curvature as f64 / ns,
        }
    }

    fn merge(into: &mut PixelLossSums, from: &PixelLossSums) {
        into.l1 += from.l1;
        into.sq_valid += from.sq_valid;
        into.sq_all += from.sq_all;
        into.mask += from.mask;
    }
}

/// Per-ray outputs a training step writes besides its sums (each `[n]`, one cell per ray).
#[derive(Clone, Copy, Default)]
pub struct StepSinks<'a> {
    /// Each ray's mean absolute colour error, `f32` bits ([`PixelLoss::ray_errors`]): the error
    /// map's input.
    pub ray_errors: Option<&'a [AtomicU32]>,
    /// Each ray's `(∂L/∂o, ∂L/∂d)` ([`NeusModel::forward_backward_rays`]): pose refinement's
    /// input.
    pub ray_grads: Option<&'a [RayGradCell]>,
}

/// A training step of a model with its configured loss ([`PixelLoss`] of
/// `model.config.loss`).
pub trait TrainStep {
    /// One training step's forward and backward on a batch.
    ///
    /// Accumulates (adds) `∂total/∂params` into `grads` (same layout as `params`), returns the
    /// loss terms. `sched`: the values at this step ([`crate::render::ModelConfig::schedule`]).
    /// `step_seed` seeds the stratified jitter. `occ`: the occupancy grid (or `None` to march
    /// everything). Generic over [`Real`] so the gradient checks run it in `f64`.
    #[allow(clippy::too_many_arguments)]
    fn train_step<T: Real>(
        &self,
        params: &[T],
        grads: &mut [T],
        batch: &RayBatch,
        targets: &Targets,
        sched: Schedule,
        occ: Option<&OccupancyGrid>,
        step_seed: u64,
    ) -> Result<StepOutput, ModelError> {
        let sinks = StepSinks::default();
        self.train_step_recording(params, grads, batch, targets, sched, occ, step_seed, sinks)
    }

    /// [`TrainStep::train_step`], also writing the per-ray outputs `sinks` asks for.
    #[allow(clippy::too_many_arguments)]
    fn train_step_recording<T: Real>(
        &self,
        params: &[T],
        grads: &mut [T],
        batch: &RayBatch,
        targets: &Targets,
        sched: Schedule,
        occ: Option<&OccupancyGrid>,
        step_seed: u64,
        sinks: StepSinks,
    ) -> Result<StepOutput, ModelError>;
}

impl TrainStep for NeusModel {
    fn train_step_recording<T: Real>(
        &self,
        params: &[T],
        grads: &mut [T],
        batch: &RayBatch,
        targets: &Targets,
        sched: Schedule,
        occ: Option<&OccupancyGrid>,
        step_seed: u64,
        sinks: StepSinks,
    ) -> Result<StepOutput, ModelError> {
        let mut loss = PixelLoss::new(&self.config.loss, sched.loss, *targets);
        if let Some(sink) = sinks.ray_errors {
            loss = loss.with_ray_errors(sink);
        }
        let b = self.forward_backward_rays(
            params,
            grads,
            batch,
            &loss,
            sched,
            occ,
            step_seed,
            sinks.ray_grads,
        )?;
        Ok(StepOutput {
            inv_s: b.inv_s,
            times: b.times,
            ..loss.output(&b.loss, b.eikonal_sum, b.curvature_sum, &b.counts)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mask BCE's gradient (squash and clamp, through `squash`) against central
    /// differences in f64, inside the range, near its ends and saturated.
    #[test]
    fn mask_bce_gradient_matches_finite_differences() {
        let h = 1e-6;
        for mode in [MaskBce::Squash, MaskBce::Clamp] {
            for &m in &[0.0, 0.3, 1.0] {
                for &o in &[0.0, 0.0005, 0.2, 0.5, 0.97, 0.9995, 1.0] {
                    let f = |o: f64| bce(mode.squash(o).0, m);
                    let (oc, doc) = mode.squash(o);
                    let analytic = doc * bce_grad(oc, m);
                    let numeric = (f(o + h) - f(o - h)) / (2.0 * h);
                    // The clamp's kink at ε and 1 − ε: only away from it.
                    let near_kink = mode == MaskBce::Clamp
                        && ((o - MASK_EPS).abs() < 2.0 * h || (o - 1.0 + MASK_EPS).abs() < 2.0 * h);
                    if near_kink {
                        continue;
                    }
                    let tol = 1e-6 * (1.0 + analytic.abs());
                    assert!(
                        (analytic - numeric).abs() < tol,
                        "{mode:?} m={m} o={o}: analytic {analytic}, numeric {numeric}"
                    );
                }
            }
        }
        // Saturated and clamped: no gradient; squashed: the largest gradient of the range.
        assert_eq!(MaskBce::Clamp.squash(1.0), (1.0 - MASK_EPS, 0.0));
        let (oc, doc) = MaskBce::Squash.squash(1.0);
        assert!(doc * bce_grad(oc, 0.0) > 900.0);
    }

    /// The colour gradient `ray` returns against central differences of the sums it adds, for
    /// every combination of L1 / MSE weights, masked colour and a valid or empty ray.
    #[test]
    fn ray_gradient_matches_finite_differences() {
        let rgb_t = [[0.2f32, 0.9, 0.5], [0.1, 0.1, 0.1]];
        let mask = [0.7f32, 0.0];
        let weights = LossWeights {
            rgb_l1: 0.7,
            rgb_mse: 1.3,
            eikonal: 0.1,
            mask: 0.25,
            curvature: 0.0,
        };
        let counts = BatchCounts {
            n_rays: 2,
            n_valid: 1,
            n_samples: 10,
        };
        for in_mask in [false, true] {
            let cfg = LossConfig {
                color_in_mask: in_mask,
                ..LossConfig::default()
            };
            let loss = PixelLoss::new(
                &cfg,
                weights,
                Targets {
                    rgb: &rgb_t,
                    mask: Some(&mask),
                },
            );
            // The part of the total that depends on ray 0's colour and opacity.
            let total = |rgb: [f64; 3], o: f64| {
                let mut s = PixelLossSums::default();
                loss.ray(&counts, 0, rgb, o, true, &mut s);
                let cn = loss.color_norm(&counts);
                weights.rgb_l1 as f64 * s.l1 / (3.0 * cn)
                    + weights.rgb_mse as f64 * s.sq_valid / (3.0 * cn)
                    + weights.mask as f64 * s.mask / counts.n_rays as f64
            };
            let (rgb, o) = ([0.31, 0.62, 0.93], 0.4);
            let (g, g_op) = loss.ray(&counts, 0, rgb, o, true, &mut PixelLossSums::default());
            let h = 1e-7;
            for k in 0..3 {
                let (mut a, mut b) = (rgb, rgb);
                a[k] += h;
                b[k] -= h;
                let num = (total(a, o) - total(b, o)) / (2.0 * h);
                assert!(
                    (g[k] - num).abs() < 1e-6,
                    "in_mask {in_mask} ch {k}: {} vs {num}",
                    g[k]
                );
            }
            let num = (total(rgb, o + h) - total(rgb, o - h)) / (2.0 * h);
            assert!((g_op - num).abs() < 1e-6, "opacity: {g_op} vs {num}");
            // An empty ray gets no colour gradient but still counts in `sq_all`.
            let mut s = PixelLossSums::default();
            let (g, _) = loss.ray(&counts, 1, [1.0; 3], 0.0, false, &mut s);
            assert_eq!(g, [0.0; 3]);
            assert_eq!((s.l1, s.sq_valid), (0.0, 0.0));
            assert!(s.sq_all > 0.0);
        }
    }

    /// The error sink receives each ray's mean absolute colour error (valid or not) and changes
    /// neither the gradients nor the sums; a sink shorter than the batch is refused.
    #[test]
    fn ray_error_sink_records_the_mean_absolute_error() {
        let rgb_t = [[0.2f32, 0.9, 0.5], [0.1, 0.1, 0.1]];
        let t = Targets {
            rgb: &rgb_t,
            mask: None,
        };
        let w = LossWeights {
            rgb_l1: 1.0,
            rgb_mse: 0.5,
            eikonal: 0.0,
            mask: 0.0,
            curvature: 0.0,
        };
        let counts = BatchCounts {
            n_rays: 2,
            n_valid: 1,
            n_samples: 4,
        };
        let plain = PixelLoss::new(&LossConfig::default(), w, t);
        let sink: Vec<AtomicU32> = (0..2).map(|_| AtomicU32::new(0)).collect();
        let rec = plain.with_ray_errors(&sink);
        let rgb = [0.5, 0.5, 0.5];
        let (mut s1, mut s2) = (PixelLossSums::default(), PixelLossSums::default());
        assert_eq!(
            plain.ray(&counts, 0, rgb, 0.3, true, &mut s1),
            rec.ray(&counts, 0, rgb, 0.3, true, &mut s2)
        );
        assert_eq!(s1, s2);
        rec.ray(&counts, 1, [0.4, 0.1, 0.0], 0.0, false, &mut s2);
        let got = |i: usize| f32::from_bits(sink[i].load(Ordering::Relaxed));
        assert!(
            (got(0) - (0.3 + 0.4 + 0.0) / 3.0).abs() < 1e-6,
            "{}",
            got(0)
        );
        assert!(
            (got(1) - (0.3 + 0.0 + 0.1) / 3.0).abs() < 1e-6,
            "{}",
            got(1)
        );
        assert!(rec.check(2).is_ok());
        let short = plain.with_ray_errors(&sink[..1]);
        assert!(matches!(
            short.check(2),
            Err(ModelError::Shape {
                what: "ray error sink",
                ..
            })
        ));
    }
}
