//! The output folder of a run: its default name, and the checks that keep a user's files safe
//! (a folder that is not a neus-aug run is never written into; a finished run is redone only with
//! `--force`; an unfinished one is continued only with `--resume`).

use super::{io_err, ReconstructError, ResolvedScene, RunConfig, RunLock, RunOptions, LOCK_FILE};
use crate::train::checkpoint;
use std::path::{Path, PathBuf};

/// The output folder of a run.
pub fn output_dir(cfg: &RunConfig, scene: &ResolvedScene) -> PathBuf {
    cfg.out.clone().unwrap_or_else(|| {
        PathBuf::from("runs").join(format!(
            "{}-{}-{}-s{}",
            scene.name,
            cfg.augment.mode.name(),
            cfg.preset.name(),
            cfg.seed
        ))
    })
}

/// Whether `out` holds a neus-aug run: its lock file, or (runs written before the lock existed) a
/// `config.toml` that parses as a [`RunConfig`] beside `metrics.json` or a checkpoint, or a
/// neus-aug checkpoint (a study copies one into a new run folder to reuse its training).
pub(super) fn is_run_folder(out: &Path) -> bool {
    if out.join(LOCK_FILE).is_file() {
        return true;
    }
    let ckpt = out.join("checkpoint.safetensors");
    let config_ok = std::fs::read_to_string(out.join("config.toml"))
        .ok()
        .is_some_and(|t| RunConfig::from_saved_toml(&t, "config.toml").is_ok());
    (config_ok && (out.join("metrics.json").is_file() || ckpt.is_file()))
        || checkpoint::is_checkpoint(&ckpt)
}

/// Checks the output folder, touching nothing: not a file; not written by another process now
/// (unless this process holds the lock: `locked`); empty or a neus-aug run; not a finished run
/// (unless `force`); not an unfinished one with a checkpoint (unless `resume` or `force`).
pub(super) fn check_output(
    out: &Path,
    opts: &RunOptions,
    locked: bool,
) -> Result<(), ReconstructError> {
    let err = |problem: String| ReconstructError::Output {
        path: out.into(),
        problem,
    };
    match crate::util::inspect_output_dir(out) {
        Ok(crate::util::OutputDir::Absent) => return Ok(()),
        Ok(_) => {}
        // A dangling link, a file: named, with what to do.
        Err(e) => return Err(err(format!("{e}; choose another --out"))),
    }
    if !locked {
        RunLock::check_free(out)?;
    }
    let mut names: Vec<String> = std::fs::read_dir(out)
        .map_err(io_err(out))?
        .filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    if !names.is_empty() && !is_run_folder(out) {
        names.sort();
        let shown = names.iter().take(5).cloned().collect::<Vec<_>>().join(", ");
        let more = if names.len() > 5 { ", …" } else { "" };
        return Err(err(format!(
            "is not empty ({shown}{more}) and does not hold a neus-aug run; refusing to write \
             into it: choose a new or empty --out"
        )));
    }
    if out.join("metrics.json").is_file() && !opts.force {
        return Err(err(
            "already holds a finished run (metrics.json); use --force to redo it or another --out"
                .into(),
        ));
    }
    if out.join("checkpoint.safetensors").is_file() && !opts.resume && !opts.force {
        return Err(err(
            "holds the checkpoint of an unfinished run; use --resume to continue it or --force to start over"
                .into(),
        ));
    }
    Ok(())
}

/// Removes `path` if it exists (a missing file is fine; any other failure is an error).
pub(super) fn remove_if_present(path: &Path) -> Result<(), ReconstructError> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(io_err(path)(e)),
        _ => Ok(()),
    }
}
