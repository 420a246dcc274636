//! The resolved configuration of a `reconstruct` run.
//!
//! One struct ([`RunConfig`]) holds every option; the TOML file and the command line are two ways
//! to set its fields. Resolution order: the preset's defaults → `--config FILE` → command-line
//! flags → `--set key=value` (TOML syntax, dotted keys). Unknown keys are errors naming the key;
//! the resolved configuration is written to the run folder as `config.toml`.
//!
//! Here: the option structs, their range checks ([`RunConfig::validate`]) and the training hash.
//! The presets' values live in `preset.rs` (`Preset::config`, `delayed_curvature`), the
//! resolution of files, flags and `--set` overrides in `overrides.rs` (`resolve`,
//! `resolve_resume`, `parse_set`).

pub use super::overrides::{parse_set, resolve, resolve_resume};

use crate::augment::{AugMode, AugmentConfig, Degradation};
use crate::render::ModelConfig;
use crate::train::hull::InitKind;
use crate::train::TrainConfig;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Why a configuration is rejected; each names the key or file at fault.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The config file could not be read.
    #[error("cannot read config file {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// TOML syntax error or unknown key / wrong type.
    #[error("{origin}: {message}")]
    Parse { origin: String, message: String },
    /// A value outside its valid range.
    #[error("config: `{key}` = {value} is invalid: {why}")]
    Invalid {
        key: String,
        value: String,
        why: String,
    },
    /// `--resume` with options that differ from the run's own `config.toml`.
    #[error(
        "cannot resume the run in {dir}: {differences}. A resumed run keeps the configuration it \
         started with (its config.toml); run `reconstruct --out {dir} --resume` with no other \
         options, or start a new run in another --out"
    )]
    ResumeMismatch { dir: PathBuf, differences: String },
}

pub(super) fn invalid(key: &str, value: impl std::fmt::Display, why: &str) -> ConfigError {
    ConfigError::Invalid {
        key: key.into(),
        value: value.to_string(),
        why: why.into(),
    }
}

/// Named starting points. `quick`, `fast` and `default` are sized for a 2-core CPU; `paper`
/// follows instant-nsr-pl `configs/neus-dtu-wmask.yaml` as closely as a CPU allows (hours).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// `fast` on half-size training images with half the samples per ray, shortened to
    /// [`QUICK_ITERATIONS`] steps: about 0.4× of `fast`'s time, under 1 mm on the default scene.
    Quick,
    /// Minutes on 2 cores: smaller hash table, fewer steps, coarser sampling.
    Fast,
    /// Tens of minutes on 2 cores.
    #[default]
    Default,
    /// The reference configuration (20k steps, T = 2^19, 1024 samples per ray): hours.
    Paper,
}

impl Preset {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Quick => "quick",
            Preset::Fast => "fast",
            Preset::Default => "default",
            Preset::Paper => "paper",
        }
    }
}

/// Which views are held out from training to measure PSNR/SSIM of novel-view renders.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Holdout {
    /// This many views, evenly spaced through the camera order.
    Count(usize),
    /// These view indices.
    Views(Vec<usize>),
}

impl Holdout {
    /// The held-out indices among `n` views (sorted, unique, in range).
    pub fn indices(&self, n: usize) -> Result<Vec<usize>, ConfigError> {
        let mut v = match self {
            Holdout::Count(0) => vec![],
            Holdout::Count(k) => {
                if *k >= n {
                    return Err(invalid("data.holdout", k, "leaves no training view"));
                }
                (0..*k)
                    .map(|i| ((i as f64 + 0.5) * n as f64 / *k as f64) as usize)
                    .collect()
            }
            Holdout::Views(v) => {
                if let Some(bad) = v.iter().find(|&&i| i >= n) {
                    return Err(invalid(
                        "data.holdout",
                        bad,
                        &format!("the scene has {n} views"),
                    ));
                }
                v.clone()
            }
        };
        v.sort_unstable();
        v.dedup();
        if v.len() >= n {
            return Err(invalid(
                "data.holdout",
                format!("{v:?}"),
                "leaves no training view",
            ));
        }
        Ok(v)
    }
}

/// What to train on (`[data]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DataConfig {
    /// Integer image downscale factor (DTU 1600×1200 → 2 gives the reference's 800×600).
    pub downscale: u32,
    /// Use masks when the scene has them (mask loss and background compositing).
    pub masks: bool,
    /// Fraction of the training views kept (the paper's reduced-data study: 0.1, 0.25, 0.5,
    /// 0.75), chosen with the run's seed; never fewer than one view.
    pub views_fraction: f64,
    /// An image degradation applied to every training image (`KIND:q`, e.g. `gaussian:0.1`).
    pub degrade: Option<Degradation>,
    /// Views held out for PSNR/SSIM (a count, evenly spaced, or a list of indices).
    pub holdout: Holdout,
    /// Held-out views are rendered at `1/render_downscale` of the training resolution.
    pub render_downscale: u32,
}

impl Default for DataConfig {
    fn default() -> Self {
        Self {
            downscale: 1,
            masks: true,
            views_fraction: 1.0,
            degrade: None,
            holdout: Holdout::Count(3),
            render_downscale: 2,
        }
    }
}

/// Mesh extraction (`[mesh]`): two-pass marching cubes on the SDF (instant-nsr-pl
/// `models/geometry.py`: a coarse pass over the box, then a refined pass over the coarse mesh's
/// bounds).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MeshConfig {
    /// Grid points per axis of the coarse pass over `[-r, r]³`.
    pub coarse_res: usize,
    /// Grid points per axis of the refined pass (the reference: 512).
    pub fine_res: usize,
    /// Padding of the refined box, as a fraction of the coarse mesh's extent.
    pub pad_fraction: f32,
    /// Half-width, in grid points, of the cube of the grey-scale closing applied to the SDF
    /// values of both passes before marching cubes (`mesh::closing`): it fills tunnels and
    /// pinholes narrower than about two cells (`2·close_radius`), which a thin sheet can get,
    /// and keeps flat faces, convex parts and wider holes. `0` extracts the raw level set, as
    /// NeuS and instant-nsr-pl do. At most 8.
    pub close_radius: usize,
    /// Clean the mesh before writing and scoring it (`mesh::clean`: mask culling, then small
    /// components, then enclosed ones, then unseen faces). The raw marching-cubes mesh is kept
    /// as `mesh_raw.ply` when the first three removed anything.
    pub clean: bool,
    /// Remove components whose area is below this share of the largest component's (`[0, 1]`).
    pub clean_min_area_share: f64,
    /// Cull what a training view sees outside its dilated mask; without masks
    /// (`data.masks = false`), what no training view sees inside its image.
    pub clean_mask_cull: bool,
    /// Mask dilation before culling, pixels of the training images.
    pub clean_dilate_px: usize,
    /// Remove components enclosed by a larger one (cavities no camera sees; `mesh::clean`).
    pub clean_enclosed: bool,
    /// Score and write as `mesh.ply` only the faces that at least this many training cameras
    /// see, occlusion by the mesh itself included (`mesh::clean` rule 4, NeuralWarp's triangle
    /// filter); the closed surface is kept as `mesh_closed.ply`. `0` keeps every face.
    pub clean_min_visible_views: usize,
    /// Rule 4 keeps, beside the faces the cameras see, every face within this distance (world
    /// mm, centroid to centroid) of one: surface that a camera sees only at a grazing angle can
    /// turn away from it in the reconstruction by a few degrees of normal error.
    pub clean_visible_margin_mm: f64,
    /// After rule 4's cut, judge what is left by closed part rather than by piece
    /// (`mesh::clean::SpeckRule::Part`): a part whose seen area is below `clean_min_area_share`
    /// of the most-seen part's goes, and every piece of the others stays. `false` (the default)
    /// drops each piece below that share of the largest piece, which also drops true surface
    /// the cut separated from the rest (a strip seen between unseen ones). Left out of
    /// `config.toml` when off, so the configurations of earlier runs keep their hashes.
    #[serde(skip_serializing_if = "is_false")]
    pub clean_specks_by_part: bool,
}

fn is_false(b: &bool) -> bool {
    !*b
}

impl MeshConfig {
    /// What rule 4's second follow-up compares (`clean_specks_by_part`).
    pub fn speck_rule(&self) -> crate::mesh::clean::SpeckRule {
        use crate::mesh::clean::SpeckRule;
        if self.clean_specks_by_part {
            SpeckRule::Part
        } else {
            SpeckRule::Piece
        }
    }
}

impl Default for MeshConfig {
    fn default() -> Self {
        Self {
            coarse_res: 128,
            fine_res: 512,
            pad_fraction: 0.1,
            close_radius: 0,
            clean: true,
            clean_min_area_share: 0.02,
            clean_mask_cull: true,
            clean_dilate_px: 4,
            clean_enclosed: true,
            clean_min_visible_views: 2,
            clean_visible_margin_mm: 0.0,
            clean_specks_by_part: false,
        }
    }
}

/// Evaluation (`[eval]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EvalConfig {
    /// Score the mesh when ground truth is found.
    pub enabled: bool,
    /// DTU ground-truth root ("SampleSet/MVS Data": `Points/stl/`, `ObsMask/`). Synthetic scenes
    /// carry theirs in the scene folder, which is used when this is unset.
    pub gt_root: Option<PathBuf>,
    /// DTU scan number; by default read from the scene's `meta.json` or its name (`scan24`).
    pub scan: Option<u32>,
    /// Also write error-coloured point clouds (`eval_d2s.ply`, `eval_s2d.ply`).
    pub vis: bool,
}

impl Default for EvalConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            gt_root: None,
            scan: None,
            vis: false,
        }
    }
}

/// Everything a `reconstruct` run does. Written as `config.toml` into the run folder.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunConfig {
    /// The preset the defaults came from.
    pub preset: Preset,
    /// A scene folder, a DTU scan under `data_root` (`scan24` or `dtu_scan24`), or a built-in
    /// synthetic scene (`neus-aug synth --list`). Empty: the embedded default scene.
    pub scene: String,
    /// Where real DTU scans live (env `NEUS_AUG_DATA`).
    pub data_root: PathBuf,
    /// Output folder (default `runs/<scene>-<aug>-<preset>-s<seed>`).
    pub out: Option<PathBuf>,
    /// Seed of everything random: initialisation, rays, views fraction, degradations.
    pub seed: u64,
    /// Training data.
    pub data: DataConfig,
    /// Image augmentations (`mode = none | sia | dia`).
    pub augment: AugmentConfig,
    /// Network, renderer and loss weights.
    pub model: ModelConfig,
    /// Optimisation.
    pub train: TrainConfig,
    /// Mesh extraction.
    pub mesh: MeshConfig,
    /// Evaluation.
    pub eval: EvalConfig,
    /// Exported files besides the scored mesh (`crate::export`).
    pub export: crate::export::ExportConfig,
}

/// Reports the first non-finite float anywhere in a configuration tree, naming its dotted key
/// (serde accepts `nan` and `inf` for every float field; none of them means anything useful).
fn check_finite(prefix: &str, v: &toml::Value) -> Result<(), ConfigError> {
    match v {
        toml::Value::Float(f) if !f.is_finite() => {
            Err(invalid(prefix, f, "must be a finite number"))
        }
        toml::Value::Table(t) => {
            for (k, x) in t {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                check_finite(&key, x)?;
            }
            Ok(())
        }
        toml::Value::Array(a) => a.iter().try_for_each(|x| check_finite(prefix, x)),
        _ => Ok(()),
    }
}

/// The version of the `config.toml` layout this build writes: 2 writes every key (schema 1 left
/// out keys at their defaults).
pub const CONFIG_SCHEMA: u32 = 2;

/// Schema 1 → 2: removes the keys of features no longer in the product when they held the
/// value that means "off", refusing a key that says the feature was on.
fn migrate_schema1(t: &mut toml::Table) -> Result<(), String> {
    type Off = fn(&toml::Value) -> bool;
    let zero: Off = |v| v.as_float() == Some(0.0) || v.as_integer() == Some(0);
    let any: Off = |_| true;
    let unset_weight: Off = |v| {
        let zero = |w: &toml::Value| w.as_float() == Some(0.0) || w.as_integer() == Some(0);
        v.as_table()
            .is_none_or(|s| s.get("weight").is_none_or(zero))
    };
    let disabled: Off = |v| {
        v.as_table()
            .is_none_or(|s| s.get("enabled").is_none_or(|e| e.as_bool() == Some(false)))
    };
    // (section path, key, is the value "off"?, what the feature was)
    let removed: [(&[&str], &str, Off, &str); 8] = [
        (
            &["train", "init"],
            "smooth_voxels",
            zero,
            "a blur of the visual hull",
        ),
        (
            &["train", "init"],
            "photo_tau",
            zero,
            "the photo-consistency carve",
        ),
        (
            &["train", "init"],
            "photo_min_views",
            any,
            "the photo-consistency carve",
        ),
        (
            &["train", "init"],
            "photo_max_iterations",
            any,
            "the photo-consistency carve",
        ),
        (&["train"], "unseen", unset_weight, "the unseen-space prior"),
        (
            &["train"],
            "multiview",
            unset_weight,
            "the multi-view patch prior",
        ),
        (
            &["model", "field"],
            "color_grid",
            disabled,
            "the colour grid",
        ),
        (
            &["train", "depth"],
            "end_step",
            |_| false,
            "an end step of the depth prior",
        ),
    ];
    for (path, key, off, what) in removed {
        let mut node = Some(&mut *t);
        for p in path {
            node = node
                .and_then(|n| n.get_mut(*p))
                .and_then(|v| v.as_table_mut());
        }
        let Some(section) = node else { continue };
        if let Some(v) = section.remove(key) {
            if !off(&v) {
                return Err(format!(
                    "`{}.{key}` = {v} turns on {what}, which this release no longer has; \
                     resume or reproduce the run with neus-aug 734b689 or earlier",
                    path.join(".")
                ));
            }
        }
    }
    if let Some(d) = t
        .get_mut("train")
        .and_then(|v| v.as_table_mut())
        .and_then(|t| t.get_mut("depth"))
        .and_then(|v| v.as_table_mut())
    {
        if let Some(v) = d.remove("final_weight") {
            return Err(format!(
                "`train.depth.final_weight` = {v} ramps the depth prior's weight, which this \
                 release no longer does; use neus-aug 734b689 or earlier"
            ));
        }
    }
    Ok(())
}

/// Largest grid points per axis of a marching-cubes pass: the SDF grid alone takes `res³ × 4`
/// bytes (32 GiB at 2048); the reference extracts at 512.
pub const MAX_MESH_RES: usize = 2048;

/// Largest accepted `mesh.close_radius` (grid points): wider closings fill real concavities.
pub const MAX_CLOSE_RADIUS: usize = 8;

impl RunConfig {
    /// Range checks that serde cannot express; each error names the key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_finite(
            "",
            &toml::Value::try_from(self).expect("configurations serialise"),
        )?;
        let t = &self.train;
        let o = &t.optimizer;
        if !(o.lr.is_finite() && o.lr > 0.0) {
            return Err(invalid(
                "train.optimizer.lr",
                o.lr,
                "must be a positive number",
            ));
        }
        if !(o.weight_decay.is_finite() && o.weight_decay >= 0.0) {
            return Err(invalid(
                "train.optimizer.weight_decay",
                o.weight_decay,
                "must be ≥ 0",
            ));
        }
        for (k, b) in [("beta1", o.beta1), ("beta2", o.beta2)] {
            if !(0.0..1.0).contains(&b) {
                return Err(invalid(
                    &format!("train.optimizer.{k}"),
                    b,
                    "must be in [0, 1)",
                ));
            }
        }
        if !(o.eps.is_finite() && o.eps > 0.0) {
            return Err(invalid("train.optimizer.eps", o.eps, "must be positive"));
        }
        if t.iterations == 0 {
            return Err(invalid("train.iterations", 0, "must be at least 1"));
        }
        if let Some((key, value, why)) = t.init.invalid() {
            return Err(invalid(key, value, why));
        }
        if let Some((key, value, why)) = t.error_map.invalid() {
            return Err(invalid(key, value, why));
        }
        if let Some((key, value, why)) = t.pose_refine.invalid() {
            return Err(invalid(key, value, why));
        }
        if let Some((key, value, why)) = t.depth.invalid() {
            return Err(invalid(&key, value, why));
        }
        if t.init.kind == InitKind::VisualHull && !self.data.masks {
            return Err(invalid(
                "train.init.kind",
                "\"visual_hull\"",
                "carves the training masks, and data.masks is false",
            ));
        }
        let lr = &t.lr;
        if !(lr.final_factor.is_finite() && lr.final_factor > 0.0) {
            return Err(invalid(
                "train.lr.final_factor",
                lr.final_factor,
                "must be positive",
            ));
        }
        if !(lr.warmup_start.is_finite() && (0.0..=1.0).contains(&lr.warmup_start)) {
            return Err(invalid(
                "train.lr.warmup_start",
                lr.warmup_start,
                "must be in [0, 1]",
            ));
        }
        let d = &self.data;
        if !(d.views_fraction.is_finite() && d.views_fraction > 0.0 && d.views_fraction <= 1.0) {
            return Err(invalid(
                "data.views_fraction",
                d.views_fraction,
                "must be in (0, 1]",
            ));
        }
        if d.downscale == 0 {
            return Err(invalid("data.downscale", 0, "must be at least 1"));
        }
        if d.render_downscale == 0 {
            return Err(invalid("data.render_downscale", 0, "must be at least 1"));
        }
        let m = &self.mesh;
        for (k, res) in [
            ("mesh.coarse_res", m.coarse_res),
            ("mesh.fine_res", m.fine_res),
        ] {
            if !(2..=MAX_MESH_RES).contains(&res) {
                return Err(invalid(
                    k,
                    res,
                    &format!(
                        "must be in 2..={MAX_MESH_RES} grid points per axis (the SDF grid takes \
                         res³ × 4 bytes)"
                    ),
                ));
            }
        }
        if !(m.pad_fraction.is_finite() && (0.0..=10.0).contains(&m.pad_fraction)) {
            return Err(invalid(
                "mesh.pad_fraction",
                m.pad_fraction,
                "must be in [0, 10] (a fraction of the coarse mesh's extent)",
            ));
        }
        if m.close_radius > MAX_CLOSE_RADIUS {
            return Err(invalid(
                "mesh.close_radius",
                m.close_radius,
                &format!("must be in 0..={MAX_CLOSE_RADIUS} grid points"),
            ));
        }
        if !(0.0..=1.0).contains(&m.clean_min_area_share) {
            return Err(invalid(
                "mesh.clean_min_area_share",
                m.clean_min_area_share,
                "must be in [0, 1]",
            ));
        }
        if !(m.clean_visible_margin_mm.is_finite() && m.clean_visible_margin_mm >= 0.0) {
            return Err(invalid(
                "mesh.clean_visible_margin_mm",
                m.clean_visible_margin_mm,
                "must be a finite distance >= 0 (world mm)",
            ));
        }
        let r = &self.model.render;
        for (k, n) in [
            ("model.render.num_samples_per_ray", r.num_samples_per_ray),
            ("model.render.train_num_rays", r.train_num_rays),
            ("model.render.max_train_num_rays", r.max_train_num_rays),
            ("model.render.chunk_samples", r.chunk_samples),
        ] {
            if n == 0 {
                return Err(invalid(k, n, "must be at least 1"));
            }
        }
        if !(1..=64).contains(&r.fd_central_every) {
            return Err(invalid(
                "model.render.fd_central_every",
                r.fd_central_every,
                "must be in 1..=64 (1: central differences on every sample)",
            ));
        }
        if !(r.fd_one_sided_span.is_finite() && (0.25..=2.0).contains(&r.fd_one_sided_span)) {
            return Err(invalid(
                "model.render.fd_one_sided_span",
                r.fd_one_sided_span,
                "must be in [0.25, 2] (units of the finite-difference step; the fast stencil takes taps up to two cells out)",
            ));
        }
        if !(r.radius.is_finite() && r.radius > 0.0) {
            return Err(invalid(
                "model.render.radius",
                r.radius,
                "must be finite and > 0",
            ));
        }
        if r.background.iter().any(|c| !(0.0..=1.0).contains(c)) {
            return Err(invalid(
                "model.render.background",
                format!("{:?}", r.background),
                "each channel must be in [0, 1]",
            ));
        }
        let occ = &r.occupancy;
        if !(1..=1024).contains(&occ.resolution) {
            return Err(invalid(
                "model.render.occupancy.resolution",
                occ.resolution,
                "must be in 1..=1024",
            ));
        }
        if !(occ.threshold.is_finite() && occ.threshold >= 0.0) {
            return Err(invalid(
                "model.render.occupancy.threshold",
                occ.threshold,
                "must be finite and ≥ 0",
            ));
        }
        if !(0.0..=1.0).contains(&occ.ema_decay) {
            return Err(invalid(
                "model.render.occupancy.ema_decay",
                occ.ema_decay,
                "must be in [0, 1]",
            ));
        }
        if occ.enabled && occ.update_every == 0 {
            return Err(invalid(
                "model.render.occupancy.update_every",
                0,
                "must be at least 1 when the occupancy grid is enabled",
            ));
        }
        let sdf = &self.model.field.sdf;
        if !(sdf.sphere_init_radius.is_finite() && sdf.sphere_init_radius > 0.0) {
            return Err(invalid(
                "model.field.sdf.sphere_init_radius",
                sdf.sphere_init_radius,
                "must be finite and > 0",
            ));
        }
        if let Err(why) = self.model.render.view_dependence.check() {
            return Err(invalid(
                "model.render.view_dependence",
                self.model.render.view_dependence,
                why,
            ));
        }
        for (k, w) in self.model.loss.weights() {
            if let Err(why) = w.check() {
                return Err(invalid(&format!("model.loss.{k}"), w, why));
            }
        }
        if let Some((key, value, why)) = self.export.invalid() {
            return Err(invalid(key, value, &why));
        }
        self.model.field.validate().map_err(|e| match e {
            crate::field::config::ConfigError::Invalid { key, value, why } => {
                invalid(&format!("model.field.{key}"), value, why)
            }
        })?;
        self.augment.validate().map_err(|e| match e {
            crate::augment::AugmentError::OutOfRange { what, value, range } => {
                invalid(&what, value, &format!("must be in {range}"))
            }
            other => invalid("augment", "", &other.to_string()),
        })?;
        Ok(())
    }

    /// The resolved configuration as TOML (what `config.toml` and `--print-config` hold): the
    /// schema version ([`CONFIG_SCHEMA`]), a comment naming the optional keys this run leaves
    /// unset (TOML has no null), then every other key with its value.
    pub fn to_toml(&self) -> String {
        let body = toml::to_string_pretty(self).expect("the configuration serialises");
        let unset: Vec<&str> = [
            ("out", self.out.is_none()),
            ("data.degrade", self.data.degrade.is_none()),
            (
                "model.field.hash_grid.progressive",
                self.model.field.hash_grid.progressive.is_none(),
            ),
            ("eval.gt_root", self.eval.gt_root.is_none()),
            ("eval.scan", self.eval.scan.is_none()),
        ]
        .into_iter()
        .filter_map(|(k, unset)| unset.then_some(k))
        .collect();
        let note = if unset.is_empty() {
            String::new()
        } else {
            format!("# unset (no value): {}\n", unset.join(", "))
        };
        format!(
            "# neus-aug run configuration: every key the run used.\n{note}schema = \
             {CONFIG_SCHEMA}\n{body}"
        )
    }

    /// Reads a saved configuration (`config.toml` of a run folder, or a checkpoint's copy),
    /// whatever schema wrote it. Schema 1 (no `schema` key; before every key was written) left
    /// out keys at their defaults, which serde fills in, and may hold keys of features since
    /// removed: those are dropped when they say the feature was off, and refused, naming the key,
    /// when it was on (such a run needs the release that had the feature). `origin` names the
    /// text in errors.
    pub fn from_saved_toml(text: &str, origin: &str) -> Result<Self, ConfigError> {
        let parse = |message: String| ConfigError::Parse {
            origin: origin.into(),
            message,
        };
        let mut t: toml::Table = toml::from_str(text).map_err(|e| parse(e.to_string()))?;
        let schema = match t.remove("schema") {
            None => 1,
            Some(toml::Value::Integer(v)) if (1..=CONFIG_SCHEMA as i64).contains(&v) => v as u32,
            Some(v) => {
                return Err(parse(format!(
                    "schema = {v}: this build reads schemas 1 to {CONFIG_SCHEMA}; a newer \
                     neus-aug wrote it"
                )))
            }
        };
        if schema == 1 {
            migrate_schema1(&mut t).map_err(parse)?;
        }
        toml::Value::Table(t)
            .try_into()
            .map_err(|e: toml::de::Error| parse(e.to_string()))
    }

    /// A hash of everything that shapes training (scene, seed, data, augmentation, model,
    /// optimisation), not output, mesh or evaluation settings: a checkpoint is resumed only under
    /// the same hash. FNV-1a 64 over the TOML of those fields.
    pub fn training_hash(&self) -> String {
        #[derive(Serialize)]
        struct Shaping<'a> {
            scene: &'a str,
            seed: u64,
            data: &'a DataConfig,
            augment: &'a AugmentConfig,
            model: &'a ModelConfig,
            train: &'a TrainConfig,
        }
        let text = toml::to_string(&Shaping {
            scene: &self.scene,
            seed: self.seed,
            data: &self.data,
            augment: &self.augment,
            model: &self.model,
            train: &self.train,
        })
        .expect("serialises");
        crate::util::fnv1a64_hex(text.as_bytes())
    }

    /// The appearance-embedding input the model needs for the augmentation mode: none for the
    /// baseline, `Emb(M)` for SIA, `[Emb(M), p]` for DIA (paper §3), one row per manipulation.
    pub fn apply_augment_to_model(&mut self) {
        let a = &mut self.model.field.appearance;
        match self.augment.mode {
            AugMode::None => {
                a.n_codes = 0;
                a.with_scalar = false;
            }
            AugMode::Sia => {
                a.n_codes = crate::augment::Manipulation::COUNT;
                a.with_scalar = false;
            }
            AugMode::Dia => {
                a.n_codes = crate::augment::Manipulation::COUNT;
                a.with_scalar = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holdout_indices() {
        assert_eq!(Holdout::Count(3).indices(49).unwrap(), vec![8, 24, 40]);
        assert_eq!(Holdout::Count(0).indices(5).unwrap(), Vec::<usize>::new());
        assert!(Holdout::Count(5).indices(5).is_err());
        assert!(Holdout::Views(vec![9]).indices(5).is_err());
        assert_eq!(
            Holdout::Views(vec![3, 1, 3]).indices(5).unwrap(),
            vec![1, 3]
        );
    }

    #[test]
    fn the_speck_rule_key_is_written_only_when_on_and_reads_back() {
        let mut c = Preset::Fast.config();
        assert!(!c.to_toml().contains("clean_specks_by_part"));
        c.mesh.clean_specks_by_part = true;
        let text = c.to_toml();
        assert!(text.contains("clean_specks_by_part = true"), "{text}");
        let back = RunConfig::from_saved_toml(&text, "test").unwrap();
        assert_eq!(back.mesh.speck_rule(), crate::mesh::clean::SpeckRule::Part);
        assert_eq!(back.training_hash(), Preset::Fast.config().training_hash());
    }

    #[test]
    fn training_hash_ignores_output_settings_only() {
        let a = Preset::Fast.config();
        let mut b = a.clone();
        b.out = Some("elsewhere".into());
        b.mesh.fine_res = 64;
        b.eval.vis = true;
        assert_eq!(a.training_hash(), b.training_hash());
        b.seed = 1;
        assert_ne!(a.training_hash(), b.training_hash());
    }
}
