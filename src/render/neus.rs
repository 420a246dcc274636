//! The NeuS model's shapes: its configuration resolved into the hash grid, the two MLPs and the
//! flat parameter layout ([`NeusModel`]), the ray batch it takes ([`RayBatch`]) and what it
//! returns, and why it refuses a batch ([`ModelError`]). The forward/backward and inference
//! entry points are in `model.rs`, the per-chunk phases in `step.rs`.

use super::alpha::inv_s_from_variance;
use super::background::BackgroundField;
use super::config::ModelConfig;
pub use super::error::ModelError;
use super::occupancy::OccupancyGrid;
use super::ray_loss::BatchCounts;
use super::workspace::{
    group, split_mut, WorkspaceCache, APPEARANCE, BG_COLOR, BG_DENSITY, COLOR_MLP, HASH_GRID,
    SDF_MLP, VARIANCE,
};
use crate::field::{Activation, HashGrid, Mlp, ParamLayout};
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;

/// One rendered ray: index, colour, opacity, depth, normal.
pub(super) type RayResult = (usize, [f32; 3], f32, f32, [f32; 3]);

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

/// `[n]` per-ray gradient cells of [`NeusModel::forward_backward_rays`]: `∂L/∂o` (3) then
/// `∂L/∂d` (3), f64 bits, each written once by the chunk that holds the ray (normalised space).
/// A cell whose first slot holds [`RAY_GRAD_SKIP`] when the step starts is not computed: its
/// ray's gradient is written as zero (a caller that needs only some rays' gradients).
pub type RayGradCell = [std::sync::atomic::AtomicU64; 6];

/// The mark of a [`RayGradCell`] whose gradient is not wanted: a NaN payload no gradient takes.
pub const RAY_GRAD_SKIP: u64 = 0x7ff8_dead_beef_0001;

/// Marks `cell` as wanted (zero) or not ([`RAY_GRAD_SKIP`]) before a step.
pub fn mark_ray_grad(cell: &RayGradCell, wanted: bool) {
    let first = if wanted { 0 } else { RAY_GRAD_SKIP };
    cell[0].store(first, std::sync::atomic::Ordering::Relaxed);
}

/// The gradient a [`RayGradCell`] holds: `(∂L/∂o, ∂L/∂d)`.
pub fn ray_grad(cell: &RayGradCell) -> ([f64; 3], [f64; 3]) {
    let v = |k: usize| f64::from_bits(cell[k].load(std::sync::atomic::Ordering::Relaxed));
    ([v(0), v(1), v(2)], [v(3), v(4), v(5)])
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
    /// The learned background's networks, forward and backward (0 without one).
    pub background: f64,
}

impl PhaseTimes {
    pub(super) fn add(&mut self, o: &PhaseTimes) {
        self.sample += o.sample;
        self.encode_fwd += o.encode_fwd;
        self.sdf_mlp_fwd += o.sdf_mlp_fwd;
        self.color_fwd += o.color_fwd;
        self.render += o.render;
        self.color_bwd += o.color_bwd;
        self.sdf_mlp_bwd += o.sdf_mlp_bwd;
        self.encode_bwd += o.encode_bwd;
        self.reduce += o.reduce;
        self.background += o.background;
    }
}

/// What [`NeusModel::forward_backward`] returns besides the gradients.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BackwardOutput<S> {
    /// The loss's per-ray sums ([`RayLoss::Sums`]), merged over shards in shard order.
    pub loss: S,
    /// `Σ (|∇f| − 1)²` over all samples.
    pub eikonal_sum: f64,
    /// `Σ |Δf|` over all samples (0 when the loss's curvature weight is 0).
    pub curvature_sum: f64,
    pub counts: BatchCounts,
    pub inv_s: f64,
    pub times: PhaseTimes,
}

/// Rendered rays (no gradients).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RenderOutput {
    /// `[n][3]` colour including the background (the learned one when it is on).
    pub rgb: Vec<[f32; 3]>,
    /// `[n]` accumulated weight of the foreground (the learned background's is not included).
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
    /// Groups in this order: `hash_grid`, `sdf_mlp`, `color_mlp`, `variance`, `appearance`,
    /// and with a learned background `bg_density`, `bg_color`.
    pub layout: ParamLayout,
    /// The learned background's networks (`None` when `config.background` is off).
    pub background: Option<BackgroundField>,
    /// Buffers [`NeusModel::forward_backward`] reuses between calls (see [`WorkspaceCache`]).
    pub(super) workspace: WorkspaceCache,
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
        if !(1..=64).contains(&r.fd_central_every) {
            return Err(ModelError::Invalid {
                key: "render.fd_central_every",
                value: r.fd_central_every.to_string(),
                why: "must be in 1..=64",
            });
        }
        if !(r.fd_one_sided_span.is_finite() && (0.25..=2.0).contains(&r.fd_one_sided_span)) {
            return Err(ModelError::Invalid {
                key: "render.fd_one_sided_span",
                value: r.fd_one_sided_span.to_string(),
                why: "must be in [0.25, 2] (the level-parallel stencil takes taps up to two cells out)",
            });
        }
        if r.occupancy.resolution == 0 || r.occupancy.resolution > 1024 {
            return Err(ModelError::Invalid {
                key: "render.occupancy.resolution",
                value: r.occupancy.resolution.to_string(),
                why: "must be in 1..=1024",
            });
        }
        if let Some((key, v, why)) = config
            .background
            .enabled()
            .then(|| BackgroundField::validate(&config.background))
            .flatten()
        {
            return Err(ModelError::Invalid {
                key,
                value: v.to_string(),
                why,
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
        let background = config
            .background
            .enabled()
            .then(|| BackgroundField::new(&config.background));
        if let Some(bg) = &background {
            layout.push(BG_DENSITY, vec![bg.density.n_params()], 1.0);
            layout.push(BG_COLOR, vec![bg.color.n_params()], 1.0);
        }
        Ok(Self {
            config,
            grid,
            sdf_mlp,
            color_mlp,
            layout,
            background,
            workspace: WorkspaceCache::default(),
        })
    }

    /// Number of parameters.
    pub fn n_params(&self) -> usize {
        self.layout.total()
    }

    /// Seeded initial parameters: hash table `U(±1e-4)`, SDF MLP sphere init (or Kaiming),
    /// colour MLP Kaiming-uniform with zero biases, `v = variance_init`, appearance table zeros,
    /// background networks (when on) Kaiming-uniform with zero biases. The optional groups are
    /// drawn last, so the rest starts the same with or without them.
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
        if let Some(bg) = &self.background {
            bg.density.init_kaiming(g.bg_density, &mut rng);
            bg.color.init_kaiming(g.bg_color, &mut rng);
        }
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

    pub(super) fn n_shards(&self) -> usize {
        match self.config.render.shards {
            0 => rayon::current_num_threads().max(1),
            s => s,
        }
    }

    pub(super) fn check_params<T>(&self, params: &[T]) -> Result<(), ModelError> {
        if params.len() != self.n_params() {
            return Err(ModelError::ParamLen {
                expected: self.n_params(),
                got: params.len(),
            });
        }
        Ok(())
    }

    pub(super) fn check_batch(&self, b: &RayBatch) -> Result<(), ModelError> {
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
}
