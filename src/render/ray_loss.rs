//! The interface between rendering and the loss: what the training step's backward needs from a
//! loss, and nothing else.
//!
//! The renderer composites each ray, hands the composited colour and opacity to a [`RayLoss`], and
//! back-propagates the two gradients it returns through compositing, the colour network, the SDF
//! network and the hash grid. The geometric regularisers (eikonal, curvature) live on samples, in
//! the middle of that backward, so the loss only gives their per-sample weights
//! ([`RayLoss::sample_weights`]); the renderer computes them and reports their sums.
//!
//! The trait lives here and its implementation (the L1/MSE colour terms, the mask BCE, the
//! normalisations and the weighted total) in `train::loss`, so that `render` never imports
//! `train`. The loss *settings* ([`LossConfig`](super::LossConfig)) stay in
//! [`super::config`] because they are part of [`ModelConfig`](super::ModelConfig), which the
//! model holds.

use super::error::ModelError;

/// Counts of a marched batch that a loss normalises by.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BatchCounts {
    /// Rays in the batch.
    pub n_rays: usize,
    /// Rays with at least one sample.
    pub n_valid: usize,
    /// Samples over all rays.
    pub n_samples: usize,
}

/// Weights of the per-sample regularisers, already divided by whatever the loss normalises them
/// by: `∂L/∂(|∇f| − 1)²` and `∂L/∂|Δf|` of one sample. A curvature weight ≤ 0 switches the
/// curvature term (and its sum) off.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SampleWeights {
    pub eikonal: f64,
    pub curvature: f64,
}

/// A loss on composited rays, as the training step's backward uses it. Implementations must be
/// deterministic: the renderer calls [`RayLoss::ray`] once per ray, in ray order within a chunk,
/// from several shards at once (hence `Sync` and the per-shard [`RayLoss::Sums`]).
pub trait RayLoss: Sync {
    /// Per-shard sums of the loss terms; merged in shard order by [`RayLoss::merge`].
    type Sums: Default + Copy + Send;

    /// Checks the supervision against a batch of `n_rays` rays (called after the batch itself
    /// was checked).
    fn check(&self, n_rays: usize) -> Result<(), ModelError>;

    /// The colour composited behind the rays before the loss compares them, given the render
    /// configuration's background.
    fn background(&self, render_background: [f32; 3]) -> [f32; 3];

    /// Loss of ray `ray` (its index in the batch) with composited colour `rgb` and opacity
    /// `opacity` (`valid`: the ray has at least one sample). Adds the ray's terms to `sums` and
    /// returns `(∂L/∂rgb, ∂L/∂opacity)`.
    fn ray(
        &self,
        counts: &BatchCounts,
        ray: usize,
        rgb: [f64; 3],
        opacity: f64,
        valid: bool,
        sums: &mut Self::Sums,
    ) -> ([f64; 3], f64);

    /// Weights of the eikonal and curvature terms of one sample.
    fn sample_weights(&self, counts: &BatchCounts) -> SampleWeights;

    /// `into += from`, term by term.
    fn merge(into: &mut Self::Sums, from: &Self::Sums);
}
