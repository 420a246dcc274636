//! The resolved configuration of a `reconstruct` run, its presets, and how overrides combine.
//!
//! One struct ([`RunConfig`]) holds every option; the TOML file and the command line are two ways
//! to set its fields. Resolution order: the preset's defaults → `--config FILE` → command-line
//! flags → `--set key=value` (TOML syntax, dotted keys). Unknown keys are errors naming the key;
//! the resolved configuration is written to the run folder as `config.toml`.

use crate::augment::{AugMode, AugmentConfig, Degradation};
use crate::field::config::ProgressiveConfig;
use crate::render::{ModelConfig, Scheduled};
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

fn invalid(key: &str, value: impl std::fmt::Display, why: &str) -> ConfigError {
    ConfigError::Invalid {
        key: key.into(),
        value: value.to_string(),
        why: why.into(),
    }
}

/// Named starting points. `fast` and `default` are sized for a 2-core CPU; `paper` follows
/// instant-nsr-pl `configs/neus-dtu-wmask.yaml` as closely as a CPU allows (hours).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
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
    /// Clean the mesh before writing and scoring it (`mesh::clean`: mask culling, then small
    /// components). The raw marching-cubes mesh is kept as `mesh_raw.ply` when anything was
    /// removed.
    pub clean: bool,
    /// Remove components whose area is below this share of the largest component's (`[0, 1]`).
    pub clean_min_area_share: f64,
    /// Cull what a training view sees outside its dilated mask; without masks
    /// (`data.masks = false`), what no training view sees inside its image.
    pub clean_mask_cull: bool,
    /// Mask dilation before culling, pixels of the training images.
    pub clean_dilate_px: usize,
}

impl Default for MeshConfig {
    fn default() -> Self {
        Self {
            coarse_res: 128,
            fine_res: 512,
            pad_fraction: 0.1,
            clean: true,
            clean_min_area_share: 0.02,
            clean_mask_cull: true,
            clean_dilate_px: 4,
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
}

impl Default for RunConfig {
    fn default() -> Self {
        Preset::Default.config()
    }
}

impl Preset {
    /// The full configuration of this preset.
    ///
    /// `paper` is instant-nsr-pl's `neus-dtu-wmask.yaml` (20000 steps, T = 2^19, 1024 samples per
    /// ray, 256 → 8192 rays, cos anneal over the whole run, constant learning rate for 5000 steps
    /// then decay to 0.1×, 512³ marching cubes, DTU images at half size). `default` and `fast`
    /// shrink the hash table (it no longer fits a CPU's cache at 2^19), the sample budget, the
    /// step count and the occupancy grid, and warm the learning rate up briefly because short
    /// runs start with few rays.
    pub fn config(self) -> RunConfig {
        let mut model = ModelConfig::default();
        let mut train = TrainConfig::default();
        let mut data = DataConfig::default();
        let mut mesh = MeshConfig::default();
        match self {
            Preset::Paper => {
                data.downscale = 2;
                data.render_downscale = 1;
                // instant-nsr-pl `configs/neus-dtu.yaml` (ProgressiveBandHashGrid): 4 levels at
                // first, one more every 1000 steps.
                model.field.hash_grid.progressive = Some(ProgressiveConfig {
                    start_level: 4,
                    start_step: 0,
                    update_steps: 1000,
                });
            }
            Preset::Default => {
                model.field.hash_grid.log2_hashmap_size = 17;
                model.render.num_samples_per_ray = 512;
                model.render.train_num_rays = 128;
                model.render.max_train_num_rays = 4096;
                model.render.occupancy.resolution = 64;
                train.iterations = 8000;
                // The same coarse-to-fine schedule as `paper`, on the preset's step count: every
                // level active after 60 % of training (issue 13: cleaner topology, and inactive
                // levels cost nothing).
                model.field.hash_grid.progressive = Some(ProgressiveConfig {
                    start_level: 4,
                    start_step: 0,
                    update_steps: 400,
                });
                train.lr.constant_steps = 2000;
                train.lr.warmup_steps = 200;
                train.checkpoint_every = 500;
                model.render.cos_anneal_end = 8000;
                mesh.coarse_res = 128;
                mesh.fine_res = 512;
            }
            Preset::Fast => {
                model.field.hash_grid.log2_hashmap_size = 16;
                model.render.num_samples_per_ray = 256;
                model.render.train_num_rays = 128;
                model.render.max_train_num_rays = 2048;
                model.render.occupancy.resolution = 48;
                train.iterations = 2000;
                model.field.hash_grid.progressive = Some(ProgressiveConfig {
                    start_level: 4,
                    start_step: 0,
                    update_steps: 100,
                });
                train.lr.constant_steps = 500;
                train.lr.warmup_steps = 100;
                train.checkpoint_every = 250;
                model.render.cos_anneal_end = 2000;
                data.render_downscale = 2;
                mesh.coarse_res = 96;
                mesh.fine_res = 256;
            }
        }
        model.loss.curvature = delayed_curvature(train.iterations);
        RunConfig {
            preset: self,
            scene: String::new(),
            data_root: PathBuf::from("data/dtu"),
            out: None,
            seed: 0,
            data,
            augment: AugmentConfig::default(),
            model,
            train,
            mesh,
            eval: EvalConfig::default(),
        }
    }
}

/// The curvature weight of every preset (issue 13): Neuralangelo's mean-|Laplacian| loss at
/// weight 5·10⁻⁴ (`projects/neuralangelo/configs/base.yaml`, `curvature: 5e-4`), but **off for the
/// first half of training** and ramped in linearly over the next tenth, i.e.
/// `[iterations/2, 0, 5e-4, 3·iterations/5]`: the ramp ends when the last hash level turns on in
/// every preset's progressive schedule (fast 1200/2000, default 4800/8000, paper 12000/20000).
/// Neuralangelo warms the weight up from step 0; here, on the torus, that kept the membrane across
/// the hole (fast preset, 2.09 mm, mask IoU 0.74), while the delayed ramp lets the masks carve the
/// topology first and then smooths it: torus seed 0 0.688 → 0.617 mm, genus 10 → 2, held-out
/// normal error 10.6° → 5.9°; default scene 1.061 → 0.687 mm, 9.3° → 3.7° (results/geometry/).
pub fn delayed_curvature(iterations: u64) -> Scheduled {
    Scheduled::Linear(iterations / 2, 0.0, 5e-4, iterations * 3 / 5)
}

/// Deep-merges `over` into `base` (tables merge key by key; other values replace).
fn merge(base: &mut toml::Value, over: toml::Value) {
    match (base, over) {
        (toml::Value::Table(b), toml::Value::Table(o)) => {
            for (k, v) in o {
                match b.get_mut(&k) {
                    Some(slot) => merge(slot, v),
                    None => {
                        b.insert(k, v);
                    }
                }
            }
        }
        (slot, v) => *slot = v,
    }
}

/// Sets a dotted key (`model.render.num_samples_per_ray`) in a TOML tree.
fn set_dotted(root: &mut toml::Value, key: &str, value: toml::Value) -> Result<(), ConfigError> {
    let parts: Vec<&str> = key.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(invalid(
            key,
            "",
            "is not a dotted key like train.iterations",
        ));
    }
    let mut node = root;
    for p in &parts[..parts.len() - 1] {
        let table = node
            .as_table_mut()
            .ok_or_else(|| invalid(key, "", "goes through a value that is not a table"))?;
        node = table
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(Default::default()));
    }
    node.as_table_mut()
        .ok_or_else(|| invalid(key, "", "goes through a value that is not a table"))?
        .insert(parts[parts.len() - 1].to_string(), value);
    Ok(())
}

/// Parses the value of a `--set key=value` (TOML syntax; a bare word is taken as a string).
pub fn parse_set(spec: &str) -> Result<(String, toml::Value), ConfigError> {
    let (k, v) = spec
        .split_once('=')
        .ok_or_else(|| invalid("--set", spec, "must look like key=value"))?;
    let k = k.trim();
    let wrapped = format!("v = {}", v.trim());
    let value = match toml::from_str::<toml::Table>(&wrapped) {
        Ok(mut t) => t.remove("v").expect("parsed key"),
        Err(_) => toml::Value::String(v.trim().to_string()),
    };
    Ok((k.to_string(), value))
}

/// Reads a TOML configuration file into a tree; errors name the file.
fn read_toml(path: &std::path::Path) -> Result<toml::Value, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
        path: path.into(),
        source,
    })?;
    let table: toml::Table = toml::from_str(&text).map_err(|e| ConfigError::Parse {
        origin: path.display().to_string(),
        message: e.to_string(),
    })?;
    Ok(toml::Value::Table(table))
}

/// The `preset` key of a configuration tree, if it has one.
fn preset_of(tree: Option<&toml::Value>) -> Result<Option<Preset>, ConfigError> {
    match tree.and_then(|v| v.get("preset")) {
        Some(p) => Ok(Some(p.clone().try_into::<Preset>().map_err(|e| {
            ConfigError::Parse {
                origin: "config key `preset`".into(),
                message: e.to_string(),
            }
        })?)),
        None => Ok(None),
    }
}

/// Builds the configuration: `preset` (if `None`, the file's `preset` key or `default`), then
/// the file, then `overrides` (dotted key → value, in order). `preset` cannot be an override: it
/// picks the defaults every other key starts from (`--preset NAME` or the file's `preset` key).
pub fn resolve(
    preset: Option<Preset>,
    file: Option<&std::path::Path>,
    overrides: &[(String, toml::Value)],
) -> Result<RunConfig, ConfigError> {
    let file_value = file.map(read_toml).transpose()?;
    let preset = preset
        .or(preset_of(file_value.as_ref())?)
        .unwrap_or_default();
    let tree = toml::Value::try_from(preset.config()).expect("presets serialise");
    finish(tree, preset, file, file_value, overrides)
}

/// Merges the file and the overrides into `tree`, then deserialises and validates.
fn finish(
    mut tree: toml::Value,
    preset: Preset,
    file: Option<&std::path::Path>,
    file_value: Option<toml::Value>,
    overrides: &[(String, toml::Value)],
) -> Result<RunConfig, ConfigError> {
    if let Some(v) = file_value {
        merge(&mut tree, v);
    }
    for (k, v) in overrides {
        if k == "preset" {
            return Err(invalid(
                "preset",
                v,
                "cannot be set with --set: a preset picks the defaults every other key starts \
                 from; use --preset NAME (or `preset` in the --config file)",
            ));
        }
        set_dotted(&mut tree, k, v.clone())?;
    }
    set_dotted(
        &mut tree,
        "preset",
        toml::Value::String(preset.name().into()),
    )?;
    let origin = match file {
        Some(p) => format!("configuration ({} and command line)", p.display()),
        None => "configuration (command line)".to_string(),
    };
    let mut cfg: RunConfig = tree
        .try_into()
        .map_err(|e: toml::de::Error| ConfigError::Parse {
            origin,
            message: e.to_string(),
        })?;
    cfg.apply_augment_to_model();
    cfg.validate()?;
    Ok(cfg)
}

/// The configuration of `reconstruct --resume`: the run's own `config.toml` (`saved`), with the
/// options given now applied on top only to check that they agree with it. A preset, file or
/// override that changes any value (the output folder aside) is refused with every differing key
/// named, so `--resume` needs no options and never silently trains another configuration.
pub fn resolve_resume(
    saved: &std::path::Path,
    preset: Option<Preset>,
    file: Option<&std::path::Path>,
    overrides: &[(String, toml::Value)],
) -> Result<RunConfig, ConfigError> {
    let dir = saved.parent().map(|p| p.to_path_buf()).unwrap_or_default();
    let saved_tree = read_toml(saved)?;
    let saved_cfg: RunConfig = saved_tree
        .clone()
        .try_into()
        .map_err(|e: toml::de::Error| ConfigError::Parse {
            origin: saved.display().to_string(),
            message: e.to_string(),
        })?;
    let file_value = file.map(read_toml).transpose()?;
    for p in [preset, preset_of(file_value.as_ref())?]
        .into_iter()
        .flatten()
    {
        if p != saved_cfg.preset {
            return Err(ConfigError::ResumeMismatch {
                dir,
                differences: format!(
                    "preset: the run has {}, given {}",
                    saved_cfg.preset.name(),
                    p.name()
                ),
            });
        }
    }
    let base = toml::Value::try_from(&saved_cfg).expect("configurations serialise");
    let cfg = finish(base, saved_cfg.preset, file, file_value, overrides)?;
    let mut diffs = Vec::new();
    let (mut a, mut b) = (saved_cfg.clone(), cfg.clone());
    a.out = None;
    b.out = None;
    diff_trees(
        "",
        &toml::Value::try_from(&a).expect("serialises"),
        &toml::Value::try_from(&b).expect("serialises"),
        &mut diffs,
    );
    if !diffs.is_empty() {
        return Err(ConfigError::ResumeMismatch {
            dir,
            differences: diffs.join("; "),
        });
    }
    Ok(cfg)
}

/// Appends `key: the run has A, given B` for every leaf where `a` and `b` differ.
fn diff_trees(prefix: &str, a: &toml::Value, b: &toml::Value, out: &mut Vec<String>) {
    let key = |k: &str| {
        if prefix.is_empty() {
            k.to_string()
        } else {
            format!("{prefix}.{k}")
        }
    };
    match (a, b) {
        (toml::Value::Table(ta), toml::Value::Table(tb)) => {
            let mut keys: Vec<&String> = ta.keys().chain(tb.keys()).collect();
            keys.sort();
            keys.dedup();
            for k in keys {
                match (ta.get(k), tb.get(k)) {
                    (Some(x), Some(y)) => diff_trees(&key(k), x, y, out),
                    (x, y) => out.push(format!(
                        "{}: the run has {}, given {}",
                        key(k),
                        x.map_or("nothing".into(), |v| v.to_string()),
                        y.map_or("nothing".into(), |v| v.to_string())
                    )),
                }
            }
        }
        _ if a != b => out.push(format!("{prefix}: the run has {a}, given {b}")),
        _ => {}
    }
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

/// Largest grid points per axis of a marching-cubes pass: the SDF grid alone takes `res³ × 4`
/// bytes (32 GiB at 2048); the reference extracts at 512.
pub const MAX_MESH_RES: usize = 2048;

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
        if !(0.0..=1.0).contains(&m.clean_min_area_share) {
            return Err(invalid(
                "mesh.clean_min_area_share",
                m.clean_min_area_share,
                "must be in [0, 1]",
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
        let l = &self.model.loss;
        for (k, w) in [
            ("rgb_l1", l.rgb_l1),
            ("rgb_mse", l.rgb_mse),
            ("eikonal", l.eikonal),
            ("mask", l.mask),
            ("curvature", l.curvature),
        ] {
            if let Err(why) = w.check() {
                return Err(invalid(&format!("model.loss.{k}"), w, why));
            }
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

    /// The resolved configuration as TOML (what `config.toml` holds).
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("the configuration serialises")
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
    fn every_preset_delays_curvature_until_the_topology_has_formed() {
        for preset in [Preset::Fast, Preset::Default, Preset::Paper] {
            let c = preset.config();
            let n = c.train.iterations;
            let w = c.model.loss.curvature;
            assert_eq!(w.at(0), 0.0, "{preset:?}");
            assert_eq!(w.at(n / 2), 0.0, "{preset:?}");
            assert!((w.at(n) - 5e-4).abs() < 1e-12, "{preset:?}");
            assert!(
                w.at(n * 11 / 20) > 0.0 && w.at(n * 11 / 20) < 5e-4,
                "{preset:?}"
            );
            // The ramp ends when the last hash level is on, not before.
            let p = c.model.field.hash_grid.progressive.unwrap();
            let levels = c.model.field.hash_grid.n_levels;
            let all_on = p.start_step + (levels - p.start_level) as u64 * p.update_steps;
            assert_eq!(n * 3 / 5, all_on, "{preset:?}");
            w.check().unwrap();
        }
    }

    #[test]
    fn presets_resolve_and_round_trip_through_toml() {
        for p in [Preset::Fast, Preset::Default, Preset::Paper] {
            let c = resolve(Some(p), None, &[]).unwrap();
            assert_eq!(c.preset, p);
            let back: RunConfig = toml::from_str(&c.to_toml()).unwrap();
            assert_eq!(back, c);
        }
        let paper = Preset::Paper.config();
        assert_eq!(paper.train.iterations, 20000);
        assert_eq!(paper.model.field.hash_grid.log2_hashmap_size, 19);
        assert_eq!(paper.model.render.num_samples_per_ray, 1024);
    }

    #[test]
    fn file_then_flags_then_set_override_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("c.toml");
        std::fs::write(
            &f,
            "preset = \"fast\"\nseed = 3\n[train]\niterations = 77\n",
        )
        .unwrap();
        let c = resolve(None, Some(&f), &[]).unwrap();
        assert_eq!(
            (c.preset, c.seed, c.train.iterations),
            (Preset::Fast, 3, 77)
        );
        // Other fast-preset values survive the partial [train] table.
        assert_eq!(
            c.train.lr.constant_steps,
            Preset::Fast.config().train.lr.constant_steps
        );
        let sets = vec![
            parse_set("train.iterations=5").unwrap(),
            parse_set("data.degrade=gaussian:0.05").unwrap(),
            parse_set("augment.mode=dia").unwrap(),
        ];
        let c = resolve(Some(Preset::Default), Some(&f), &sets).unwrap();
        assert_eq!((c.preset, c.train.iterations), (Preset::Default, 5));
        assert_eq!(c.augment.mode, AugMode::Dia);
        assert_eq!(c.data.degrade.unwrap().to_string(), "gaussian:0.05");
    }

    #[test]
    fn unknown_keys_and_bad_values_are_named() {
        let e = resolve(None, None, &[parse_set("train.iterationz=5").unwrap()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("iterationz"), "{e}");
        let e = resolve(
            None,
            None,
            &[parse_set("train.optimizer.lr=-0.01").unwrap()],
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("train.optimizer.lr") && e.contains("-0.01"),
            "{e}"
        );
        let e = resolve(None, None, &[parse_set("data.views_fraction=0").unwrap()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("views_fraction"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("bad.toml");
        std::fs::write(&f, "[train\niterations = 1").unwrap();
        let e = resolve(None, Some(&f), &[]).unwrap_err().to_string();
        assert!(e.contains("bad.toml"), "{e}");
        let e = resolve(None, Some(&dir.path().join("none.toml")), &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.toml"), "{e}");
    }

    #[test]
    fn loss_weights_follow_the_reference_schedule_helper() {
        let sets = vec![
            parse_set("model.loss.eikonal=[0, 0.1, 0.0, 10]").unwrap(),
            parse_set("model.loss.mask=0.25").unwrap(),
        ];
        let c = resolve(Some(Preset::Fast), None, &sets).unwrap();
        let at = |step| c.model.schedule(step).loss;
        assert!((at(0).eikonal - 0.1).abs() < 1e-7);
        assert!((at(5).eikonal - 0.05).abs() < 1e-7);
        assert_eq!(at(50).eikonal, 0.0);
        assert_eq!((at(0).mask, at(50).mask), (0.25, 0.25));
        // The written configuration keeps the quadruple.
        let back: RunConfig = toml::from_str(&c.to_toml()).unwrap();
        assert_eq!(back.model.loss, c.model.loss);
        let bad = resolve(
            None,
            None,
            &[parse_set("model.loss.mask=[0, 0.1, -1.0, 10]").unwrap()],
        );
        assert!(bad.unwrap_err().to_string().contains("model.loss.mask"));
        let bad = resolve(
            None,
            None,
            &[parse_set("model.loss.curvature=-0.5").unwrap()],
        );
        assert!(bad
            .unwrap_err()
            .to_string()
            .contains("model.loss.curvature"));
    }

    #[test]
    fn resume_keeps_the_saved_configuration_and_names_every_difference() {
        let dir = tempfile::tempdir().unwrap();
        let saved = dir.path().join("config.toml");
        let sets = vec![
            parse_set("seed=7").unwrap(),
            parse_set("scene=torus").unwrap(),
            parse_set("train.iterations=33").unwrap(),
        ];
        let c = resolve(Some(Preset::Fast), None, &sets).unwrap();
        std::fs::write(&saved, c.to_toml()).unwrap();
        // No options: the saved configuration, whatever the default preset says.
        assert_eq!(resolve_resume(&saved, None, None, &[]).unwrap(), c);
        // Agreeing options (and another spelling of the output folder) are accepted.
        let same = vec![
            parse_set("seed=7").unwrap(),
            parse_set("out=\"elsewhere\"").unwrap(),
        ];
        let r = resolve_resume(&saved, Some(Preset::Fast), None, &same).unwrap();
        assert_eq!(r.out, Some(PathBuf::from("elsewhere")));
        // Two changed values: both named, with the saved and the given value.
        let e = resolve_resume(
            &saved,
            None,
            None,
            &[
                parse_set("seed=8").unwrap(),
                parse_set("mesh.fine_res=64").unwrap(),
            ],
        )
        .unwrap_err()
        .to_string();
        for want in [
            "seed: the run has 7, given 8",
            "mesh.fine_res: the run has 256, given 64",
        ] {
            assert!(e.contains(want), "{e}");
        }
        let e = resolve_resume(&saved, Some(Preset::Paper), None, &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("preset: the run has fast, given paper"), "{e}");
        // The saved file is never rewritten by resolution.
        assert_eq!(std::fs::read_to_string(&saved).unwrap(), c.to_toml());
    }

    #[test]
    fn nan_is_refused_in_any_float_key_by_name() {
        for key in [
            "mesh.pad_fraction",
            "model.render.occupancy.ema_decay",
            "model.render.variance_init",
            "train.lr.warmup_start",
            "model.field.sdf.softplus_beta",
        ] {
            let e = resolve(None, None, &[parse_set(&format!("{key}=nan")).unwrap()])
                .unwrap_err()
                .to_string();
            assert!(e.contains(key) && e.contains("NaN"), "{key}: {e}");
        }
    }

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
