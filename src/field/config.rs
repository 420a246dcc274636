//! Configuration of the field (hash grid, SDF MLP, colour MLP, appearance input).
//!
//! Defaults follow instant-nsr-pl `configs/neus-dtu-wmask.yaml` (the hash grid with tcnn's
//! semantics); every size is configurable because presets shrink them for CPU speed. All structs
//! deserialise from TOML with unknown keys rejected and missing keys defaulted.

use serde::{Deserialize, Serialize};

/// Errors from validating a [`FieldConfig`]; each names the key and the value at fault.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ConfigError {
    #[error("field config: `{key}` = {value} is invalid: {why}")]
    Invalid {
        /// The key under the field config, e.g. `hash_grid.n_levels`.
        key: String,
        value: String,
        why: &'static str,
    },
}

fn invalid(key: impl Into<String>, value: impl ToString, why: &'static str) -> ConfigError {
    ConfigError::Invalid {
        key: key.into(),
        value: value.to_string(),
        why,
    }
}

/// Multiresolution hash grid with tiny-cuda-nn semantics (Müller et al. 2022, tcnn
/// `include/tiny-cuda-nn/encodings/grid.h`): level `l` has `scale_l = base·b^l − 1`, resolution
/// `ceil(scale_l) + 1`, and looks up `pos = scale_l·x + 0.5` for `x ∈ [0,1]³`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HashGridConfig {
    /// Number of levels `L` (16).
    pub n_levels: usize,
    /// Features per level `F` (2).
    pub n_features_per_level: usize,
    /// `log2` of the entries per hashed level `T` (19).
    pub log2_hashmap_size: u32,
    /// Resolution of the coarsest level (32).
    pub base_resolution: f64,
    /// Growth factor between levels `b` (64^(1/15) ≈ 1.3195, finest level 2048).
    pub per_level_scale: f64,
    /// Table entries are initialised uniform in `±init_range` (tcnn: 1e-4).
    pub init_range: f32,
    /// Concatenate the raw position (mapped to `[-1,1]`) before the grid features
    /// (instant-nsr-pl `include_xyz: true`, `CompositeEncoding` puts xyz first).
    pub include_xyz: bool,
    /// Progressive (coarse-to-fine) levels: levels start at `start_level` active and one more is
    /// added every `update_steps` after `start_step` (instant-nsr-pl `ProgressiveBandHashGrid`).
    /// `None` (the neus-dtu-wmask default) keeps every level active.
    pub progressive: Option<ProgressiveConfig>,
}

/// Coarse-to-fine schedule of active hash-grid levels (see [`HashGridConfig::progressive`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProgressiveConfig {
    pub start_level: usize,
    pub start_step: u64,
    pub update_steps: u64,
}

impl Default for ProgressiveConfig {
    fn default() -> Self {
        // instant-nsr-pl `configs/neus-dtu.yaml` with ProgressiveBandHashGrid.
        Self {
            start_level: 4,
            start_step: 0,
            update_steps: 1000,
        }
    }
}

impl Default for HashGridConfig {
    fn default() -> Self {
        Self {
            n_levels: 16,
            n_features_per_level: 2,
            log2_hashmap_size: 19,
            base_resolution: 32.0,
            per_level_scale: 1.3195079107728942,
            init_range: 1e-4,
            include_xyz: true,
            progressive: None,
        }
    }
}

impl HashGridConfig {
    /// Checks sizes; errors name the key as `prefix.<field>` (the config path of this grid).
    pub fn validate(&self, prefix: &str) -> Result<(), ConfigError> {
        let h = self;
        let k = |name: &str| format!("{prefix}.{name}");
        if h.n_levels == 0 || h.n_levels > 32 {
            return Err(invalid(k("n_levels"), h.n_levels, "must be in 1..=32"));
        }
        if h.n_features_per_level == 0 || h.n_features_per_level > 8 {
            return Err(invalid(
                k("n_features_per_level"),
                h.n_features_per_level,
                "must be in 1..=8",
            ));
        }
        if !(4..=26).contains(&h.log2_hashmap_size) {
            return Err(invalid(
                k("log2_hashmap_size"),
                h.log2_hashmap_size,
                "must be in 4..=26",
            ));
        }
        if !(h.base_resolution >= 2.0 && h.base_resolution.is_finite()) {
            return Err(invalid(
                k("base_resolution"),
                h.base_resolution,
                "must be finite and >= 2",
            ));
        }
        if !(h.per_level_scale >= 1.0 && h.per_level_scale.is_finite()) {
            return Err(invalid(
                k("per_level_scale"),
                h.per_level_scale,
                "must be finite and >= 1",
            ));
        }
        let finest = h.base_resolution * h.per_level_scale.powi(h.n_levels as i32 - 1);
        if finest > 1.0e6 {
            return Err(invalid(
                k("per_level_scale"),
                h.per_level_scale,
                "finest resolution above 1e6",
            ));
        }
        if !(h.init_range >= 0.0 && h.init_range.is_finite()) {
            return Err(invalid(k("init_range"), h.init_range, "must be >= 0"));
        }
        if let Some(p) = &h.progressive {
            if p.start_level == 0 || p.start_level > h.n_levels {
                return Err(invalid(
                    k("progressive.start_level"),
                    p.start_level,
                    "must be in 1..=n_levels",
                ));
            }
            if p.update_steps == 0 {
                return Err(invalid(k("progressive.update_steps"), 0, "must be > 0"));
            }
        }
        Ok(())
    }

    /// Number of active levels at training step `step` (all levels without a progressive
    /// schedule). Pass the result explicitly to the model; nothing keeps schedule state.
    pub fn active_levels(&self, step: u64) -> usize {
        match &self.progressive {
            None => self.n_levels,
            Some(p) => {
                let extra = step.saturating_sub(p.start_step) / p.update_steps.max(1);
                (p.start_level as u64 + extra).min(self.n_levels as u64) as usize
            }
        }
    }
}

/// SDF network: `in → n_neurons (Softplus β) × n_hidden_layers → feature_dim`, output channel 0 is
/// the SDF (normalised units), all `feature_dim` channels feed the colour network.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SdfMlpConfig {
    /// Hidden width (64).
    pub n_neurons: usize,
    /// Hidden layers (1): `35 → 64 → 13` by default.
    pub n_hidden_layers: usize,
    /// Output channels including the SDF channel (13).
    pub feature_dim: usize,
    /// Softplus sharpness β (100). instant-nsr-pl replaces the YAML's ReLU by Softplus(β=100)
    /// whenever sphere init is on (`models/network_utils.py`, `make_activation`).
    pub softplus_beta: f32,
    /// Geometric initialisation to a sphere (Atzmon & Lipman 2020; `sphere_init`).
    pub sphere_init: bool,
    /// Radius of the initial sphere in normalised units (0.5).
    pub sphere_init_radius: f32,
}

impl Default for SdfMlpConfig {
    fn default() -> Self {
        Self {
            n_neurons: 64,
            n_hidden_layers: 1,
            feature_dim: 13,
            softplus_beta: 100.0,
            sphere_init: true,
            sphere_init_radius: 0.5,
        }
    }
}

/// Colour network: `[feature_dim, SH(dir) 16, normal 3, code code_dim, p?] → 64 → 64 → 3`, ReLU,
/// sigmoid output (instant-nsr-pl `models/texture.py`, `VolumeRadiance`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ColorMlpConfig {
    /// Hidden width (64).
    pub n_neurons: usize,
    /// Hidden layers (2).
    pub n_hidden_layers: usize,
}

impl Default for ColorMlpConfig {
    fn default() -> Self {
        Self {
            n_neurons: 64,
            n_hidden_layers: 2,
        }
    }
}

/// Appearance input of the colour network (the augmentation issue fills it): a learnable table of
/// `n_codes × code_dim`, **initialised to zeros**, indexed per ray by `code`, plus, when
/// `with_scalar`, the per-ray augmentation intensity `p` as one more input. `n_codes = 0` means no
/// appearance input at all (the baseline); then `with_scalar` must be false.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AppearanceConfig {
    pub n_codes: usize,
    pub code_dim: usize,
    pub with_scalar: bool,
}

impl Default for AppearanceConfig {
    fn default() -> Self {
        Self {
            n_codes: 0,
            code_dim: 8,
            with_scalar: false,
        }
    }
}

/// Everything that shapes the field's parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct FieldConfig {
    pub hash_grid: HashGridConfig,
    pub sdf: SdfMlpConfig,
    pub color: ColorMlpConfig,
    pub appearance: AppearanceConfig,
}

impl FieldConfig {
    /// Checks sizes; the error names the key and value.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.hash_grid.validate("hash_grid")?;
        if self.sdf.n_neurons == 0 || self.sdf.n_hidden_layers == 0 {
            return Err(invalid(
                "sdf.n_neurons/n_hidden_layers",
                format!("{}/{}", self.sdf.n_neurons, self.sdf.n_hidden_layers),
                "must be > 0",
            ));
        }
        if self.sdf.feature_dim == 0 {
            return Err(invalid(
                "sdf.feature_dim",
                0,
                "must be >= 1 (channel 0 is the SDF)",
            ));
        }
        if !(self.sdf.softplus_beta > 0.0 && self.sdf.softplus_beta.is_finite()) {
            return Err(invalid(
                "sdf.softplus_beta",
                self.sdf.softplus_beta,
                "must be > 0",
            ));
        }
        if self.color.n_neurons == 0 || self.color.n_hidden_layers == 0 {
            return Err(invalid(
                "color.n_neurons/n_hidden_layers",
                format!("{}/{}", self.color.n_neurons, self.color.n_hidden_layers),
                "must be > 0",
            ));
        }
        let a = &self.appearance;
        if a.n_codes > 0 && a.code_dim == 0 {
            return Err(invalid(
                "appearance.code_dim",
                0,
                "must be > 0 when n_codes > 0",
            ));
        }
        if a.n_codes == 0 && a.with_scalar {
            return Err(invalid(
                "appearance.with_scalar",
                true,
                "needs n_codes > 0 (no appearance input in the baseline)",
            ));
        }
        Ok(())
    }

    /// Width of the appearance part of the colour input (`code_dim` + 1 if `with_scalar`, 0 when
    /// `n_codes = 0`).
    pub fn appearance_dim(&self) -> usize {
        let a = &self.appearance;
        if a.n_codes == 0 {
            0
        } else {
            a.code_dim + usize::from(a.with_scalar)
        }
    }

    /// Width of the colour-MLP input: `feature_dim + 16 + 3 + appearance_dim` (in that
    /// order).
    pub fn color_input_dim(&self) -> usize {
        self.sdf.feature_dim + crate::field::sh::SH_DIM + 3 + self.appearance_dim()
    }
}
