//! The training loop: one step = occupancy update, ray batch, forward/backward, AdamW, dynamic
//! ray count. Everything random in step `k` is seeded from `(seed, k)`, so a run resumed from a
//! checkpoint at step `k` continues bit for bit like an uninterrupted one.

use super::adam::{AdamW, AdamWConfig, OptimError};
use super::checkpoint::TrainState;
use super::data::{Batch, TrainData};
use super::depth::{DepthConfig, DepthPrior, DepthStep};
use super::error_map::{ErrorMap, ErrorMapConfig};
use super::hull::InitConfig;
use super::loss::{StepOutput, StepSinks, Targets, TrainStep};
use super::pose_refine::{PoseRefineConfig, PoseRefiner, PoseStep};
use super::schedule::LrSchedule;
use crate::render::model::{ModelError, NeusModel, RayBatch};
use crate::scene::Camera;
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};
use std::sync::atomic::AtomicU32;

/// Optimisation settings (`[train]` in the TOML config).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrainConfig {
    /// Training steps (the reference: 20000).
    pub iterations: u64,
    /// AdamW hyper-parameters (base learning rate 1e-2; the variance group uses 0.1× of it).
    pub optimizer: AdamWConfig,
    /// Learning-rate multiplier over the run.
    pub lr: LrSchedule,
    /// Write a checkpoint every this many steps (0: only at the end).
    pub checkpoint_every: u64,
    /// Consecutive steps the NaN guard may skip before the run stops as diverged.
    pub max_consecutive_skips: u32,
    /// How the SDF starts (`[train.init]`; the sphere init by default, see [`super::hull`]).
    pub init: InitConfig,
    /// Error-map ray sampling (`[train.error_map]`; off by default, half the rays in the `fast`
    /// preset; see [`super::error_map`]).
    pub error_map: ErrorMapConfig,
    /// Depth prior from multi-view stereo (`[train.depth]`; off unless asked for or switched
    /// on, see [`super::depth`]).
    pub depth: DepthConfig,
    /// Per-view pose refinement (`[train.pose_refine]`; off by default and then absent from
    /// the configuration's text, see [`super::pose_refine`]).
    #[serde(skip_serializing_if = "PoseRefineConfig::is_default")]
    pub pose_refine: PoseRefineConfig,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            iterations: 20000,
            optimizer: AdamWConfig::default(),
            lr: LrSchedule::default(),
            checkpoint_every: 1000,
            max_consecutive_skips: 20,
            init: InitConfig::default(),
            error_map: ErrorMapConfig::default(),
            depth: DepthConfig::default(),
            pose_refine: PoseRefineConfig::default(),
        }
    }
}

/// Why training stopped early.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// The model refused a batch (a programming error or corrupt data).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The optimiser's NaN guard skipped too many steps in a row.
    #[error("training diverged at step {step}: {consecutive} consecutive steps had non-finite updates (last: {detail}); lower the learning rate")]
    Diverged {
        step: u64,
        consecutive: u32,
        detail: String,
    },
    /// Any other optimiser failure.
    #[error(transparent)]
    Optim(OptimError),
    /// The training state does not fit the trainer's settings.
    #[error("training state: {0}")]
    State(String),
}

/// What one step did.
#[derive(Clone, Debug)]
pub struct StepReport {
    /// The step that ran (0-based).
    pub step: u64,
    /// Loss terms and counts from the model.
    pub out: StepOutput,
    /// Rays in this step's batch.
    pub rays: usize,
    /// Learning-rate multiplier used.
    pub lr_factor: f64,
    /// `Some(reason)` when the NaN guard skipped the update.
    pub skipped: Option<String>,
    /// Whether the occupancy grid was updated before the step.
    pub occupancy_updated: bool,
    /// What the depth prior did (`None` when off or outside its steps).
    pub depth: Option<DepthStep>,
    /// What pose refinement did (`None` when off or the step was skipped).
    pub pose: Option<PoseStep>,
}

/// Independent random streams of a step.
#[derive(Clone, Copy)]
enum Stream {
    Rays = 1,
    Augment = 2,
    Jitter = 3,
    Occupancy = 4,
}

/// A 64-bit seed for `(seed, step, stream)` (SplitMix64 finaliser over a combined key; Steele et
/// al. 2014), so each step's randomness depends on nothing but its coordinates.
fn step_seed(seed: u64, step: u64, stream: Stream) -> u64 {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(step.wrapping_mul(0xBF58_476D_1CE4_E5B9))
        .wrapping_add((stream as u64).wrapping_mul(0x94D0_49BB_1331_11EB));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Runs training steps for one model on one data set.
pub struct Trainer<'a> {
    model: &'a NeusModel,
    data: &'a TrainData,
    config: &'a TrainConfig,
    seed: u64,
    aug_seed: u64,
    grads: Vec<f32>,
    batch: Batch,
    consecutive_skips: u32,
    depth: Option<DepthPrior>,
    /// `[rays]` per-ray colour errors of the step (error-map sampling only).
    ray_errors: Vec<AtomicU32>,
    /// Pose refinement's buffers (`None` when off).
    pose: Option<PoseRefiner>,
}

impl<'a> Trainer<'a> {
    /// `seed` drives ray sampling, jitter and occupancy updates; `aug_seed` the augmentations.
    pub fn new(
        model: &'a NeusModel,
        data: &'a TrainData,
        config: &'a TrainConfig,
        seed: u64,
        aug_seed: u64,
    ) -> Self {
        Self {
            model,
            data,
            config,
            seed,
            aug_seed,
            grads: vec![0.0; model.n_params()],
            batch: Batch::default(),
            consecutive_skips: 0,
            depth: None,
            ray_errors: Vec::new(),
            pose: None,
        }
    }

    /// Refines the poses of the training cameras `cameras` (normalised frame, the order given
    /// to [`TrainData::new`]) with the field, as `config.pose_refine` says
    /// ([`super::pose_refine`]); the state then carries the corrections.
    pub fn with_pose_refinement(mut self, cameras: &[Camera]) -> Self {
        self.pose = Some(PoseRefiner::new(&self.config.pose_refine, cameras));
        self
    }

    /// Adds the depth prior (`config.depth`, [`super::depth`]) to every step from its start step
    /// to its end step.
    pub fn with_depth_prior(mut self, prior: DepthPrior) -> Self {
        self.depth = Some(prior);
        self
    }

    /// Adds the depth prior part-way through a run (the automatic switch,
    /// [`super::depth_auto`]); it applies from its start step as with [`Self::with_depth_prior`].
    pub fn set_depth_prior(&mut self, prior: DepthPrior) {
        self.depth = Some(prior);
    }

    /// The state at step 0: seeded parameters, fresh moments, an all-occupied grid.
    pub fn initial_state(&self) -> TrainState {
        TrainState {
            step: 0,
            params: self.model.init_params(self.seed),
            adam: AdamW::new(self.config.optimizer.clone(), self.model.n_params()),
            occ: self.model.new_occupancy_grid(),
            num_rays: self.model.config.render.train_num_rays.max(1),
            skipped_steps: 0,
            error_map: self
                .config
                .error_map
                .enabled()
                .then(|| ErrorMap::new(&self.config.error_map, &self.data.sizes())),
            pose: self.pose.as_ref().map(|r| r.new_state()),
        }
    }

    /// Runs step `state.step` and advances the state.
    pub fn step(&mut self, state: &mut TrainState) -> Result<StepReport, TrainError> {
        let step = state.step;
        let model = self.model;
        let rcfg = &model.config.render;
        let sched = model.config.schedule(step);
        let occupancy_updated = rcfg.occupancy.enabled
            && model.update_occupancy(
                &state.params,
                &mut state.occ,
                step,
                sched,
                step_seed(self.seed, step, Stream::Occupancy),
            );
        let mut rng = Pcg64Mcg::seed_from_u64(step_seed(self.seed, step, Stream::Rays));
        let mut aug_rng = Pcg64Mcg::seed_from_u64(step_seed(self.aug_seed, step, Stream::Augment));
        if let Some(m) = state.error_map.as_mut().filter(|m| m.rebuilds_at(step)) {
            m.rebuild();
        }
        self.data.sample(
            state.num_rays,
            &mut rng,
            &mut aug_rng,
            state.error_map.as_ref(),
            &mut self.batch,
        );
        let refine = match (self.pose.as_mut(), state.pose.as_ref()) {
            (Some(r), Some(ps)) => {
                if r.gated() != ps.gate.is_some() {
                    return Err(TrainError::State(format!(
                        "pose refinement's gate is {} but the training state {} its sums (a \
                         checkpoint from another configuration?)",
                        if r.gated() { "on" } else { "off" },
                        if ps.gate.is_some() { "holds" } else { "lacks" }
                    )));
                }
                if (ps.corrections.len(), ps.focal.len()) != (r.n_views(), r.n_focal()) {
                    return Err(TrainError::State(format!(
                        "the training state holds corrections of {} views and {} focal scales; \
                         this scene's refinement needs {} and {}",
                        ps.corrections.len(),
                        ps.focal.len(),
                        r.n_views(),
                        r.n_focal()
                    )));
                }
                let b = &mut self.batch;
                let when = (step, self.config.iterations);
                r.correct(ps, &b.views, &mut b.origins, &mut b.dirs, when);
                true
            }
            (None, None) => false,
            (r, ps) => {
                return Err(TrainError::State(format!(
                    "pose refinement is {} but the training state {} its corrections (a \
                     checkpoint from another configuration?)",
                    if r.is_some() { "on" } else { "off" },
                    if ps.is_some() { "holds" } else { "lacks" }
                )))
            }
        };
        let sink = state.error_map.is_some().then(|| {
            let n = self.batch.len();
            if self.ray_errors.len() < n {
                self.ray_errors.resize_with(n, || AtomicU32::new(0));
            }
            &self.ray_errors[..n]
        });
        // The gradient buffer is zero here: it starts zeroed and every optimiser step (or
        // skipped step) below leaves it zeroed.
        let b = &self.batch;
        let out = model.train_step_recording::<f32>(
            &state.params,
            &mut self.grads,
            &RayBatch {
                origins: &b.origins,
                dirs: &b.dirs,
                codes: &b.codes,
                p: &b.p,
            },
            &Targets {
                rgb: &b.rgb,
                mask: self.data.has_masks().then_some(&b.mask[..]),
            },
            sched,
            rcfg.occupancy.enabled.then_some(&state.occ),
            step_seed(self.seed, step, Stream::Jitter),
            StepSinks {
                ray_errors: sink,
                ray_grads: self.pose.as_ref().and_then(|r| r.wanted_cells()),
            },
        )?;
        if let (Some(m), Some(errors)) = (state.error_map.as_mut(), sink) {
            m.record(&b.views, &b.pixels, errors);
        }
        let depth = self.depth.as_ref().and_then(|d| {
            d.add_grad(
                model,
                &state.params,
                step,
                sched.active_levels,
                &self.batch,
                &mut self.grads,
            )
        });
        let lr_factor = self.config.lr.factor(step, self.config.iterations);
        let skipped = match state.adam.step_and_zero_grads(
            &mut state.params,
            &mut self.grads,
            &model.layout,
            lr_factor as f32,
        ) {
            Ok(()) => {
                self.consecutive_skips = 0;
                None
            }
            Err(e @ OptimError::NonFinite { .. }) => {
                // A skipped step changes nothing, so the gradients are still to be cleared.
                self.grads.iter_mut().for_each(|g| *g = 0.0);
                self.consecutive_skips += 1;
                state.skipped_steps += 1;
                if self.consecutive_skips > self.config.max_consecutive_skips {
                    return Err(TrainError::Diverged {
                        step,
                        consecutive: self.consecutive_skips,
                        detail: e.to_string(),
                    });
                }
                Some(e.to_string())
            }
            Err(e) => {
                self.grads.iter_mut().for_each(|g| *g = 0.0);
                return Err(TrainError::Optim(e));
            }
        };
        let pose = match (
            refine && skipped.is_none(),
            self.pose.as_mut(),
            state.pose.as_mut(),
        ) {
            (true, Some(r), Some(ps)) => {
                Some(r.update(ps, &self.batch.views, step, self.config.iterations))
            }
            _ => None,
        };
        let budget = rcfg.train_num_rays * rcfg.num_samples_per_ray;
        let rays = state.num_rays;
        state.num_rays = next_num_rays(rays, out.n_samples, budget, rcfg.max_train_num_rays);
        state.step += 1;
        Ok(StepReport {
            step,
            out,
            rays,
            lr_factor,
            skipped,
            occupancy_updated,
            depth,
            pose,
        })
    }
}

/// The dynamic ray count of instant-nsr-pl (`systems/neus.py`, `training_step`): scale the ray
/// count towards the sample budget, smooth 0.9/0.1, cap at `max_rays`.
pub fn next_num_rays(
    current: usize,
    samples_used: usize,
    sample_budget: usize,
    max_rays: usize,
) -> usize {
    let used = samples_used.max(1) as f64;
    let target = (current as f64 * (sample_budget as f64 / used)) as usize;
    let next = (current as f64 * 0.9 + target as f64 * 0.1) as usize;
    next.clamp(1, max_rays.max(1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_seeds_differ_across_steps_streams_and_seeds() {
        let mut seen = std::collections::HashSet::new();
        for seed in 0..4 {
            for step in 0..100 {
                for s in [
                    Stream::Rays,
                    Stream::Augment,
                    Stream::Jitter,
                    Stream::Occupancy,
                ] {
                    assert!(seen.insert(step_seed(seed, step, s)));
                }
            }
        }
    }

    #[test]
    fn dynamic_ray_count() {
        // Twice the budget used: move 10% of the way to half the rays.
        assert_eq!(next_num_rays(1000, 2000, 1000, 8192), 950);
        assert_eq!(next_num_rays(8000, 1, 1 << 20, 8192), 8192);
    }
}
