//! Running a study on this machine: one run at a time, in process, skipping finished runs and
//! resuming unfinished ones; a lock keeps two study processes out of one folder.

use super::plan::{open_folder, run_dir, RunState, StudyPlan};
use super::{io_err, StudyError};
use crate::reconstruct::{self, RunConfig, RunOptions};
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// File names.
pub const LOG_FILE: &str = "study.log";
pub const LOCK_FILE: &str = "study.lock";

/// How to run (nothing here changes results).
#[derive(Clone, Debug, Default)]
pub struct ExecOptions {
    /// No progress output from the runs (the study still prints one line per run).
    pub quiet: bool,
    /// Other studies whose records of the same configurations count as runs of this one
    /// ([`super::plan::import_records`]).
    pub reuse_records: Vec<std::path::PathBuf>,
    /// Other studies whose finished runs of the same training lend this study's runs their
    /// final checkpoint ([`lend_checkpoint`]), so a run that differs from them only in mesh,
    /// evaluation or export settings re-extracts instead of training again.
    pub reuse_training: Vec<std::path::PathBuf>,
    /// Run at most this many unfinished runs (in plan order), then write the report and stop:
    /// a slice of a long grid, so several grids can advance in turn.
    pub max_runs: Option<usize>,
}

/// What [`execute`] did.
#[derive(Clone, Debug, Default)]
pub struct ExecSummary {
    /// Runs finished by this call.
    pub ran: Vec<String>,
    /// Runs found finished and skipped.
    pub skipped: Vec<String>,
    /// Runs that failed, with the error.
    pub failed: Vec<(String, String)>,
}

/// An exclusive lock on `dir/study.lock`, released when dropped or when the process dies.
pub struct StudyLock {
    _file: std::fs::File,
}

impl StudyLock {
    /// Takes the lock or fails at once with [`StudyError::Locked`].
    pub fn acquire(dir: &Path) -> Result<Self, StudyError> {
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
        let path = dir.join(LOCK_FILE);
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(io_err(&path))?;
        match file.try_lock() {
            Ok(()) => Ok(Self { _file: file }),
            Err(std::fs::TryLockError::WouldBlock) => Err(StudyError::Locked {
                dir: dir.into(),
                lock: path,
            }),
            Err(std::fs::TryLockError::Error(e)) => Err(StudyError::Io { path, source: e }),
        }
    }
}

/// Appends one line to `study.log` (seconds since the Unix epoch, then the message).
fn log(dir: &Path, msg: &str) -> Result<(), StudyError> {
    let path = dir.join(LOG_FILE);
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .map_err(io_err(&path))?;
    writeln!(f, "{t} {msg}").map_err(io_err(&path))
}

/// Copies the final checkpoint of `src` into `dst` when `src` is finished and `dst` has none, so
/// `dst` (same training, other mesh settings) only re-extracts. Returns whether it copied.
fn reuse_checkpoint(dir: &Path, src: &str, dst: &str) -> Result<bool, StudyError> {
    copy_final_checkpoint(&run_dir(dir, src), &run_dir(dir, dst))
}

/// Copies `src/checkpoint.safetensors` into run folder `dst` (atomically) when the run in `src`
/// is finished (`metrics.json`) and `dst` has no checkpoint yet. Returns whether it copied.
fn copy_final_checkpoint(src: &Path, dst: &Path) -> Result<bool, StudyError> {
    let from = src.join("checkpoint.safetensors");
    let to = dst.join("checkpoint.safetensors");
    if !src.join("metrics.json").is_file() || !from.is_file() || to.exists() {
        return Ok(false);
    }
    std::fs::create_dir_all(dst).map_err(io_err(dst))?;
    let bytes = std::fs::read(&from).map_err(io_err(&from))?;
    dtu_eval::atomic::write_atomic(&to, &bytes).map_err(io_err(&to))?;
    Ok(true)
}

/// Copies into this study's run `id` (folder `dst`, with no checkpoint yet) the final checkpoint
/// of the run of the same id in the study folder `other`, when that run is finished and its
/// `config.toml` has the training hash of `cfg` ([`RunConfig::training_hash`]: the same scene,
/// seed, data, augmentation, model and optimisation). Returns whether it copied; a run of
/// other training is left alone (this run then trains).
fn lend_checkpoint(
    other: &Path,
    id: &str,
    cfg: &RunConfig,
    dst: &Path,
) -> Result<bool, StudyError> {
    let src = run_dir(other, id);
    let saved = src.join("config.toml");
    if !saved.is_file() || dst.join("checkpoint.safetensors").exists() {
        return Ok(false);
    }
    let text = std::fs::read_to_string(&saved).map_err(io_err(&saved))?;
    let Ok(theirs) = RunConfig::from_saved_toml(&text, &saved.display().to_string()) else {
        return Ok(false);
    };
    if theirs.training_hash() != cfg.training_hash() {
        return Ok(false);
    }
    copy_final_checkpoint(&src, dst)
}

/// Runs every unfinished run of `plan` in `dir` (see the module docs), then writes the report
/// (`dir/report/`). `cfgs` are the runs' resolved configurations (from
/// [`super::plan::make_plan`]); `base_src` the user's `--config` file, copied into a new folder.
/// Failed runs do not stop the others; they make the result [`StudyError::RunsFailed`] after
/// the report is written.
pub fn execute(
    dir: &Path,
    plan: &StudyPlan,
    cfgs: &[RunConfig],
    base_src: Option<&Path>,
    opts: &ExecOptions,
) -> Result<ExecSummary, StudyError> {
    let _lock = StudyLock::acquire(dir)?;
    let mut states = open_folder(dir, plan, cfgs, base_src)?;
    if !opts.reuse_records.is_empty() {
        let n = super::plan::import_records(dir, plan, &opts.reuse_records)?;
        if n > 0 {
            log(dir, &format!("reused {n} records of other studies"))?;
            states = open_folder(dir, plan, cfgs, base_src)?;
        }
    }
    let total = plan.runs.len();
    let todo = states.iter().filter(|s| **s != RunState::Done).count();
    eprintln!(
        "study {} in {}: {total} runs, {} finished, {todo} to run",
        plan.options.grid,
        dir.display(),
        total - todo
    );
    let mut summary = ExecSummary::default();
    let t_study = Instant::now();
    let mut done_now = 0usize;
    for (i, ((spec, cfg), state)) in plan.runs.iter().zip(cfgs).zip(&states).enumerate() {
        let tag = format!("[{}/{total}] {}", i + 1, spec.id);
        if *state == RunState::Done {
            summary.skipped.push(spec.id.clone());
            continue;
        }
        if opts
            .max_runs
            .is_some_and(|m| summary.ran.len() + summary.failed.len() >= m)
        {
            break;
        }
        if let Some(src) = &spec.reuse_training_of {
            if reuse_checkpoint(dir, src, &spec.id)? {
                log(dir, &format!("reuse {} checkpoint-of {src}", spec.id))?;
            }
        }
        let rd = run_dir(dir, &spec.id);
        if !rd.join("checkpoint.safetensors").is_file() {
            for other in &opts.reuse_training {
                if lend_checkpoint(other, &spec.id, cfg, &rd)? {
                    log(
                        dir,
                        &format!("reuse {} training-of {}", spec.id, other.display()),
                    )?;
                    break;
                }
            }
        }
        let resuming = rd.join("checkpoint.safetensors").is_file();
        log(
            dir,
            &format!(
                "start {}{}",
                spec.id,
                if resuming { " (resume)" } else { "" }
            ),
        )?;
        eprintln!(
            "{tag}: {}{}",
            if resuming { "resuming" } else { "starting" },
            eta(t_study.elapsed().as_secs_f64(), done_now, todo)
        );
        let t = Instant::now();
        let ro = RunOptions {
            resume: true,
            force: false,
            quiet: opts.quiet,
            stop_after: None,
        };
        let result =
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| reconstruct::run(cfg, &ro)));
        let secs = t.elapsed().as_secs_f64();
        match result {
            Ok(Ok(m)) => {
                let cs = m
                    .chamfer
                    .as_ref()
                    .map_or("no ground truth".to_string(), |c| {
                        format!("chamfer_sum {:.4} mm", c.chamfer_sum)
                    });
                log(dir, &format!("done {} {cs} {secs:.1}s", spec.id))?;
                super::plan::sync_records(dir, plan)?;
                eprintln!("{tag}: done in {secs:.0} s, {cs}");
                summary.ran.push(spec.id.clone());
                done_now += 1;
            }
            Ok(Err(e)) => {
                let msg = error_chain(&e);
                log(dir, &format!("failed {}: {msg}", spec.id))?;
                eprintln!("{tag}: FAILED: {msg}");
                summary.failed.push((spec.id.clone(), msg));
            }
            Err(panic) => {
                let msg = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_else(|| "panic".into());
                log(dir, &format!("failed {}: panic: {msg}", spec.id))?;
                eprintln!("{tag}: FAILED (panic): {msg}");
                summary
                    .failed
                    .push((spec.id.clone(), format!("panic: {msg}")));
            }
        }
    }
    let report = dir.join(super::report::REPORT_DIR);
    let c = super::report::collect(dir, &report)?;
    eprintln!(
        "study {}: {} ran, {} already finished, {} failed; report in {} ({} of {} runs collected)",
        plan.options.grid,
        summary.ran.len(),
        summary.skipped.len(),
        summary.failed.len(),
        report.display(),
        c.collected,
        c.planned
    );
    if let Some((id, msg)) = summary.failed.first() {
        return Err(StudyError::RunsFailed {
            failed: summary.failed.len(),
            total,
            log: dir.join(LOG_FILE),
            first: format!("{id}: {msg}"),
        });
    }
    Ok(summary)
}

fn eta(elapsed: f64, done: usize, todo: usize) -> String {
    if done == 0 {
        return String::new();
    }
    let left = elapsed / done as f64 * (todo - done) as f64;
    format!(" (about {:.0} min left)", left / 60.0)
}

/// The error and its causes on one line, each cause once ([`dtu_eval::error::error_chain`]).
fn error_chain(e: &dyn std::error::Error) -> String {
    dtu_eval::error::error_chain(e).replace('\n', " ")
}

/// Plans a study folder for job emission: the same checks as [`execute`] (a mismatching folder
/// is refused), then the job files.
pub fn emit_jobs(
    dir: &Path,
    plan: &StudyPlan,
    cfgs: &[RunConfig],
    base_src: Option<&Path>,
) -> Result<super::jobs::EmittedJobs, StudyError> {
    let _lock = StudyLock::acquire(dir)?;
    open_folder(dir, plan, cfgs, base_src)?;
    super::jobs::emit(dir, plan)
}
