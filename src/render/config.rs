//! The model's configuration, `[model]` in the TOML config: the field's shapes
//! ([`FieldConfig`]), rendering and sampling ([`RenderConfig`]) and the loss settings
//! ([`LossConfig`]). Plain data with serde defaults; the values at a training step are resolved in
//! [`super::schedule`], and the losses themselves are computed in `train::loss`.
//!
//! `LossConfig` is declared here, not in `train`, because it is a field of [`ModelConfig`], which
//! the model ([`super::NeusModel::config`]) holds: moving it up would make `render` import
//! `train`. Only the settings live here; every loss value and gradient is computed in `train`.

use super::occupancy::OccupancyConfig;
use super::scheduled::Scheduled;
use crate::field::FieldConfig;
use serde::{Deserialize, Serialize};

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
    /// Scale of the view-direction terms (spherical-harmonic degrees 1–3) in the colour network's
    /// input, as a [`Scheduled`] value (1: the reference's full view dependence). Below 1 early in
    /// training, the colour network cannot give one surface point a different colour per view, so a
    /// wrong surface (a lid over a concavity, a membrane across a hole) that shows what lies behind
    /// it no longer fits every view and photometric consistency moves it; the ramp to 1 lets real
    /// view-dependent effects (highlights) back in later. The degree-0 term is constant and kept.
    /// This project's own choice, not a reference's; in spirit the coarse-to-fine annealing of a
    /// positional encoding's bands (BARF, Lin et al. 2021; Nerfies, Park et al. 2021), applied to
    /// the direction encoding. Queries after training use the value at the last step.
    pub view_dependence: Scheduled,
    /// Which training samples take central finite differences of the SDF (six taps, `x ± ε·e_a`)
    /// and which one-sided ones (three taps, `x + ε·e_a` or `x − ε·e_a`, the centre's own value
    /// standing for the other side). 1 (the default): every sample central, as Neuralangelo
    /// (`projects/neuralangelo/utils/modules.py`, the `numerical` gradient) and instant-nsr-pl
    /// (`models/geometry.py`, `grad_type: finite_difference`) do. `k > 1` (opt-in): one-sided, `+`
    /// and `−` in turn (so their first-order errors, `±ε/2·∂²f/∂x_a²`, cancel on average), except
    /// that while the curvature loss is on every `k`-th sample of a batch takes central differences
    /// and carries the curvature term (its Laplacian needs both sides), weighted `k` so the loss
    /// stays an unbiased estimate of the mean over all samples. A one-sided difference costs about
    /// 0.6 of a central one in the hash grid and the SDF network: the training step runs 1.3×
    /// faster on one-sided samples (`cargo bench --bench field`), at an accuracy cost over `ε` and
    /// none measured over `2ε` (`fd_one_sided_span = 2`; `docs/recipe.md`). This project's choice,
    /// not a reference's. Renders and meshes after training always use central differences.
    pub fd_central_every: u32,
    /// Span of a one-sided difference in units of `ε` (default 1): its taps sit at
    /// `x ± span·ε·e_a` and it divides by `span·ε`. At 2 a one-sided difference averages the
    /// gradient over the same `2ε` as a central one (the smoothing of Neuralangelo's numerical
    /// gradient, `projects/neuralangelo/utils/modules.py`), at twice its first-order error
    /// (which the alternation of sides cancels on average). Only read when
    /// `fd_central_every > 1`. This project's choice.
    pub fd_one_sided_span: f32,
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
            view_dependence: Scheduled::Constant(1.0),
            fd_central_every: 1,
            fd_one_sided_span: 1.0,
        }
    }
}

/// Loss weights (instant-nsr-pl `systems/neus.py` `training_step` and the YAML's `system.loss`):
/// `lambda_rgb_l1: 1`, `lambda_rgb_mse: 0`, `lambda_eikonal: 0.1`. The mask BCE weight is 0.1 as in
/// Totoro97/NeuS `confs/wmask.conf` (`mask_weight`) and instant-nsr-pl `neus-blender.yaml` /
/// `neuralangelo-dtu-wmask.yaml` (`neus-dtu-wmask.yaml` itself sets 0.0 and only masks the target
/// colours).
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
    /// How the mask BCE keeps `log` finite.
    pub mask_bce: MaskBce,
    /// NeuS-style colour loss (`exp_runner.py`): the colour error only inside the mask,
    /// normalised by `3·Σ mask`, and no background colour composited. `false`: instant-nsr-pl
    /// style, every ray's target composited on `render.background` where the mask is 0.
    pub color_in_mask: bool,
}

/// How the mask BCE of the opacity `o ∈ [0, 1]` keeps its logarithms finite.
///
/// NeuS (`exp_runner.py`) and instant-nsr-pl (`systems/neus.py`) clip `o` to `[1e-3, 1 − 1e-3]`
/// before `binary_cross_entropy`; the clip passes no gradient outside that range, so a surface that
/// became fully opaque where the mask says background (the membrane across a hole) gets no gradient
/// from the mask at all, and the colour network paints it with the background. The squash keeps
/// that gradient, and opened such membranes where the clip did not (measured: docs/recipe.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MaskBce {
    /// `o' = clamp(o, 1e-3, 1 − 1e-3)`: the references' form, no gradient when saturated.
    Clamp,
    /// `o' = 1e-3 + (1 − 2·1e-3)·o`: an affine squash into the same range, differentiable
    /// everywhere, gradient up to ~1000× the weight at saturation (the default).
    Squash,
}

impl LossConfig {
    /// Every scheduled loss weight with its key under `model.loss`, in declaration order: the
    /// one list that validation and the step-scaling of `study pareto` walk.
    pub fn weights(&self) -> [(&'static str, Scheduled); 5] {
        [
            ("rgb_l1", self.rgb_l1),
            ("rgb_mse", self.rgb_mse),
            ("eikonal", self.eikonal),
            ("mask", self.mask),
            ("curvature", self.curvature),
        ]
    }

    /// [`LossConfig::weights`], mutable (same keys, same order).
    pub fn weights_mut(&mut self) -> [(&'static str, &mut Scheduled); 5] {
        [
            ("rgb_l1", &mut self.rgb_l1),
            ("rgb_mse", &mut self.rgb_mse),
            ("eikonal", &mut self.eikonal),
            ("mask", &mut self.mask),
            ("curvature", &mut self.curvature),
        ]
    }
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

/// Which background model composites behind the foreground (`[model.background] kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BackgroundKind {
    /// The constant `render.background` colour (the default; what every run used before).
    #[default]
    None,
    /// A learned radiance field outside the marched box on NeRF++'s inverted-sphere coordinates
    /// (NeuS `models/renderer.py` `render_core_outside`; see [`super::background`]).
    Nerfpp,
}

/// The learned background (`[model.background]`), for training without masks: NeuS
/// `confs/womask.conf` (`n_outside = 32`, a NeRF with 8 layers of 256), instant-nsr-pl
/// `configs/neus-dtu.yaml` (`learned_background: true`, a hash grid → 64 → 1 + 8 density network
/// and an 8 + SH(4) → 64 → 64 → 3 colour network). Here a frequency encoding replaces both
/// references' heavier position encodings, to stay cheap on a CPU; the sizes are this
/// project's choice. Off by default: with `kind = "none"` nothing else here is read, the
/// parameter layout has no background group, and the section is not even written into a
/// resolved config, so every existing config, preset and checkpoint is unchanged.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BackgroundConfig {
    /// `"none"` (constant colour) or `"nerfpp"` (learned field outside the box).
    pub kind: BackgroundKind,
    /// Samples per ray beyond the box exit, spaced uniformly in inverse distance (NeuS
    /// `n_outside = 32`).
    pub n_outside: usize,
    /// Frequencies `L` of the encoding `[q, sin(2^l q), cos(2^l q)]_{l<L}` of the 4-vector
    /// inverted-sphere point `q` (input width `4(1 + 2L)`; NeuS's NeRF uses 10).
    pub n_frequencies: usize,
    /// Width of the hidden layers of both background networks (64).
    pub n_neurons: usize,
    /// Hidden layers of the density network (2).
    pub n_hidden_layers: usize,
    /// Hidden layers of the colour network (1).
    pub color_hidden_layers: usize,
    /// Feature channels passed from the density network to the colour network (15: with the
    /// density channel, 16 outputs, a width the register kernels specialise).
    pub feature_dim: usize,
}

impl Default for BackgroundConfig {
    fn default() -> Self {
        Self {
            kind: BackgroundKind::None,
            n_outside: 32,
            n_frequencies: 6,
            n_neurons: 64,
            n_hidden_layers: 2,
            color_hidden_layers: 1,
            feature_dim: 15,
        }
    }
}

impl BackgroundConfig {
    /// Whether a learned background is on.
    pub fn enabled(&self) -> bool {
        self.kind != BackgroundKind::None
    }
}

/// Everything that defines a model (sits in the TOML config as `[model]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct ModelConfig {
    pub field: FieldConfig,
    pub render: RenderConfig,
    pub loss: LossConfig,
    /// The learned background (off by default).
    pub background: BackgroundConfig,
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
        // Every key is written, at its default too: the background section and the tap layout.
        assert!(text.contains("[background]"), "{text}");
        assert!(text.contains("fd_central_every = 1"), "{text}");
        assert!(text.contains("fd_one_sided_span = 1"), "{text}");
        let mut k = c.clone();
        k.render.fd_central_every = 4;
        k.render.fd_one_sided_span = 2.0;
        let text = toml::to_string(&k).unwrap();
        assert!(text.contains("fd_central_every = 4"), "{text}");
        assert!(text.contains("fd_one_sided_span = 2"), "{text}");
        assert_eq!(toml::from_str::<ModelConfig>(&text).unwrap(), k);
        let bg: ModelConfig =
            toml::from_str("[background]\nkind = \"nerfpp\"\nn_outside = 8\n").unwrap();
        assert!(bg.background.enabled());
        assert_eq!(bg.background.n_outside, 8);
        let text = toml::to_string(&bg).unwrap();
        assert_eq!(toml::from_str::<ModelConfig>(&text).unwrap(), bg);
        let err = toml::from_str::<ModelConfig>("[background]\nkind = \"nerf\"\n").unwrap_err();
        assert!(err.to_string().contains("nerf"), "{err}");
    }
}
