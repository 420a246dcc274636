//! `neus-aug reconstruct [SCENE]`: train NeuS, extract the mesh, evaluate it.

use anyhow::Context;
use neus_aug::augment::{AugMode, Degradation};
use neus_aug::reconstruct::{self, parse_set, Preset, RunOptions};
use std::path::PathBuf;

/// Train NeuS on a scene, extract the mesh (world mm) and score it with the DTU protocol when
/// ground truth exists. Every flag is also a config field (see `config.toml` in a run folder);
/// `--set key=value` reaches any other field.
#[derive(Debug, clap::Args)]
pub struct ReconstructArgs {
    /// A scene folder (NeuS/IDR DTU layout), a DTU scan under --data-root (`scan24`), or a
    /// built-in synthetic scene (`neus-aug synth --list`). Default: the embedded default scene.
    pub scene: Option<String>,
    /// Where real DTU scans live (config `data_root`).
    #[arg(long, env = "NEUS_AUG_DATA")]
    pub data_root: Option<PathBuf>,
    /// Image augmentation (config `augment.mode`).
    #[arg(long, value_enum)]
    pub aug: Option<AugMode>,
    /// Starting configuration (config `preset`); default: `default`.
    #[arg(long, value_enum)]
    pub preset: Option<Preset>,
    /// Seed of everything random (config `seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Keep this fraction of the training views, e.g. 0.25 (config `data.views_fraction`).
    #[arg(long)]
    pub views_fraction: Option<f64>,
    /// Degrade the training images, `KIND:q` (gaussian, motion_blur, poisson, salt_pepper,
    /// speckle; config `data.degrade`).
    #[arg(long)]
    pub degrade: Option<Degradation>,
    /// Training steps (config `train.iterations`).
    #[arg(long)]
    pub iterations: Option<u64>,
    /// Output folder (config `out`; default `runs/<scene>-<aug>-<preset>-s<seed>`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// A TOML configuration file (any subset of the fields of `config.toml`).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Set any config field: `--set model.render.num_samples_per_ray=256` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// DTU ground-truth root ("SampleSet/MVS Data"; config `eval.gt_root`).
    #[arg(long)]
    pub gt_root: Option<PathBuf>,
    /// DTU scan number for evaluation (config `eval.scan`).
    #[arg(long)]
    pub scan: Option<u32>,
    /// Continue the run in the output folder from its checkpoint, with the configuration in its
    /// own config.toml (`reconstruct --out DIR --resume` needs no other option; options given
    /// must agree with it). A folder without a run starts one when the command names the scene.
    #[arg(long)]
    pub resume: bool,
    /// Redo a finished run in the output folder (the finished run is kept aside until the new
    /// one has finished, and comes back if it fails).
    #[arg(long)]
    pub force: bool,
    /// No progress output.
    #[arg(long, short)]
    pub quiet: bool,
    /// Stop after this many steps with a checkpoint, as if killed (for testing --resume).
    #[arg(long, hide = true)]
    pub stop_after: Option<u64>,
    /// Print the resolved configuration and exit.
    #[arg(long)]
    pub print_config: bool,
}

fn toml_str(s: impl ToString) -> toml::Value {
    toml::Value::String(s.to_string())
}

/// A `u64` flag as a TOML integer (signed 64-bit): values from 2^63 up are refused by name,
/// instead of wrapping to a negative number.
fn toml_int(flag: &str, v: u64) -> anyhow::Result<toml::Value> {
    match i64::try_from(v) {
        Ok(i) => Ok(toml::Value::Integer(i)),
        Err(_) => anyhow::bail!(
            "{flag} {v} is too large: at most {} (2^63 - 1; the configuration is TOML, whose \
             integers are signed 64-bit)",
            i64::MAX
        ),
    }
}

pub fn run(args: ReconstructArgs) -> anyhow::Result<()> {
    let mut sets: Vec<(String, toml::Value)> = Vec::new();
    let mut put = |k: &str, v: toml::Value| sets.push((k.to_string(), v));
    if let Some(s) = &args.scene {
        put("scene", toml_str(s));
    }
    if let Some(d) = &args.data_root {
        put("data_root", toml_str(d.display()));
    }
    if let Some(a) = args.aug {
        put("augment.mode", toml_str(a.name()));
    }
    if let Some(s) = args.seed {
        put("seed", toml_int("--seed", s)?);
    }
    if let Some(f) = args.views_fraction {
        put("data.views_fraction", toml::Value::Float(f));
    }
    if let Some(d) = &args.degrade {
        put("data.degrade", toml_str(d));
    }
    if let Some(i) = args.iterations {
        put("train.iterations", toml_int("--iterations", i)?);
    }
    if let Some(o) = &args.out {
        put("out", toml_str(o.display()));
    }
    if let Some(g) = &args.gt_root {
        put("eval.gt_root", toml_str(g.display()));
    }
    if let Some(s) = args.scan {
        put("eval.scan", toml::Value::Integer(s as i64));
    }
    for s in &args.set {
        sets.push(parse_set(s)?);
    }
    let cfg = if args.resume {
        resume_config(&args, &sets)?
    } else {
        reconstruct::resolve(args.preset, args.config.as_deref(), &sets)?
    };
    if args.print_config {
        print!("{}", cfg.to_toml());
        return Ok(());
    }
    let metrics = reconstruct::run(
        &cfg,
        &RunOptions {
            resume: args.resume,
            force: args.force,
            quiet: args.quiet,
            stop_after: args.stop_after,
        },
    )
    .context("reconstruct failed")?;
    if args.quiet {
        if let Some(c) = &metrics.chamfer {
            println!(
                "chamfer_sum {:.4} mm (accuracy {:.4}, completeness {:.4})",
                c.chamfer_sum, c.mean_d2s, c.mean_s2d
            );
        }
    }
    Ok(())
}

/// The configuration of `--resume`: the run folder's own `config.toml` when it has one (options
/// given are checked against it, see [`reconstruct::resolve_resume`]), else the usual resolution
/// (a folder without a run yet: the first attempt of a study job, for example), but only when
/// the command names what to run: `--resume` alone on a folder without a run is refused rather
/// than starting the default scene there.
fn resume_config(
    args: &ReconstructArgs,
    sets: &[(String, toml::Value)],
) -> anyhow::Result<reconstruct::RunConfig> {
    let out = match &args.out {
        Some(o) => o.clone(),
        None => {
            // The default folder depends on the scene, augmentation, preset and seed given.
            let cfg = reconstruct::resolve(args.preset, args.config.as_deref(), sets)?;
            let scene = reconstruct::resolve_scene(&cfg.scene, &cfg.data_root, args.quiet)?;
            reconstruct::output_dir(&cfg, &scene)
        }
    };
    let saved = out.join("config.toml");
    if saved.is_file() {
        Ok(reconstruct::resolve_resume(
            &saved,
            args.preset,
            args.config.as_deref(),
            sets,
        )?)
    } else {
        let named =
            args.scene.is_some() || args.config.is_some() || sets.iter().any(|(k, _)| k == "scene");
        anyhow::ensure!(
            named,
            "--resume: {} holds no run to resume (no config.toml); to start one there, name the \
             scene and drop --resume (e.g. `neus-aug reconstruct SCENE --out {}`)",
            out.display(),
            out.display()
        );
        Ok(reconstruct::resolve(
            args.preset,
            args.config.as_deref(),
            sets,
        )?)
    }
}
