//! Stage 2, *open the run folder*: lock it, look again (another process may have finished a run
//! there meanwhile), read a checkpoint to resume and check that the inputs are those the run
//! started with; only then move a replaced run aside and write `config.toml`.
//!
//! A finished run replaced with `--force` stays whole until its replacement is complete: its
//! files are moved (renamed, no copy, so a full disk cannot stop it) into
//! `<out>/.previous-run/` and moved back if the new run fails, or removed once it has written its
//! `metrics.json`. A process killed in between leaves `.previous-run/`, which the next run in the
//! folder moves back before anything else.

use super::lock::RunLock;
use super::output::{check_output, remove_if_present};
use super::prepare::Prepared;
use super::{io_err, say, write_atomic, ReconstructError, RunConfig, RunOptions};
use crate::train::checkpoint::{self, TrainState};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// What a run writes into its folder (besides the lock): everything a replaced run is made of.
pub const RUN_OUTPUTS: [&str; 11] = [
    "metrics.json",
    "mesh.ply",
    "mesh_raw.ply",
    "mesh_closed.ply",
    "renders",
    "eval_d2s.ply",
    "eval_s2d.ply",
    "depth_auto.json",
    "checkpoint.safetensors",
    "config.toml",
    INPUTS_FILE,
];

/// The outputs that a resumed run keeps in place: the training state it continues from.
const TRAINING_STATE: [&str; 4] = [
    "checkpoint.safetensors",
    "config.toml",
    "depth_auto.json",
    INPUTS_FILE,
];

/// Where a replaced run waits until its replacement has finished.
pub const PREVIOUS_DIR: &str = ".previous-run";

/// The digest of the inputs a run trains on (`inputs.json`).
pub const INPUTS_FILE: &str = "inputs.json";

/// `inputs.json`: what training read, so that a resumed run can tell it reads the same.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InputsRecord {
    /// The scene folder.
    pub scene: PathBuf,
    /// Training views (indices into the scene).
    pub train_views: Vec<usize>,
    /// FNV-1a 64 of the training cameras, images and masks as loaded.
    pub digest: String,
}

/// The open run folder: locked, with what the run resumes from.
pub(super) struct RunFolder {
    pub out: PathBuf,
    pub ckpt_path: PathBuf,
    /// The resolved configuration as written to `config.toml` (also stored in checkpoints).
    pub config_toml: String,
    /// The training hash checkpoints carry (the one of a resumed checkpoint, when it was written
    /// by an older build for this same configuration).
    pub hash: String,
    pub resumed: Option<TrainState>,
    replaced: Option<PathBuf>,
    _lock: RunLock,
}

impl RunFolder {
    /// Stage 2 (see the module doc).
    pub fn open(
        cfg: &RunConfig,
        p: &Prepared,
        opts: &RunOptions,
    ) -> Result<Self, ReconstructError> {
        let out = p.out.clone();
        std::fs::create_dir_all(&out).map_err(io_err(&out))?;
        let lock = RunLock::acquire(&out)?;
        if let Some(pid) = lock.previous {
            say(
                opts.quiet,
                format!(
                    "{}: taking over the lock of pid {pid}, which ended without releasing it",
                    out.display()
                ),
            );
        }
        if out.join(PREVIOUS_DIR).is_dir() {
            restore_previous(&out)?;
            eprintln!(
                "{}: a replacement run (--force) ended before it finished; the run it was \
                 replacing has been moved back",
                out.display()
            );
        }
        check_output(&out, opts, true)?;
        let ckpt_path = out.join("checkpoint.safetensors");
        let mut hash = cfg.training_hash();
        let resumed = if opts.resume && ckpt_path.is_file() {
            check_inputs(&out, p)?;
            if let Some(h) = legacy_hash(&ckpt_path, &hash) {
                hash = h;
            }
            let em = &cfg.train.error_map;
            let sizes = p.data.sizes();
            Some(checkpoint::load(
                &ckpt_path,
                &p.model.layout,
                &cfg.train.optimizer,
                &hash,
                em.enabled().then_some((em, &sizes[..])),
                cfg.train.pose_refine.enabled.then_some(sizes.len()),
            )?)
        } else {
            None
        };
        let replaced = if opts.force {
            let keep: &[&str] = if resumed.is_some() {
                &TRAINING_STATE
            } else {
                &[]
            };
            move_aside(&out, keep)?
        } else {
            None
        };
        let folder = Self {
            ckpt_path,
            config_toml: cfg.to_toml(),
            hash,
            resumed,
            replaced,
            _lock: lock,
            out,
        };
        folder.write_start(p)
    }

    /// `config.toml` and `inputs.json`, and no decision of an earlier check of the depth
    /// prior's switch when the run starts over.
    fn write_start(self, p: &Prepared) -> Result<Self, ReconstructError> {
        let config_path = self.out.join("config.toml");
        if std::fs::read_to_string(&config_path).ok().as_deref() != Some(&self.config_toml) {
            write_atomic(&config_path, &self.config_toml)?;
        }
        let inputs = InputsRecord {
            scene: p.scene_ref.dir.clone(),
            train_views: p.train_idx.clone(),
            digest: p.input_digest.clone(),
        };
        let text = serde_json::to_string_pretty(&inputs).expect("serialises");
        write_atomic(&self.out.join(INPUTS_FILE), &text)?;
        if self.resumed.is_none() {
            remove_if_present(&self.out.join("depth_auto.json"))?;
            remove_if_present(&self.ckpt_path)?;
        }
        Ok(self)
    }

    /// The run finished (`metrics.json` written): the replaced run goes.
    pub fn commit(self) -> Result<(), ReconstructError> {
        if let Some(dir) = &self.replaced {
            std::fs::remove_dir_all(dir).map_err(io_err(dir))?;
        }
        Ok(())
    }

    /// The run failed: what it wrote goes, and a replaced run comes back. Returns `e`, or the
    /// error of the restore when that failed too (it names the folder to look in).
    pub fn roll_back(self, e: ReconstructError) -> ReconstructError {
        if self.replaced.is_none() {
            return e;
        }
        match restore_previous(&self.out) {
            Ok(()) => {
                eprintln!(
                    "{}: the run failed; the run it was replacing is back in place",
                    self.out.display()
                );
                e
            }
            Err(r) => ReconstructError::Output {
                path: self.out.clone(),
                problem: format!(
                    "the run failed ({e}) and moving the replaced run back failed too ({r}); \
                     its files are in {}",
                    self.out.join(PREVIOUS_DIR).display()
                ),
            },
        }
    }
}

/// Moves the run outputs present in `out`, but those in `keep`, into `out/.previous-run/`.
/// `None` when there was nothing to move.
fn move_aside(out: &Path, keep: &[&str]) -> Result<Option<PathBuf>, ReconstructError> {
    let dir = out.join(PREVIOUS_DIR);
    let present: Vec<&str> = RUN_OUTPUTS
        .into_iter()
        .filter(|n| !keep.contains(n) && out.join(n).symlink_metadata().is_ok())
        .collect();
    if present.is_empty() {
        return Ok(None);
    }
    std::fs::create_dir(&dir).map_err(io_err(&dir))?;
    for n in present {
        let (from, to) = (out.join(n), dir.join(n));
        std::fs::rename(&from, &to).map_err(io_err(&from))?;
    }
    Ok(Some(dir))
}

/// Removes what a replacement wrote and moves the replaced run's files back from
/// `out/.previous-run/`.
fn restore_previous(out: &Path) -> Result<(), ReconstructError> {
    let dir = out.join(PREVIOUS_DIR);
    let names: Vec<_> = std::fs::read_dir(&dir)
        .map_err(io_err(&dir))?
        .filter_map(Result::ok)
        .map(|e| e.file_name())
        .collect();
    for n in RUN_OUTPUTS {
        let p = out.join(n);
        if p.symlink_metadata().is_err() {
            continue;
        }
        if p.is_dir() {
            std::fs::remove_dir_all(&p).map_err(io_err(&p))?;
        } else {
            std::fs::remove_file(&p).map_err(io_err(&p))?;
        }
    }
    for n in names {
        let (from, to) = (dir.join(&n), out.join(&n));
        std::fs::rename(&from, &to).map_err(io_err(&from))?;
    }
    std::fs::remove_dir(&dir).map_err(io_err(&dir))
}

/// Refuses to resume a run whose inputs changed since it started (`inputs.json`; a run folder
/// written before the record existed resumes as it did).
fn check_inputs(out: &Path, p: &Prepared) -> Result<(), ReconstructError> {
    let path = out.join(INPUTS_FILE);
    let Ok(text) = std::fs::read_to_string(&path) else {
        return Ok(());
    };
    let rec: InputsRecord = serde_json::from_str(&text).map_err(|e| ReconstructError::Output {
        path: path.clone(),
        problem: format!("cannot be read ({e}); move it away to resume without the check"),
    })?;
    if rec.train_views != p.train_idx || rec.digest != p.input_digest {
        return Err(ReconstructError::Output {
            path: out.into(),
            problem: format!(
                "the run started on other inputs than {} holds now (training views {:?} with \
                 digest {}, now {:?} with digest {}): its images, masks or cameras changed. \
                 Resuming would mix two data sets; use --force to start over",
                p.scene_ref.dir.display(),
                rec.train_views,
                rec.digest,
                p.train_idx,
                p.input_digest
            ),
        });
    }
    Ok(())
}

/// The hash a checkpoint written by an older build carries for this same configuration: its
/// stored configuration, read whatever schema wrote it, has the training hash `current`.
/// `None` when the checkpoint carries `current` already, or another configuration (the
/// checkpoint's own check then refuses it, naming both hashes).
fn legacy_hash(ckpt: &Path, current: &str) -> Option<String> {
    let meta = checkpoint::metadata(ckpt)?;
    let stored = meta.get("config_hash")?;
    if stored == current {
        return None;
    }
    let cfg = RunConfig::from_saved_toml(meta.get("config")?, "checkpoint").ok()?;
    (cfg.training_hash() == current).then(|| stored.clone())
}
