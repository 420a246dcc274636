//! The NeuS model: configuration, flat parameters, and the batched forward/backward of a training
//! step, plus the inference entry points (SDF of points, rendering rays, occupancy updates).
//!
//! Per sample (midpoint `x` of a marched interval), the SDF network is evaluated at `x` and at the
//! six taps `x ± ε·e_k` (clamped to the box; `ε` = one cell of the finest active level). The
//! central differences give the SDF gradient `g`, the normal `n = g/max(|g|, 1e-12)` and the
//! eikonal term `(|g| − 1)²`. With only first derivatives anywhere, every backward pass is first
//! order (instant-nsr-pl `grad_type: finite_difference`).
//!
//! Work is split into fixed chunks of whole rays (`chunk_samples`, 256 by default: a chunk's
//! buffers stay in the L2 cache), the chunks into `shards` contiguous groups run in parallel with
//! rayon; each shard accumulates gradients in its own buffer (shard 0 directly in the caller's),
//! and the buffers are summed in shard order. The bits of the result depend only on the inputs,
//! the seed and `shards`, never on thread scheduling. The shard buffers and scratch vectors are
//! kept inside the model between steps (a cache behind a mutex, see `WorkspaceCache`), so a step
//! allocates nothing of the parameter size.
//!
//! Hot paths (measured in `benches/field.rs`): the level-parallel finite-difference stencil of
//! the hash grid ([`crate::field::lanes`]) with software prefetching, register-blocked MLP
//! kernels ([`crate::field::dense`]) with fused activations, the SDF channel of the taps computed
//! in the hidden layer's epilogue. The large buffers should come from
//! [`crate::field::alloc::LargeAligned`] (cache-line alignment, huge pages).

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::alpha::{inv_s_from_variance, neus_alpha, AlphaGrad};
use super::composite::{composite_backward, composite_forward};
use super::occupancy::{OccupancyConfig, OccupancyGrid};
use super::rays::{march_rays, RaySamples};
use super::scheduled::Scheduled;
use crate::field::config::ConfigError;
use crate::field::mlp::MlpTape;
use crate::field::sh::{sh4, SH_DIM};
use crate::field::{sigmoid, Activation, FieldConfig, HashGrid, Mlp, ParamLayout, Real};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// One rendered ray: index, colour, opacity, depth, normal.
type RayResult = (usize, [f32; 3], f32, f32, [f32; 3]);

/// Rendering and sampling settings (instant-nsr-pl `configs/neus-dtu-wmask.yaml`, `model:`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderConfig {
    /// Half-size of the marched box `[-r, r]³` in normalised units (1.0).
    pub radius: f32,
    /// Sets the march step `Δ = 1.732·2r / num_samples_per_ray` (1024).
    pub num_samples_per_ray: usize,
    /// Stratified jitter of each ray's first interval during training (true).
    pub randomized: bool,
    /// Background colour composited behind the object (white, `background_color: white`).
    pub background: [f32; 3],
    /// Steps over which the cos anneal ratio goes from 0 to 1 (20000; 0 = annealed from the
    /// start).
    pub cos_anneal_end: u64,
    /// Initial value of the variance parameter `v`, `inv_s = exp(10·v)` (0.3).
    pub variance_init: f32,
    /// Empty-space skipping.
    pub occupancy: OccupancyConfig,
    /// Initial rays per batch of the dynamic ray count (256).
    pub train_num_rays: usize,
    /// Cap of the dynamic ray count (8192).
    pub max_train_num_rays: usize,
    /// Samples per work chunk (performance knob; results do not depend on it beyond rounding).
    pub chunk_samples: usize,
    /// Parallel gradient shards; 0 = rayon's thread count. Fix it to reproduce bits across
    /// machines.
    pub shards: usize,
}

impl Default for RenderConfig {
    fn default() -> Self {
        Self {
            radius: 1.0,
            num_samples_per_ray: 1024,
            randomized: true,
            background: [1.0, 1.0, 1.0],
            cos_anneal_end: 20000,
            variance_init: 0.3,
            occupancy: OccupancyConfig::default(),
            train_num_rays: 256,
            max_train_num_rays: 8192,
            chunk_samples: 256,
            shards: 0,
        }
    }
}

/// Loss weights (instant-nsr-pl `systems/neus.py` `training_step` and the YAML's `system.loss`):
/// `lambda_rgb_l1: 1`, `lambda_rgb_mse: 0`, `lambda_eikonal: 0.1`. The mask BCE weight is 0.1 as in
/// ../shared/DESIGN.md §5 and instant-nsr-pl `neus-blender.yaml` / `neuralangelo-dtu-wmask.yaml`
/// (`neus-dtu-wmask.yaml` itself sets 0.0 and only masks the target colours).
///
/// Each weight is a [`Scheduled`] value, as instant-nsr-pl reads its `lambda_*` through `C()`: a
/// number, or `[start_step, start, end, end_step]` (e.g. `eikonal = [0, 0.1, 0.01, 5000]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LossConfig {
    pub rgb_l1: Scheduled,
    pub rgb_mse: Scheduled,
    pub eikonal: Scheduled,
    pub mask: Scheduled,
    /// Curvature loss weight: mean `|Δf|` over samples, the Laplacian taken from the six
    /// finite-difference taps and the centre (`Σ_k f(x ± ε e_k) − 6 f(x)) / ε²`), Neuralangelo
    /// §3.2 (`projects/neuralangelo/utils/losses.py`, `curvature_loss`). 0 (off) by default.
    pub curvature: Scheduled,
    /// How the mask BCE keeps `log` finite (issue 13).
    pub mask_bce: MaskBce,
    /// NeuS-style colour loss (`exp_runner.py`): the colour error only inside the mask,
    /// normalised by `3·Σ mask`, and no background colour composited. `false`: instant-nsr-pl
    /// style, every ray's target composited on `render.background` where the mask is 0.
    pub color_in_mask: bool,
}

/// How the mask BCE of the opacity `o ∈ [0, 1]` keeps its logarithms finite.
///
/// NeuS (`exp_runner.py`) and instant-nsr-pl (`systems/neus.py`) clip `o` to `[1e-3, 1 − 1e-3]`
/// before `binary_cross_entropy`; the clip passes no gradient outside that range, so a surface
/// that became fully opaque where the mask says background (the membrane across a hole) gets no
/// gradient from the mask at all, and the colour network paints it with the background. Measured
/// on the `torus` (issue 13): clip 5.49 mm, squash 0.73 mm at seed 0 (fast preset).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MaskBce {
    /// `o' = clamp(o, 1e-3, 1 − 1e-3)`: the references' form, no gradient when saturated.
    Clamp,
    /// `o' = 1e-3 + (1 − 2·1e-3)·o`: an affine squash into the same range, differentiable
    /// everywhere, gradient up to ~1000× the weight at saturation (the default).
    Squash,
}

impl Default for LossConfig {
    fn default() -> Self {
        Self {
            rgb_l1: Scheduled::Constant(1.0),
            rgb_mse: Scheduled::Constant(0.0),
            eikonal: Scheduled::Constant(0.1),
            mask: Scheduled::Constant(0.1),
            curvature: Scheduled::Constant(0.0),
            mask_bce: MaskBce::Squash,
            color_in_mask: false,
        }
    }
}

/// The loss weights at one step (from [`LossConfig`] through [`ModelConfig::schedule`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LossWeights {
    pub rgb_l1: f32,
    pub rgb_mse: f32,
    pub eikonal: f32,
    pub mask: f32,
    pub curvature: f32,
}

impl LossConfig {
    /// The weights at `step`.
    pub fn at(&self, step: u64) -> LossWeights {
        LossWeights {
            rgb_l1: self.rgb_l1.at(step) as f32,
            rgb_mse: self.rgb_mse.at(step) as f32,
            eikonal: self.eikonal.at(step) as f32,
            mask: self.mask.at(step) as f32,
            curvature: self.curvature.at(step) as f32,
        }
    }
}

/// Everything that defines a model (sits in the TOML config as `[model]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct ModelConfig {
    pub field: FieldConfig,
    pub render: RenderConfig,
    pub loss: LossConfig,
}

/// Values that change with the training step, passed explicitly (no hidden schedule state).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Schedule {
    /// Cos anneal ratio in `[0,1]` (`min(1, step/cos_anneal_end)`).
    pub cos_anneal: f32,
    /// Active hash-grid levels (progressive mask).
    pub active_levels: usize,
    /// Loss weights.
    pub loss: LossWeights,
}

impl ModelConfig {
    /// The schedule of instant-nsr-pl at `step` (`NeuSModel.update_step`).
    pub fn schedule(&self, step: u64) -> Schedule {
        let end = self.render.cos_anneal_end;
        Schedule {
            cos_anneal: if end == 0 {
                1.0
            } else {
                (step as f64 / end as f64).min(1.0) as f32
            },
            active_levels: self.field.hash_grid.active_levels(step),
            loss: self.loss.at(step),
        }
    }

    /// The schedule used for inference: annealed, all scheduled levels at `step`.
    pub fn inference_schedule(&self, step: u64) -> Schedule {
        Schedule {
            cos_anneal: 1.0,
            active_levels: self.field.hash_grid.active_levels(step),
            loss: self.loss.at(step),
        }
    }
}

/// Errors of the model entry points; each names the offending input.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error("model config: `{key}` = {value} is invalid: {why}")]
    Invalid {
        key: &'static str,
        value: String,
        why: &'static str,
    },
    #[error("batch: `{what}` has {got} entries, expected {expected}")]
    Shape {
        what: &'static str,
        expected: usize,
        got: usize,
    },
    #[error("batch: ray {ray} uses appearance code {code}, but the table has {n_codes} codes")]
    CodeOutOfRange {
        ray: usize,
        code: u32,
        n_codes: usize,
    },
    #[error("batch: ray {ray} has a non-finite origin or direction")]
    NonFiniteRay { ray: usize },
    #[error("parameter buffer has {got} values, the layout needs {expected}")]
    ParamLen { expected: usize, got: usize },
}

/// Rays of a batch (normalised space, f32) and their appearance inputs.
#[derive(Debug, Clone, Copy)]
pub struct RayBatch<'a> {
    /// `[n][3]` ray origins.
    pub origins: &'a [[f32; 3]],
    /// `[n][3]` unit directions.
    pub dirs: &'a [[f32; 3]],
    /// `[n]` appearance code per ray, or empty (code 0 for every ray). Ignored when
    /// `n_codes = 0`.
    pub codes: &'a [u32],
    /// `[n]` augmentation intensity per ray, or empty (0). Used only with `with_scalar`.
    pub p: &'a [f32],
}

/// Supervision of a batch.
#[derive(Debug, Clone, Copy)]
pub struct Targets<'a> {
    /// `[n][3]` target colours in `[0,1]` (already composited on the background where masked).
    pub rgb: &'a [[f32; 3]],
    /// `[n]` foreground mask in `[0,1]`, or `None` (no mask loss).
    pub mask: Option<&'a [f32]>,
}

/// CPU seconds per phase, summed over shards.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PhaseTimes {
    pub sample: f64,
    pub encode_fwd: f64,
    pub sdf_mlp_fwd: f64,
    pub color_fwd: f64,
    pub render: f64,
    pub color_bwd: f64,
    pub sdf_mlp_bwd: f64,
    pub encode_bwd: f64,
    pub reduce: f64,
}

impl PhaseTimes {
    fn add(&mut self, o: &PhaseTimes) {
        self.sample += o.sample;
        self.encode_fwd += o.encode_fwd;
        self.sdf_mlp_fwd += o.sdf_mlp_fwd;
        self.color_fwd += o.color_fwd;
        self.render += o.render;
        self.color_bwd += o.color_bwd;
        self.sdf_mlp_bwd += o.sdf_mlp_bwd;
        self.encode_bwd += o.encode_bwd;
        self.reduce += o.reduce;
    }
}

/// Result of [`NeusModel::train_step`]. Loss terms are unweighted; `total` is the weighted sum
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

/// Rendered rays (no gradients).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RenderOutput {
    /// `[n][3]` colour including the background.
    pub rgb: Vec<[f32; 3]>,
    /// `[n]` accumulated weight.
    pub opacity: Vec<f32>,
    /// `[n]` `Σ w_i t_i` (normalised units; divide by opacity for the expected surface depth).
    pub depth: Vec<f32>,
    /// `[n][3]` normalised composited normal (zero for empty rays), normalised space.
    pub normal: Vec<[f32; 3]>,
    pub n_samples: usize,
}

/// The model: shapes and the parameter layout (parameters themselves live in a flat buffer the
/// caller owns).
#[derive(Debug, Clone)]
pub struct NeusModel {
    pub config: ModelConfig,
    pub grid: HashGrid,
    pub sdf_mlp: Mlp,
    pub color_mlp: Mlp,
    /// Groups in this order: `hash_grid`, `sdf_mlp`, `color_mlp`, `variance`, `appearance`.
    pub layout: ParamLayout,
    /// Buffers [`NeusModel::train_step`] reuses between calls (see [`WorkspaceCache`]).
    workspace: WorkspaceCache,
}

/// Buffers a training step keeps between calls so that it allocates and zeroes nothing of the
/// parameter size: the gradient buffers of shards `1..` (all zero between steps; shard 0 adds
/// into the caller's buffer) and each shard's scratch vectors.
struct StepWorkspace<T> {
    extra: Vec<Vec<T>>,
    scratch: Vec<Scratch<T>>,
}

impl<T> Default for StepWorkspace<T> {
    fn default() -> Self {
        Self {
            extra: Vec::new(),
            scratch: Vec::new(),
        }
    }
}

/// A cache holding at most one [`StepWorkspace`] (of whichever scalar type was used last).
/// Taken out for the duration of a step and put back after it, so a step that panics drops it
/// (no half-written buffer is ever reused) and concurrent steps on one model each get their own.
/// Cloning a model gives the clone an empty cache. Holds about one gradient buffer per extra
/// shard (56 MB per shard for the default network).
#[derive(Default)]
struct WorkspaceCache(std::sync::Mutex<Option<Box<dyn std::any::Any + Send>>>);

impl WorkspaceCache {
    fn take<T: Real>(&self) -> StepWorkspace<T> {
        let cached = self.0.lock().ok().and_then(|mut g| g.take());
        cached
            .and_then(|b| b.downcast::<StepWorkspace<T>>().ok())
            .map(|b| *b)
            .unwrap_or_default()
    }

    fn put<T: Real>(&self, ws: StepWorkspace<T>) {
        if let Ok(mut g) = self.0.lock() {
            *g = Some(Box::new(ws));
        }
    }
}

impl Clone for WorkspaceCache {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl std::fmt::Debug for WorkspaceCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("WorkspaceCache")
    }
}

/// Mutable gradient views of each group.
struct GroupsMut<'a, T> {
    hash: &'a mut [T],
    sdf: &'a mut [T],
    color: &'a mut [T],
    var: &'a mut [T],
    app: &'a mut [T],
}

struct Groups<'a, T> {
    hash: &'a [T],
    sdf: &'a [T],
    color: &'a [T],
    var: &'a [T],
    app: &'a [T],
}

/// Per-shard buffers, reused across chunks.
#[derive(Default)]
struct Scratch<T> {
    /// Sample centres `[n][3]` and their finite-difference tap coordinates `[n][axis][+/−]`.
    xs: Vec<[T; 3]>,
    taps: Vec<[[T; 2]; 3]>,
    dir: Vec<[T; 3]>,
    enc: Vec<T>,
    sdf_tape: MlpTape<T>,
    out: Vec<T>,
    tap: Vec<T>,
    grad: Vec<[T; 3]>,
    normal: Vec<[T; 3]>,
    cin: Vec<T>,
    col_tape: MlpTape<T>,
    raw: Vec<T>,
    rgb: Vec<[T; 3]>,
    t: Vec<T>,
    alpha: Vec<T>,
    agrad: Vec<AlphaGrad<T>>,
    d_alpha: Vec<T>,
    d_rgb: Vec<[T; 3]>,
    d_raw: Vec<T>,
    d_hc: Vec<T>,
    d_cin: Vec<T>,
    d_out: Vec<T>,
    d_tap: Vec<T>,
    d_h: Vec<T>,
    d_enc: Vec<T>,
    tmp: Vec<T>,
}

/// Loss sums of a shard.
#[derive(Default, Clone, Copy)]
struct Sums {
    l1: f64,
    sq_valid: f64,
    sq_all: f64,
    eik: f64,
    mask: f64,
    curv: f64,
    d_inv_s: f64,
}

struct StepCtx<'a> {
    batch: &'a RayBatch<'a>,
    targets: Option<&'a Targets<'a>>,
    samples: &'a RaySamples,
    sched: Schedule,
    inv_s: f64,
    n_valid: usize,
    /// Σ mask over the batch (NeuS colour normaliser).
    mask_sum: f64,
}

impl NeusModel {
    /// Builds the model's shapes and parameter layout from a config (validated here).
    pub fn new(config: ModelConfig) -> Result<Self, ModelError> {
        config.field.validate()?;
        let r = &config.render;
        if !(r.radius > 0.0 && r.radius.is_finite()) {
            return Err(ModelError::Invalid {
                key: "render.radius",
                value: r.radius.to_string(),
                why: "must be finite and > 0",
            });
        }
        if r.num_samples_per_ray == 0 || r.chunk_samples == 0 {
            return Err(ModelError::Invalid {
                key: "render.num_samples_per_ray/chunk_samples",
                value: format!("{}/{}", r.num_samples_per_ray, r.chunk_samples),
                why: "must be > 0",
            });
        }
        if r.occupancy.resolution == 0 || r.occupancy.resolution > 1024 {
            return Err(ModelError::Invalid {
                key: "render.occupancy.resolution",
                value: r.occupancy.resolution.to_string(),
                why: "must be in 1..=1024",
            });
        }
        let f = &config.field;
        let grid = HashGrid::new(&f.hash_grid);
        let mut sdf_dims = vec![grid.output_dim()];
        sdf_dims.extend(std::iter::repeat_n(f.sdf.n_neurons, f.sdf.n_hidden_layers));
        sdf_dims.push(f.sdf.feature_dim);
        let sdf_mlp = Mlp::new(
            sdf_dims,
            if f.sdf.sphere_init {
                Activation::Softplus {
                    beta: f.sdf.softplus_beta,
                }
            } else {
                Activation::Relu
            },
        );
        let mut col_dims = vec![f.color_input_dim()];
        col_dims.extend(std::iter::repeat_n(
            f.color.n_neurons,
            f.color.n_hidden_layers,
        ));
        col_dims.push(3);
        let color_mlp = Mlp::new(col_dims, Activation::Relu);
        let mut layout = ParamLayout::default();
        layout.push(HASH_GRID, vec![grid.n_entries, grid.n_features], 1.0);
        layout.push(SDF_MLP, vec![sdf_mlp.n_params()], 1.0);
        layout.push(COLOR_MLP, vec![color_mlp.n_params()], 1.0);
        layout.push(VARIANCE, vec![1], 0.1);
        let a = &f.appearance;
        layout.push(
            APPEARANCE,
            vec![a.n_codes, if a.n_codes > 0 { a.code_dim } else { 0 }],
            1.0,
        );
        Ok(Self {
            config,
            grid,
            sdf_mlp,
            color_mlp,
            layout,
            workspace: WorkspaceCache::default(),
        })
    }

    /// Number of parameters.
    pub fn n_params(&self) -> usize {
        self.layout.total()
    }

    /// Seeded initial parameters: hash table `U(±1e-4)`, SDF MLP sphere init (or Kaiming),
    /// colour MLP Kaiming-uniform with zero biases, `v = variance_init`, appearance table zeros.
    pub fn init_params(&self, seed: u64) -> Vec<f32> {
        let mut p = vec![0f32; self.n_params()];
        let mut rng = Pcg64Mcg::seed_from_u64(seed);
        let g = split_mut(&self.layout, &mut p);
        self.grid.init(g.hash, &mut rng);
        let s = &self.config.field.sdf;
        if s.sphere_init {
            self.sdf_mlp
                .init_sphere(g.sdf, &mut rng, s.sphere_init_radius);
        } else {
            self.sdf_mlp.init_kaiming(g.sdf, &mut rng);
        }
        self.color_mlp.init_kaiming(g.color, &mut rng);
        g.var[0] = self.config.render.variance_init;
        g.app.fill(0.0);
        p
    }

    /// March step `Δ = 1.732·2r / num_samples_per_ray` (instant-nsr-pl `render_step_size`).
    pub fn render_step_size(&self) -> f32 {
        1.732 * 2.0 * self.config.render.radius / self.config.render.num_samples_per_ray as f32
    }

    /// `inv_s` of a parameter buffer.
    pub fn inv_s(&self, params: &[f32]) -> f32 {
        let v = params[group(&self.layout, VARIANCE).start];
        inv_s_from_variance(v).0
    }

    /// Finite-difference step for `active` levels (normalised units).
    pub fn fd_eps(&self, active: usize) -> f64 {
        self.grid.fd_eps(active, self.config.render.radius as f64)
    }

    /// An empty occupancy grid sized by the config (every cell occupied until the first update).
    pub fn new_occupancy_grid(&self) -> OccupancyGrid {
        OccupancyGrid::new(
            self.config.render.occupancy.resolution,
            self.config.render.radius,
        )
    }

    fn n_shards(&self) -> usize {
        match self.config.render.shards {
            0 => rayon::current_num_threads().max(1),
            s => s,
        }
    }

    fn check_params<T>(&self, params: &[T]) -> Result<(), ModelError> {
        if params.len() != self.n_params() {
            return Err(ModelError::ParamLen {
                expected: self.n_params(),
                got: params.len(),
            });
        }
        Ok(())
    }

    fn check_batch(&self, b: &RayBatch) -> Result<(), ModelError> {
        let n = b.origins.len();
        if b.dirs.len() != n {
            return Err(ModelError::Shape {
                what: "dirs",
                expected: n,
                got: b.dirs.len(),
            });
        }
        if !b.codes.is_empty() && b.codes.len() != n {
            return Err(ModelError::Shape {
                what: "codes",
                expected: n,
                got: b.codes.len(),
            });
        }
        if !b.p.is_empty() && b.p.len() != n {
            return Err(ModelError::Shape {
                what: "p",
                expected: n,
                got: b.p.len(),
            });
        }
        let n_codes = self.config.field.appearance.n_codes;
        if n_codes > 0 {
            if let Some((ray, &code)) = b
                .codes
                .iter()
                .enumerate()
                .find(|(_, &c)| c as usize >= n_codes)
            {
                return Err(ModelError::CodeOutOfRange { ray, code, n_codes });
            }
        }
        for (ray, (o, d)) in b.origins.iter().zip(b.dirs).enumerate() {
            if !o.iter().chain(d.iter()).all(|v| v.is_finite()) {
                return Err(ModelError::NonFiniteRay { ray });
            }
        }
        Ok(())
    }

    fn sample(
        &self,
        b: &RayBatch,
        occ: Option<&OccupancyGrid>,
        jitter_seed: Option<u64>,
    ) -> RaySamples {
        let jitter: Vec<f32> = match jitter_seed {
            Some(seed) => {
                let mut rng = Pcg64Mcg::seed_from_u64(seed);
                (0..b.origins.len()).map(|_| rng.random::<f32>()).collect()
            }
            None => Vec::new(),
        };
        let occ = occ.filter(|_| self.config.render.occupancy.enabled);
        march_rays(
            b.origins,
            b.dirs,
            self.config.render.radius,
            self.render_step_size(),
            &jitter,
            occ,
        )
    }

    /// Fixed chunking: consecutive whole rays, at most `chunk_samples` samples per chunk (a longer
    /// ray gets a chunk of its own). Returns ray boundaries.
    fn chunks(&self, s: &RaySamples) -> Vec<usize> {
        let cap = self.config.render.chunk_samples;
        let mut b = vec![0usize];
        let mut cur = 0usize;
        for r in 0..s.n_rays() {
            let m = s.range(r).len();
            if cur > 0 && cur + m > cap {
                b.push(r);
                cur = 0;
            }
            cur += m;
        }
        if *b.last().unwrap_or(&0) != s.n_rays() || s.n_rays() == 0 {
            b.push(s.n_rays());
        }
        b
    }

    /// One training step's forward and backward on a batch.
    ///
    /// Accumulates (adds) `∂total/∂params` into `grads` (same layout as `params`), returns the
    /// loss terms. `step_seed` seeds the stratified jitter. `occ`: the occupancy grid (or `None`
    /// to march everything). Generic over [`Real`] so the gradient checks run it in `f64`.
    #[allow(clippy::too_many_arguments)]
    pub fn train_step<T: Real>(
        &self,
        params: &[T],
        grads: &mut [T],
        batch: &RayBatch,
        targets: &Targets,
        sched: Schedule,
        occ: Option<&OccupancyGrid>,
        step_seed: u64,
    ) -> Result<StepOutput, ModelError> {
        self.check_params(params)?;
        self.check_params(grads)?;
        self.check_batch(batch)?;
        let n = batch.origins.len();
        if targets.rgb.len() != n {
            return Err(ModelError::Shape {
                what: "target rgb",
                expected: n,
                got: targets.rgb.len(),
            });
        }
        if let Some(m) = targets.mask {
            if m.len() != n {
                return Err(ModelError::Shape {
                    what: "mask",
                    expected: n,
                    got: m.len(),
                });
            }
        }
        let t0 = Instant::now();
        let jitter = self.config.render.randomized.then_some(step_seed);
        let samples = self.sample(batch, occ, jitter);
        let sample_time = t0.elapsed().as_secs_f64();
        let n_valid = (0..n).filter(|&r| !samples.range(r).is_empty()).count();
        let mask_sum: f64 = targets
            .mask
            .map_or(0.0, |m| m.iter().map(|&v| v as f64).sum());
        let pg = split(&self.layout, params);
        let (inv_s, d_inv_s_dv) = inv_s_from_variance(pg.var[0]);
        let ctx = StepCtx {
            batch,
            targets: Some(targets),
            samples: &samples,
            sched,
            inv_s: inv_s.to_f64(),
            n_valid,
            mask_sum,
        };
        let bounds = self.chunks(&samples);
        let n_chunks = bounds.len() - 1;
        let k = self.n_shards().min(n_chunks).max(1);
        let mut ws = self.workspace.take::<T>();
        if ws.extra.len() < k - 1 {
            ws.extra.resize_with(k - 1, Vec::new);
        }
        for e in ws.extra.iter_mut() {
            if e.len() != params.len() {
                *e = vec![T::ZERO; params.len()];
            }
        }
        ws.scratch
            .resize_with(k.max(ws.scratch.len()), Scratch::default);
        let mut views: Vec<&mut [T]> = Vec::with_capacity(k);
        views.push(&mut *grads);
        for e in ws.extra.iter_mut().take(k - 1) {
            views.push(&mut e[..]);
        }
        let results: Vec<(Sums, PhaseTimes)> = views
            .into_par_iter()
            .zip(ws.scratch[..k].par_iter_mut())
            .enumerate()
            .map(|(s, (g, scratch))| {
                let c0 = s * n_chunks / k;
                let c1 = (s + 1) * n_chunks / k;
                let mut sums = Sums::default();
                let mut times = PhaseTimes::default();
                let mut gg = split_mut(&self.layout, g);
                for c in c0..c1 {
                    self.chunk::<T, true>(
                        &pg,
                        Some(&mut gg),
                        &ctx,
                        bounds[c],
                        bounds[c + 1],
                        scratch,
                        &mut sums,
                        &mut times,
                        None,
                    );
                }
                (sums, times)
            })
            .collect();
        let t1 = Instant::now();
        let mut sums = Sums::default();
        let mut times = PhaseTimes {
            sample: sample_time,
            ..Default::default()
        };
        for (s, t) in &results {
            sums.l1 += s.l1;
            sums.sq_valid += s.sq_valid;
            sums.sq_all += s.sq_all;
            sums.eik += s.eik;
            sums.mask += s.mask;
            sums.curv += s.curv;
            sums.d_inv_s += s.d_inv_s;
            times.add(t);
        }
        // Fixed-order reduction of the shard buffers, parallel over index blocks; the shard
        // buffers are zeroed on the way, ready for the next step.
        if k > 1 {
            const BLOCK: usize = 1 << 14;
            let mut extra: Vec<std::slice::ChunksMut<'_, T>> = ws
                .extra
                .iter_mut()
                .take(k - 1)
                .map(|e| e.chunks_mut(BLOCK))
                .collect();
            let blocks: Vec<(&mut [T], Vec<&mut [T]>)> = grads
                .chunks_mut(BLOCK)
                .map(|gb| {
                    (
                        gb,
                        extra
                            .iter_mut()
                            .map(|e| e.next().expect("same length"))
                            .collect(),
                    )
                })
                .collect();
            blocks.into_par_iter().for_each(|(gb, es)| {
                for e in es {
                    for (a, b) in gb.iter_mut().zip(e.iter_mut()) {
                        *a += *b;
                        *b = T::ZERO;
                    }
                }
            });
        }
        self.workspace.put(ws);
        // Variance gradient: the per-sample ∂α/∂inv_s summed in f64, chained through exp(10v).
        let var_off = group(&self.layout, VARIANCE).start;
        grads[var_off] += T::from_f64(sums.d_inv_s) * d_inv_s_dv;
        times.reduce = t1.elapsed().as_secs_f64();
        let l = sched.loss;
        let nv = n_valid.max(1) as f64;
        let ns = samples.n_samples().max(1) as f64;
        // NeuS-style colour loss: normalised by the mask sum instead of the valid rays.
        let cn = if self.config.loss.color_in_mask && targets.mask.is_some() {
            mask_sum.max(1e-5)
        } else {
            nv
        };
        let out = StepOutput {
            rgb_l1: sums.l1 / (3.0 * cn),
            rgb_mse: sums.sq_valid / (3.0 * cn),
            eikonal: sums.eik / ns,
            curvature: sums.curv / ns,
            mask: if targets.mask.is_some() {
                sums.mask / n.max(1) as f64
            } else {
                0.0
            },
            total: 0.0,
            mse_all: sums.sq_all / (3.0 * n.max(1) as f64),
            n_rays: n,
            n_valid_rays: n_valid,
            n_samples: samples.n_samples(),
            inv_s: inv_s.to_f64(),
            times,
        };
        Ok(StepOutput {
            total: l.rgb_l1 as f64 * out.rgb_l1
                + l.rgb_mse as f64 * out.rgb_mse
                + l.eikonal as f64 * out.eikonal
                + l.mask as f64 * out.mask
                + l.curvature as f64 * out.curvature,
            ..out
        })
    }

    /// Renders rays without gradients (held-out views) with the given schedule (normally
    /// [`ModelConfig::inference_schedule`]), no jitter, and the occupancy grid if given.
    pub fn render(
        &self,
        params: &[f32],
        batch: &RayBatch,
        sched: Schedule,
        occ: Option<&OccupancyGrid>,
    ) -> Result<RenderOutput, ModelError> {
        self.check_params(params)?;
        self.check_batch(batch)?;
        let n = batch.origins.len();
        let samples = self.sample(batch, occ, None);
        let pg = split(&self.layout, params);
        let ctx = StepCtx {
            batch,
            targets: None,
            samples: &samples,
            sched,
            inv_s: inv_s_from_variance(pg.var[0]).0 as f64,
            n_valid: 0,
            mask_sum: 0.0,
        };
        let bounds = self.chunks(&samples);
        let parts: Vec<Vec<RayResult>> = (0..bounds.len() - 1)
            .into_par_iter()
            // One scratch per rayon job split, reused across its chunks.
            .map_init(Scratch::default, |scratch, c| {
                let mut sums = Sums::default();
                let mut times = PhaseTimes::default();
                let mut out = Vec::new();
                self.chunk::<f32, false>(
                    &pg,
                    None,
                    &ctx,
                    bounds[c],
                    bounds[c + 1],
                    scratch,
                    &mut sums,
                    &mut times,
                    Some(&mut out),
                );
                out
            })
            .collect();
        let mut o = RenderOutput {
            rgb: vec![[0.0; 3]; n],
            opacity: vec![0.0; n],
            depth: vec![0.0; n],
            normal: vec![[0.0; 3]; n],
            n_samples: samples.n_samples(),
        };
        for (r, c, op, d, nr) in parts.into_iter().flatten() {
            o.rgb[r] = c;
            o.opacity[r] = op;
            o.depth[r] = d;
            o.normal[r] = nr;
        }
        Ok(o)
    }

    /// SDF (channel 0 of the SDF network) at points `[n][3]` of the normalised space, with
    /// `active` hash-grid levels. Parallel over fixed chunks; usable as a marching-cubes closure:
    /// `|pts: &[[f32; 3]]| model.sdf(&params, pts, active)`.
    pub fn sdf(&self, params: &[f32], points: &[[f32; 3]], active: usize) -> Vec<f32> {
        let pg = split(&self.layout, params);
        let d = self.grid.output_dim();
        let r = self.config.render.radius;
        let mut out = vec![0f32; points.len()];
        const CH: usize = 1024;
        out.par_chunks_mut(CH)
            .zip(points.par_chunks(CH))
            .for_each_init(
                || (Vec::new(), MlpTape::default()),
                |(enc, tape), (o, pts)| {
                    let n = pts.len();
                    enc.resize(n * d, 0f32);
                    self.grid.encode_batch(pg.hash, pts, r, active, enc, d);
                    // The SDF channel straight from the hidden layer's epilogue.
                    self.sdf_mlp
                        .forward_hidden_with(pg.sdf, &enc[..n * d], n, tape, |i, h| {
                            o[i] = self.sdf_mlp.output_channel(pg.sdf, 0, h);
                        });
                },
            );
        out
    }

    /// Occupancy-grid update at training step `step` (see [`crate::render::occupancy`] for the
    /// rule). Evaluates the SDF at the planned points and turns it into the NeuS alpha of one
    /// render step with `cos = −1`, through the one alpha function. Returns whether it updated.
    pub fn update_occupancy(
        &self,
        params: &[f32],
        grid: &mut OccupancyGrid,
        step: u64,
        sched: Schedule,
        seed: u64,
    ) -> bool {
        let cfg = &self.config.render.occupancy;
        let Some((cells, pts)) = grid.plan_update(cfg, step, seed) else {
            return false;
        };
        let sdf = self.sdf(params, &pts, sched.active_levels);
        let inv_s = self.inv_s(params);
        let dt = self.render_step_size();
        let alpha: Vec<f32> = sdf
            .iter()
            .map(|&f| neus_alpha::<f32, false>(f, -1.0, dt, inv_s, 1.0).0)
            .collect();
        grid.apply_update(cfg, &cells, &alpha);
        true
    }

    /// The forward (and, when `TRAIN`, backward) of one chunk of rays `r0..r1`.
    #[allow(clippy::too_many_arguments)]
    fn chunk<T: Real, const TRAIN: bool>(
        &self,
        p: &Groups<T>,
        g: Option<&mut GroupsMut<T>>,
        ctx: &StepCtx,
        r0: usize,
        r1: usize,
        sc: &mut Scratch<T>,
        sums: &mut Sums,
        times: &mut PhaseTimes,
        render_out: Option<&mut Vec<RayResult>>,
    ) {
        let samples = ctx.samples;
        let s0 = samples.ray_start[r0];
        let s1 = samples.ray_start[r1];
        let n = s1 - s0;
        let cfgf = &self.config.field;
        let fdim = cfgf.sdf.feature_dim;
        let d = self.grid.output_dim();
        let wh = self.sdf_mlp.last_hidden_dim();
        let dc = cfgf.color_input_dim();
        let app = &cfgf.appearance;
        let radius = T::from_f32(self.config.render.radius);
        let active = ctx.sched.active_levels;
        let eps = T::from_f64(self.fd_eps(active));
        let inv_2eps = T::ONE / (eps + eps);
        let inv_s = T::from_f64(ctx.inv_s);
        let anneal = T::from_f32(ctx.sched.cos_anneal);
        let bg = self.config.render.background.map(T::from_f32);

        // ---- positions, taps, hash encoding ----
        let t_enc = Instant::now();
        sc.xs.clear();
        sc.taps.clear();
        sc.dir.clear();
        sc.t.clear();
        for r in r0..r1 {
            let o = ctx.batch.origins[r].map(T::from_f32);
            let dir = ctx.batch.dirs[r].map(T::from_f32);
            for s in samples.range(r) {
                let t = T::from_f32(samples.t[s]);
                let x = [o[0] + dir[0] * t, o[1] + dir[1] * t, o[2] + dir[2] * t];
                // Taps x ± ε·e_a, clamped to the box.
                let taps = [0, 1, 2].map(|a| {
                    [
                        (x[a] + eps).maxv(-radius).minv(radius),
                        (x[a] - eps).maxv(-radius).minv(radius),
                    ]
                });
                sc.xs.push(x);
                sc.taps.push(taps);
                sc.dir.push(dir);
                sc.t.push(t);
            }
        }
        sc.enc.resize(7 * n * d, T::ZERO);
        self.grid
            .encode_fd_batch(p.hash, &sc.xs, &sc.taps, radius, active, &mut sc.enc, |i| {
                tap_rows(i, n, d)
            });
        times.encode_fwd += t_enc.elapsed().as_secs_f64();

        // ---- SDF network on centres and taps ----
        let t_mlp = Instant::now();
        sc.out.resize(n * fdim, T::ZERO);
        sc.tap.resize(6 * n, T::ZERO);
        {
            // Taps need only the SDF channel: computed in the hidden layer's epilogue.
            let tap = &mut sc.tap;
            self.sdf_mlp
                .forward_hidden_with(p.sdf, &sc.enc, 7 * n, &mut sc.sdf_tape, |i, h| {
                    if i >= n {
                        tap[i - n] = self.sdf_mlp.output_channel(p.sdf, 0, h);
                    }
                });
        }
        let h = sc.sdf_tape.acts.last().expect("hidden layer");
        self.sdf_mlp
            .forward_last(p.sdf, &h[..n * wh], n, fdim, &mut sc.out);
        times.sdf_mlp_fwd += t_mlp.elapsed().as_secs_f64();

        // ---- gradients, normals, colour input, colour network ----
        let t_col = Instant::now();
        sc.grad.resize(n, [T::ZERO; 3]);
        sc.normal.resize(n, [T::ZERO; 3]);
        sc.cin.resize(n * dc, T::ZERO);
        let mut i = 0;
        for r in r0..r1 {
            let code = if app.n_codes > 0 {
                ctx.batch.codes.get(r).copied().unwrap_or(0) as usize
            } else {
                0
            };
            let pr = T::from_f32(ctx.batch.p.get(r).copied().unwrap_or(0.0));
            for _ in samples.range(r) {
                let tp = &sc.tap[6 * i..6 * i + 6];
                let gr = [
                    (tp[0] - tp[1]) * inv_2eps,
                    (tp[2] - tp[3]) * inv_2eps,
                    (tp[4] - tp[5]) * inv_2eps,
                ];
                let len = (gr[0] * gr[0] + gr[1] * gr[1] + gr[2] * gr[2]).sqrt();
                let l = len.maxv(T::from_f64(1e-12));
                let nr = [gr[0] / l, gr[1] / l, gr[2] / l];
                sc.grad[i] = gr;
                sc.normal[i] = nr;
                let row = &mut sc.cin[i * dc..(i + 1) * dc];
                row[..fdim].copy_from_slice(&sc.out[i * fdim..(i + 1) * fdim]);
                sh4(sc.dir[i], &mut row[fdim..fdim + SH_DIM]);
                row[fdim + SH_DIM..fdim + SH_DIM + 3].copy_from_slice(&nr);
                if app.n_codes > 0 {
                    let a0 = fdim + SH_DIM + 3;
                    row[a0..a0 + app.code_dim]
                        .copy_from_slice(&p.app[code * app.code_dim..(code + 1) * app.code_dim]);
                    if app.with_scalar {
                        row[a0 + app.code_dim] = pr;
                    }
                }
                i += 1;
            }
        }
        self.color_mlp
            .forward_hidden(p.color, &sc.cin, n, &mut sc.col_tape);
        sc.raw.resize(n * 3, T::ZERO);
        let hc = sc.col_tape.acts.last().expect("hidden layer");
        self.color_mlp.forward_last(p.color, hc, n, 3, &mut sc.raw);
        sc.rgb.resize(n, [T::ZERO; 3]);
        for i in 0..n {
            for k in 0..3 {
                sc.rgb[i][k] = sigmoid(sc.raw[3 * i + k]);
            }
        }
        times.color_fwd += t_col.elapsed().as_secs_f64();

        // ---- alpha, compositing, losses, compositing backward ----
        let t_r = Instant::now();
        sc.alpha.resize(n, T::ZERO);
        sc.agrad.resize(n, AlphaGrad::default());
        for i in 0..n {
            let nr = sc.normal[i];
            let dir = sc.dir[i];
            let cos = dir[0] * nr[0] + dir[1] * nr[1] + dir[2] * nr[2];
            let dt = T::from_f32(samples.dt[s0 + i]);
            let (a, ag) = neus_alpha::<T, TRAIN>(sc.out[i * fdim], cos, dt, inv_s, anneal);
            sc.alpha[i] = a;
            sc.agrad[i] = ag;
        }
        if !TRAIN {
            if let Some(out) = render_out {
                for r in r0..r1 {
                    let rg = samples.range(r);
                    let (a, b) = (rg.start - s0, rg.end - s0);
                    let c = composite_forward(
                        &sc.alpha[a..b],
                        &sc.rgb[a..b],
                        &sc.t[a..b],
                        &sc.normal[a..b],
                        bg,
                    );
                    out.push((
                        r,
                        c.rgb.map(|v| v.to_f32()),
                        c.opacity.to_f32(),
                        c.depth.to_f32(),
                        c.normal.map(|v| v.to_f32()),
                    ));
                }
            }
            times.render += t_r.elapsed().as_secs_f64();
            return;
        }
        let Some(g) = g else { return };
        let Some(targets) = ctx.targets else { return };
        let l = ctx.sched.loss;
        let n_rays = ctx.batch.origins.len().max(1) as f64;
        let nv = ctx.n_valid.max(1) as f64;
        let ns = samples.n_samples().max(1) as f64;
        sc.d_alpha.resize(n, T::ZERO);
        sc.d_rgb.resize(n, [T::ZERO; 3]);
        let in_mask = self.config.loss.color_in_mask && targets.mask.is_some();
        let bgt = if in_mask { [T::ZERO; 3] } else { bg };
        let cnorm = if in_mask {
            3.0 * ctx.mask_sum.max(1e-5)
        } else {
            3.0 * nv
        };
        for r in r0..r1 {
            let rg = samples.range(r);
            let (a, b) = (rg.start - s0, rg.end - s0);
            let c = composite_forward(
                &sc.alpha[a..b],
                &sc.rgb[a..b],
                &sc.t[a..b],
                &sc.normal[a..b],
                bgt,
            );
            let tgt = targets.rgb[r];
            let mw = match targets.mask {
                Some(m) if in_mask => m[r] as f64,
                _ => 1.0,
            };
            let valid = b > a;
            let mut g_rgb = [T::ZERO; 3];
            for k in 0..3 {
                let diff = c.rgb[k].to_f64() - tgt[k] as f64;
                sums.sq_all += diff * diff;
                if valid {
                    sums.l1 += mw * diff.abs();
                    sums.sq_valid += mw * diff * diff;
                    let sign = if diff > 0.0 {
                        1.0
                    } else if diff < 0.0 {
                        -1.0
                    } else {
                        0.0
                    };
                    g_rgb[k] = T::from_f64(
                        mw * (l.rgb_l1 as f64 * sign + l.rgb_mse as f64 * 2.0 * diff) / cnorm,
                    );
                }
            }
            let mut g_op = T::ZERO;
            if let Some(mask) = targets.mask {
                let m = mask[r] as f64;
                let o = c.opacity.to_f64();
                const E: f64 = 1e-3;
                // `oc` and `d oc / d o` (MaskBce docs).
                let (oc, doc) = match self.config.loss.mask_bce {
                    MaskBce::Clamp => (
                        o.clamp(E, 1.0 - E),
                        if (E..=1.0 - E).contains(&o) { 1.0 } else { 0.0 },
                    ),
                    MaskBce::Squash => (E + (1.0 - 2.0 * E) * o, 1.0 - 2.0 * E),
                };
                sums.mask += -(m * oc.ln() + (1.0 - m) * (1.0 - oc).ln());
                if doc != 0.0 {
                    g_op = T::from_f64(
                        l.mask as f64 * doc * (-m / oc + (1.0 - m) / (1.0 - oc)) / n_rays,
                    );
                }
            }
            composite_backward(
                &sc.alpha[a..b],
                &sc.rgb[a..b],
                &sc.t[a..b],
                bgt,
                g_rgb,
                g_op,
                T::ZERO,
                &mut sc.d_alpha[a..b],
                &mut sc.d_rgb[a..b],
            );
        }
        times.render += t_r.elapsed().as_secs_f64();

        // ---- colour network backward ----
        let t_cb = Instant::now();
        sc.d_raw.resize(n * 3, T::ZERO);
        for i in 0..n {
            for k in 0..3 {
                let y = sc.rgb[i][k];
                sc.d_raw[3 * i + k] = sc.d_rgb[i][k] * y * (T::ONE - y);
            }
        }
        let wc = self.color_mlp.last_hidden_dim();
        sc.d_hc.resize(n * wc, T::ZERO);
        sc.d_cin.resize(n * dc, T::ZERO);
        {
            let hc = sc.col_tape.acts.last().expect("hidden layer");
            self.color_mlp
                .backward_last(p.color, g.color, hc, n, 3, &sc.d_raw, &mut sc.d_hc);
        }
        self.color_mlp.backward_hidden(
            p.color,
            g.color,
            &sc.cin,
            n,
            &sc.col_tape,
            &mut sc.d_hc,
            &mut sc.tmp,
            Some(&mut sc.d_cin),
        );
        times.color_bwd += t_cb.elapsed().as_secs_f64();

        // ---- alpha/normal/eikonal backward to SDF outputs and taps ----
        let t_sb = Instant::now();
        sc.d_out.resize(n * fdim, T::ZERO);
        sc.d_tap.resize(6 * n, T::ZERO);
        let c_eik = T::from_f64(l.eikonal as f64 / ns);
        let inv_eps2 = T::ONE / (eps * eps);
        let c_curv = T::from_f64(l.curvature as f64 / ns) * inv_eps2;
        let mut d_inv_s = 0.0f64;
        let mut i = 0;
        for r in r0..r1 {
            let code = if app.n_codes > 0 {
                ctx.batch.codes.get(r).copied().unwrap_or(0) as usize
            } else {
                0
            };
            for _ in samples.range(r) {
                let da = sc.d_alpha[i];
                let ag = sc.agrad[i];
                d_inv_s += (da * ag.d_inv_s).to_f64();
                let dci = &sc.d_cin[i * dc..(i + 1) * dc];
                let dout = &mut sc.d_out[i * fdim..(i + 1) * fdim];
                dout.copy_from_slice(&dci[..fdim]);
                dout[0] += da * ag.d_sdf;
                let dcos = da * ag.d_cos;
                let dir = sc.dir[i];
                let mut dn = [T::ZERO; 3];
                for k in 0..3 {
                    dn[k] = dci[fdim + SH_DIM + k] + dcos * dir[k];
                }
                if app.n_codes > 0 {
                    let a0 = fdim + SH_DIM + 3;
                    let ga = &mut g.app[code * app.code_dim..(code + 1) * app.code_dim];
                    for (gv, &dv) in ga.iter_mut().zip(&dci[a0..a0 + app.code_dim]) {
                        *gv += dv;
                    }
                }
                let gr = sc.grad[i];
                let nr = sc.normal[i];
                let len = (gr[0] * gr[0] + gr[1] * gr[1] + gr[2] * gr[2]).sqrt();
                let mut dg = [T::ZERO; 3];
                let tiny = T::from_f64(1e-12);
                if len > tiny {
                    let ndn = nr[0] * dn[0] + nr[1] * dn[1] + nr[2] * dn[2];
                    let e = c_eik * T::from_f64(2.0) * (len - T::ONE);
                    for k in 0..3 {
                        dg[k] = (dn[k] - nr[k] * ndn) / len + e * nr[k];
                    }
                } else {
                    for k in 0..3 {
                        dg[k] = dn[k] / tiny;
                    }
                }
                for k in 0..3 {
                    let v = dg[k] * inv_2eps;
                    sc.d_tap[6 * i + 2 * k] = v;
                    sc.d_tap[6 * i + 2 * k + 1] = -v;
                }
                if l.curvature > 0.0 {
                    // Δf ≈ (Σ taps − 6 f(x)) / ε²; loss mean |Δf| (LossConfig::curvature).
                    let tp = &sc.tap[6 * i..6 * i + 6];
                    let lap = (tp.iter().fold(T::ZERO, |a, &v| a + v)
                        - T::from_f64(6.0) * sc.out[i * fdim])
                        * inv_eps2;
                    sums.curv += lap.to_f64().abs();
                    let sgn = if lap > T::ZERO {
                        c_curv
                    } else if lap < T::ZERO {
                        -c_curv
                    } else {
                        T::ZERO
                    };
                    for v in &mut sc.d_tap[6 * i..6 * i + 6] {
                        *v += sgn;
                    }
                    dout[0] -= T::from_f64(6.0) * sgn;
                }
                let e = len - T::ONE;
                sums.eik += (e * e).to_f64();
                i += 1;
            }
        }
        sums.d_inv_s += d_inv_s;
        sc.d_h.resize(7 * n * wh, T::ZERO);
        {
            let h = sc.sdf_tape.acts.last().expect("hidden layer");
            let (dh_c, dh_t) = sc.d_h.split_at_mut(n * wh);
            self.sdf_mlp
                .backward_last(p.sdf, g.sdf, &h[..n * wh], n, fdim, &sc.d_out, dh_c);
            self.sdf_mlp
                .backward_last(p.sdf, g.sdf, &h[n * wh..], 6 * n, 1, &sc.d_tap, dh_t);
        }
        sc.d_enc.resize(7 * n * d, T::ZERO);
        // Only the hash-grid columns of the input gradient: the xyz prefix has no parameters.
        let grid_cols = self.grid.xyz_dim()..d;
        self.sdf_mlp.backward_hidden_cols(
            p.sdf,
            g.sdf,
            &sc.enc,
            7 * n,
            &sc.sdf_tape,
            &mut sc.d_h,
            &mut sc.tmp,
            Some((&mut sc.d_enc, grid_cols)),
        );
        times.sdf_mlp_bwd += t_sb.elapsed().as_secs_f64();

        // ---- hash grid backward ----
        let t_eb = Instant::now();
        self.grid.encode_fd_backward_batch(
            &sc.xs,
            &sc.taps,
            radius,
            active,
            &sc.d_enc,
            |i| tap_rows(i, n, d),
            g.hash,
        );
        times.encode_bwd += t_eb.elapsed().as_secs_f64();
    }
}

/// Rows of sample `i`'s centre (row `i`) and taps (rows `n + 6i + k`) in the `[7n][d]` buffers.
#[inline]
fn tap_rows(i: usize, n: usize, d: usize) -> [usize; 7] {
    let b = n + 6 * i;
    [
        i * d,
        b * d,
        (b + 1) * d,
        (b + 2) * d,
        (b + 3) * d,
        (b + 4) * d,
        (b + 5) * d,
    ]
}

/// Names of the parameter groups, in the order [`NeusModel::new`] lays them out.
const HASH_GRID: &str = "hash_grid";
const SDF_MLP: &str = "sdf_mlp";
const COLOR_MLP: &str = "color_mlp";
const VARIANCE: &str = "variance";
const APPEARANCE: &str = "appearance";

/// The flat index range of the group `name` (every model layout has all five groups).
fn group(layout: &ParamLayout, name: &str) -> std::ops::Range<usize> {
    layout
        .group(name)
        .unwrap_or_else(|| panic!("parameter group '{name}' missing from the layout"))
        .range()
}

fn split<'a, T>(layout: &ParamLayout, p: &'a [T]) -> Groups<'a, T> {
    Groups {
        hash: &p[group(layout, HASH_GRID)],
        sdf: &p[group(layout, SDF_MLP)],
        color: &p[group(layout, COLOR_MLP)],
        var: &p[group(layout, VARIANCE)],
        app: &p[group(layout, APPEARANCE)],
    }
}

fn split_mut<'a, T>(layout: &ParamLayout, p: &'a mut [T]) -> GroupsMut<'a, T> {
    // The groups are contiguous in layout order: cut the buffer at each group's end.
    let len = |name| group(layout, name).len();
    debug_assert_eq!(group(layout, SDF_MLP).start, len(HASH_GRID));
    let (hash, rest) = p.split_at_mut(len(HASH_GRID));
    let (sdf, rest) = rest.split_at_mut(len(SDF_MLP));
    let (color, rest) = rest.split_at_mut(len(COLOR_MLP));
    let (var, rest) = rest.split_at_mut(len(VARIANCE));
    let (app, _) = rest.split_at_mut(len(APPEARANCE));
    GroupsMut {
        hash,
        sdf,
        color,
        var,
        app,
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
    fn config_round_trips_through_toml_and_rejects_unknown_keys() {
        let c = ModelConfig::default();
        let text = toml::to_string(&c).unwrap();
        let back: ModelConfig = toml::from_str(&text).unwrap();
        assert_eq!(back, c);
        let partial: ModelConfig = toml::from_str("[field.hash_grid]\nn_levels = 8\n").unwrap();
        assert_eq!(partial.field.hash_grid.n_levels, 8);
        assert_eq!(partial.render, RenderConfig::default());
        let err = toml::from_str::<ModelConfig>("[render]\nradiuss = 2.0\n").unwrap_err();
        assert!(err.to_string().contains("radiuss"), "{err}");
    }

    #[test]
    fn layout_and_defaults() {
        let m = NeusModel::new(ModelConfig::default()).unwrap();
        let names: Vec<&str> = m.layout.groups.iter().map(|g| g.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "hash_grid",
                "sdf_mlp",
                "color_mlp",
                "variance",
                "appearance"
            ]
        );
        assert_eq!(m.sdf_mlp.dims, [35, 64, 13]);
        assert_eq!(m.color_mlp.dims, [13 + 16 + 3, 64, 64, 3]);
        let p = m.init_params(1);
        assert_eq!(p, m.init_params(1), "seeded");
        assert!((m.inv_s(&p) - 3f32.exp()).abs() < 1e-4);
        assert_eq!(m.layout.group("variance").unwrap().lr_scale, 0.1);
        let mut c = ModelConfig::default();
        c.field.appearance = crate::field::config::AppearanceConfig {
            n_codes: 6,
            code_dim: 4,
            with_scalar: true,
        };
        let m = NeusModel::new(c).unwrap();
        assert_eq!(m.color_mlp.dims[0], 13 + 16 + 3 + 4 + 1);
        let g = m.layout.group("appearance").unwrap();
        assert_eq!(g.shape, [6, 4]);
        assert!(
            m.init_params(2)[g.range()].iter().all(|&v| v == 0.0),
            "appearance starts at zero"
        );
        let mut bad = ModelConfig::default();
        bad.field.appearance.with_scalar = true;
        assert!(NeusModel::new(bad)
            .unwrap_err()
            .to_string()
            .contains("with_scalar"));
    }

    /// `sdf` (batched level-parallel encoding, register-kernel MLP, fused output channel)
    /// against a slow f64 reference (naive encoding, naive layers, standard-library softplus)
    /// on the default network with perturbed weights, inside and on the box.
    #[test]
    fn sdf_matches_slow_reference() {
        use crate::field::fastmath::softplus_f64;
        use crate::field::mlp::linear_forward_naive;
        use rand::Rng;
        let model = NeusModel::new(ModelConfig::default()).unwrap();
        let mut p = model.init_params(3);
        let mut rng = Pcg64Mcg::seed_from_u64(4);
        for i in model.layout.group("hash_grid").unwrap().range() {
            p[i] = rng.random_range(-0.05..0.05);
        }
        for i in model.layout.group("sdf_mlp").unwrap().range() {
            p[i] += rng.random_range(-0.05..0.05);
        }
        let mut pts: Vec<[f32; 3]> = (0..300)
            .map(|_| [0, 1, 2].map(|_| rng.random_range(-1.0..1.0)))
            .collect();
        pts.push([1.0, -1.0, 1.0]);
        let active = 13;
        let got = model.sdf(&p, &pts, active);
        let p64: Vec<f64> = p.iter().map(|&v| v as f64).collect();
        let hash = &p64[model.layout.group("hash_grid").unwrap().range()];
        let sdf = &p64[model.layout.group("sdf_mlp").unwrap().range()];
        let dims = &model.sdf_mlp.dims;
        let (d0, d1) = (dims[0], dims[1]);
        let mut worst = 0.0f64;
        for (x, g) in pts.iter().zip(&got) {
            let enc = model
                .grid
                .encode_naive(hash, x.map(|v| v as f64), 1.0, active);
            let mut h = vec![0.0; d1];
            linear_forward_naive(&sdf[..d0 * d1], &sdf[d0 * d1..], &enc, 1, d0, d1, &mut h);
            for v in h.iter_mut() {
                *v = softplus_f64(*v, 100.0).0;
            }
            let o = d1 * (d0 + 1);
            let mut y = [0.0];
            linear_forward_naive(&sdf[o..], &sdf[o + dims[2] * d1..], &h, 1, d1, 1, &mut y);
            worst = worst.max((*g as f64 - y[0]).abs() / (1.0 + y[0].abs()));
        }
        assert!(worst < 1e-5, "sdf vs slow reference: {worst}");
    }

    #[test]
    fn dynamic_ray_count() {
        // Twice the budget used: move 10% of the way to half the rays.
        assert_eq!(next_num_rays(1000, 2000, 1000, 8192), 950);
        assert_eq!(next_num_rays(8000, 1, 1 << 20, 8192), 8192);
    }
}
