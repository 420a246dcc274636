//! `neus-aug reconstruct`: from a scene to a scored mesh, in stages, each a function with typed
//! inputs and outputs, timed into `metrics.json`:
//!
//! 1. [`prepare`](prepare::prepare): resolve and load the scene, the training set (held-out
//!    views, views fraction, degradation, augmentation), the model and the start's shape;
//! 2. [`open the run folder`](folder::RunFolder::open): lock, resume, move a replaced run aside,
//!    write `config.toml`;
//! 3. [`train`](training::train), with the depth prior's automatic switch;
//! 4. [`extract`](extract::extract) the mesh (two-pass marching cubes);
//! 5. [`clean`](extract::clean_and_write) it and write it in world mm (through `scale_mat`);
//! 6. [`evaluate`](evaluate::evaluate) it with the DTU protocol when ground truth exists;
//! 7. [`render`](heldout::render_heldout) the held-out views (PSNR, SSIM, normals);
//! 8. [`write`](report::write_metrics) `metrics.json`, last.
//!
//! Output folder: `config.toml` (every key of the resolved configuration, written first),
//! `inputs.json` (a digest of what training reads), `checkpoint.safetensors`, `mesh.ply` (world
//! mm, binary, cleaned: `mesh::clean`, the part the training cameras see), `mesh_closed.ply`
//! (the closed cleaned surface, when the visibility rule cut its unseen side), `mesh_raw.ply`
//! (the marching-cubes mesh before clean-up, when that removed anything), `renders/`, and
//! `metrics.json`, written last: a folder without `metrics.json` holds an unfinished run,
//! never one that looks complete.
//!
//! A run folder is never lost or mixed up: `.neus-aug-run.lock` ([`lock`]) is held for the whole
//! run, so a second process writing into the same folder is refused naming the holder; a
//! non-empty folder that is not a neus-aug run is refused; the scene, masks, training set and
//! model are all loaded and validated, and a resumed checkpoint read and checked, before anything
//! in the folder is removed or written; and a finished run replaced with `--force` is kept aside
//! until its replacement has finished ([`folder`]). Every file is written atomically
//! ([`dtu_eval::atomic`]).

pub mod config;
mod evaluate;
mod extract;
pub mod folder;
mod heldout;
pub mod lock;
pub mod metrics;
pub mod normal_error;
mod output;
mod overrides;
mod prepare;
mod preset;
mod progress;
mod refined;
mod report;
mod scene_ref;
pub mod seen_floor;
mod training;
mod truth;

pub use config::{
    parse_set, resolve, resolve_resume, ConfigError, DataConfig, EvalConfig, Holdout, MeshConfig,
    Preset, RunConfig,
};
pub use extract::{clean_cut, marching_cubes_of, masked_views, trained_cameras};
pub use lock::{LockError, RunLock, LOCK_FILE};
pub use metrics::{
    ChamferMetrics, HullInitSummary, MeshSummary, Metrics, Timings, TrainSummary, ViewMetrics,
};
pub use output::output_dir;
pub use prepare::training_views;
pub use preset::scale_run_length;
pub use scene_ref::{resolve_scene, ResolvedScene, SceneKind};

use crate::augment::AugmentError;
use crate::mesh::McError;
use crate::render::model::ModelError;
use crate::scene::SceneError;
use crate::sim::SimError;
use crate::train::checkpoint::CheckpointError;
use crate::train::data::DataError;
use crate::train::hull::HullError;
use crate::train::TrainError;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Why a run failed. Every variant says what to do or names the file at fault.
#[derive(Debug, thiserror::Error)]
pub enum ReconstructError {
    /// The scene name resolves to nothing.
    #[error(
        "scene '{name}' not found. Looked for: the folder {name}; {root}/{name} and {root}/dtu_{name} \
         (real DTU in the NeuS layout; set --data-root or NEUS_AUG_DATA); a built-in synthetic scene \
         (known: {known}). Real DTU: download the NeuS-preprocessed DTU scans (data_DTU.zip from \
         Totoro97/NeuS) and unpack them under {root}/."
    )]
    SceneNotFound {
        name: String,
        root: String,
        known: String,
    },
    /// `--out` is unusable or holds another run.
    #[error("output folder {path}: {problem}")]
    Output { path: PathBuf, problem: String },
    /// Another process is writing the run folder.
    #[error(transparent)]
    Lock(#[from] LockError),
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Sim(#[from] SimError),
    #[error(transparent)]
    Augment(#[from] AugmentError),
    #[error(transparent)]
    Data(#[from] DataError),
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error(transparent)]
    Train(#[from] TrainError),
    #[error(transparent)]
    Hull(#[from] HullError),
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    #[error("mesh extraction failed: {0}")]
    Mesh(#[from] McError),
    #[error("evaluation failed: {0}")]
    Eval(#[from] dtu_eval::EvalError),
    #[error(transparent)]
    Ply(#[from] dtu_eval::ply::PlyError),
    #[error(transparent)]
    Image(#[from] crate::scene::ImageError),
    /// Training would see, or saw, nothing of the object.
    #[error("nothing to reconstruct: {0}")]
    NothingTrained(String),
    /// The run trained, but no surface is left to score.
    #[error("the mesh is empty: {0}")]
    EmptyMesh(String),
    #[error(transparent)]
    Export(#[from] crate::export::ExportError),
    #[error("cannot write {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> ReconstructError + '_ {
    move |source| ReconstructError::Io {
        path: path.into(),
        source,
    }
}

/// How to run (not part of the configuration: it does not change results).
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Continue from the output folder's checkpoint if there is one.
    pub resume: bool,
    /// Overwrite a finished run in the output folder.
    pub force: bool,
    /// No progress output.
    pub quiet: bool,
    /// Stop after this many completed steps (checkpoint written), as if killed: for tests of
    /// `--resume`.
    pub stop_after: Option<u64>,
}

/// Writes `text` to `path` with the workspace's one atomic writer
/// ([`dtu_eval::atomic::write_atomic`]).
fn write_atomic(path: &Path, text: &str) -> Result<(), ReconstructError> {
    dtu_eval::atomic::write_atomic(path, text.as_bytes()).map_err(io_err(path))
}

fn say(quiet: bool, msg: impl AsRef<str>) {
    if !quiet {
        eprintln!("{}", msg.as_ref());
    }
}

/// Runs the whole pipeline, stage by stage (module doc). `cfg` must come from [`resolve`]
/// (validated, appearance input set).
pub fn run(cfg: &RunConfig, opts: &RunOptions) -> Result<Metrics, ReconstructError> {
    let t_total = Instant::now();
    let prepared = prepare::prepare(cfg, opts)?;
    let mut folder = folder::RunFolder::open(cfg, &prepared, opts)?;
    match finish(cfg, &prepared, &mut folder, opts, t_total) {
        Ok(metrics) => {
            folder.commit()?;
            Ok(metrics)
        }
        Err(e) => Err(folder.roll_back(e)),
    }
}

/// Stages 3 to 8, in the open run folder.
fn finish(
    cfg: &RunConfig,
    p: &prepare::Prepared,
    folder: &mut folder::RunFolder,
    opts: &RunOptions,
    t_total: Instant,
) -> Result<Metrics, ReconstructError> {
    let quiet = opts.quiet;
    let trained = training::train(cfg, p, folder, opts)?;
    let t = Instant::now();
    let raw = extract::extract(cfg, p, &trained.state)?;
    let cameras = extract::trained_cameras(&p.scene, &p.train_idx, trained.state.pose.as_ref());
    let meshes = extract::clean_and_write(cfg, p, &cameras, raw, &folder.out, quiet, t)?;
    let mut ev = evaluate::evaluate(cfg, p, &meshes, &folder.out, quiet)?;
    let truth_mesh = ev.truth_mesh.take();
    let views = heldout::render_heldout(cfg, p, &trained.state, truth_mesh, &folder.out, quiet)?;
    // Stage 7b: normals and colours into mesh.ply, the turntable, the held-out sheet
    // (`crate::export`).
    let t = Instant::now();
    let sched = p.model.config.inference_schedule(cfg.train.iterations);
    let params = &trained.state.params;
    let (scene, ti, hv) = (&p.scene, &p.train_idx, &p.heldout);
    let out = &folder.out;
    crate::export::after_reconstruct(
        &cfg.export,
        &p.model,
        params,
        sched,
        scene,
        ti,
        &meshes.mesh,
        hv,
        out,
        quiet,
    )?;
    let export_secs = t.elapsed().as_secs_f64();
    report::write_metrics(
        cfg,
        p,
        folder,
        report::Stages {
            trained,
            meshes,
            ev,
            views,
            export_secs,
        },
        t_total,
        quiet,
    )
}
