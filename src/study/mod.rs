//! `neus-aug study`: the paper's experiment grids on the built-in synthetic scenes, run
//! repeatably, resumably, and summarised with seeds, paired statistics, tables and plots.
//!
//! The paper's claims are comparative (does SIA or DIA lower the Chamfer distance; do
//! augmentations help when data are scarce or degraded), so a study is a grid of
//! `neus-aug reconstruct` runs that differ in one thing at a time, each repeated over seeds:
//!
//! | grid            | runs (per scene, per seed)                                              | paper       |
//! |-----------------|-------------------------------------------------------------------------|-------------|
//! | `table2`        | baseline, DIA, SIA                                                      | Table 2     |
//! | `reduced`       | IA off / on × 10, 25, 50, 75 % of the training views                   | Table 4     |
//! | `degraded`      | IA off / on × the five degradations at their main strength              | Table 4     |
//! | `degraded-mild` | IA off / on × the five degradations at their milder strength            | appendix    |
//! | `pareto`        | one factor at a time around the preset, plus the presets                | —           |
//! | `smoke`         | baseline and SIA for a tenth of the preset's steps: a quick check       | —           |
//! | `hard`          | baseline; DIA/SIA on torus, double-torus: floor, genus, normals         | —           |
//!
//! "IA" is SIA unless `--ia dia` ([`grid::StudyOptions::ia`]): the paper's best NeuS geometry
//! figure is SIA's (its Table 2: 1.91 vs 2.03 for the baseline and for DIA) at the baseline's cost.
//!
//! # Layout of a study folder
//! ```text
//! study.toml           the plan: grid, options, every run with its configuration hashes
//! base.toml            a copy of --config FILE, when one was given (runs read this copy)
//! study.lock           held (flock) while a study process runs in the folder
//! study.log            one line per run started / finished / failed / skipped
//! records.jsonl        one line per finished run: its config.toml and metrics.json (`store`);
//!                      what a study commits, and all `study collect` needs beside study.toml
//! runs/<id>/           one `neus-aug reconstruct` output folder per run (config.toml, metrics.json, …)
//! report/              what `study collect` writes: report.md, runs.csv, runs.json, summary.json, PNGs
//! jobs.txt, slurm.sbatch, parallel.sh, logs/   with --emit-jobs
//! ```
//!
//! # Execution: in process, one run at a time
//! Each run is [`crate::reconstruct::run`] called in this process, one after another (every run
//! already uses all cores through rayon). In-process rather than spawning the binary because a
//! killed or interrupted study then stops its current run with it: no orphaned child keeps
//! writing into a run folder while a resumed study works on the same run, so "every run is done
//! once" holds by construction. The cluster path ([`jobs`]) runs the very same runs as separate
//! `neus-aug reconstruct` command lines; a test checks that such a line produces the run folder
//! (the same resolved configuration) that the study planned.
//!
//! # Never redo, never mix
//! A run whose folder holds `metrics.json` and a `config.toml` equal to the planned one is done
//! and skipped; a folder with a checkpoint but no `metrics.json` is resumed. A study folder
//! planned with other options, or a run folder whose `config.toml` is not the planned
//! configuration, is refused with the differing options or keys named ([`plan`]).
//!
//! # Statistics
//! Means and sample standard deviations over seeds; paired differences `arm − baseline`, paired
//! by (condition, scene, seed), with percentile bootstrap 95 % confidence intervals from a fixed
//! seed ([`stats`]). `study collect` reads only the stored plan and run folders, sorts everything
//! by the plan's order and formats floats with fixed precision, so its outputs regenerate bit for
//! bit.

pub mod confighash;
pub mod grid;
pub mod jobs;
pub mod plan;
pub mod plot;
pub mod report;
pub mod run;
pub mod stats;
pub mod store;

pub use grid::{Grid, StudyOptions};
pub use plan::{RunSpec, StudyPlan};
pub use report::{collect, collect_with, CollectOptions, CollectSummary, RunRecord, Subset};
pub use run::{execute, ExecOptions, ExecSummary};

use std::path::PathBuf;

/// Why a study cannot go on. Each variant names the folder, run, option or file at fault.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// `neus-aug study NAME` with a name that is not a grid.
    #[error("unknown grid '{name}'; known grids: {known} (and `collect DIR`)")]
    UnknownGrid { name: String, known: String },
    /// A study option is unusable.
    #[error("study option {option} = {value}: {why}")]
    Option {
        option: String,
        value: String,
        why: String,
    },
    /// The folder was planned with other options; nothing was run.
    #[error(
        "study folder {dir} holds a study planned with other options; nothing was run or \
         mixed. Differences (stored plan → this command):\n{differences}\nUse another --out, \
         or repeat the original options (see {dir}/study.toml)."
    )]
    PlanMismatch { dir: PathBuf, differences: String },
    /// A run folder holds results of another configuration.
    #[error(
        "run folder {path} does not hold the run this study planned: {problem}. It was made \
         with another configuration; move it away (or use another study folder) rather than \
         mixing results."
    )]
    RunMismatch { path: PathBuf, problem: String },
    /// Not a study folder, or a damaged one.
    #[error("study folder {dir}: {problem}")]
    Folder { dir: PathBuf, problem: String },
    /// Another study process works in the folder.
    #[error("study folder {dir} is in use by another `neus-aug study` process ({lock} is locked)")]
    Locked { dir: PathBuf, lock: PathBuf },
    /// A stored file could not be parsed.
    #[error("cannot parse {path}: {message}")]
    Parse { path: PathBuf, message: String },
    /// Reading or writing a file failed.
    #[error("cannot access {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Drawing a plot failed.
    #[error("cannot draw {path}: {message}")]
    Plot { path: PathBuf, message: String },
    /// A run configuration does not resolve.
    #[error(transparent)]
    Config(#[from] crate::reconstruct::ConfigError),
    /// Some runs failed; the others finished and the report was written.
    #[error("{failed} of {total} runs failed (see {log}): {first}")]
    RunsFailed {
        failed: usize,
        total: usize,
        log: PathBuf,
        first: String,
    },
}

pub(crate) fn io_err(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> StudyError + '_ {
    move |source| StudyError::Io {
        path: path.into(),
        source,
    }
}

/// Writes `bytes` to `path` with the workspace's one atomic writer
/// ([`dtu_eval::atomic::write_atomic`]), creating the parent folder first.
pub(crate) fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> Result<(), StudyError> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(io_err(parent))?;
    }
    dtu_eval::atomic::write_atomic(path, bytes).map_err(io_err(path))
}
