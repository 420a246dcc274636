//! `neus-aug reconstruct`: from a scene to a scored mesh.
//!
//! Phases, each timed into `metrics.json`: resolve and load the scene → prepare the training set
//! (held-out views, views fraction, degradation, augmentation) → train (with progress and
//! atomic checkpoints) → extract the mesh (two-pass marching cubes, mapped back to world mm
//! through `scale_mat`) → score it with the DTU protocol when ground truth exists → render the
//! held-out views (PSNR, SSIM).
//!
//! Output folder: `config.toml` (resolved configuration, written first), `checkpoint.safetensors`,
//! `mesh.ply` (world mm, binary, cleaned: `mesh::clean`, the part the training cameras see),
//! `mesh_closed.ply` (the closed cleaned surface, when the visibility rule cut its unseen side),
//! `mesh_raw.ply` (the marching-cubes mesh before clean-up, when that removed anything),
//! `renders/`, and `metrics.json`, written last: a folder without
//! `metrics.json` holds an unfinished run, never one that looks complete.
//!
//! A run folder is never lost or mixed up: `.neus-aug-run.lock` ([`lock`]) is held for the whole
//! run, so a second process writing into the same folder is refused naming the holder; a
//! non-empty folder that is not a neus-aug run is refused; and the scene, masks, training set and
//! model are all loaded and validated, and a resumed checkpoint read and checked, before anything
//! in the folder is removed or written (so a refused `--force` or `--resume` changes nothing).
//! Every file is written atomically ([`dtu_eval::atomic`]).

pub mod config;
pub mod lock;
pub mod metrics;
pub mod normal_error;
mod output;
mod overrides;
mod preset;
pub mod seen_floor;
mod truth;

pub use config::{
    parse_set, resolve, resolve_resume, ConfigError, DataConfig, EvalConfig, Holdout, MeshConfig,
    Preset, RunConfig,
};
pub use lock::{LockError, RunLock, LOCK_FILE};
pub use metrics::{
    ChamferMetrics, HullInitSummary, MeshSummary, Metrics, Timings, TrainSummary, ViewMetrics,
};
pub use output::output_dir;
use output::{check_output, remove_if_present};
pub use preset::scale_run_length;
use truth::{find_gt, own_truth, GeometryVsTruth};

use crate::augment::{degrade_views, views_fraction, AugSampler, AugmentError};
use crate::mesh::clean::{clean_mesh, cull_unseen_parts, CleanOptions};
use crate::mesh::{extract_two_pass, to_world, McError, McOptions, TopologyReport, TwoPassOptions};
use crate::render::model::{ModelError, NeusModel, RayBatch};
use crate::scene::{dtu, GrayImage, LoadOptions, RgbImage, Scene, SceneError};
use crate::sim::{self, SimError};
use crate::train::checkpoint::{self, CheckpointError, TrainState};
use crate::train::data::{camera_rays, DataError};
use crate::train::depth::{self as depth_prior, DepthConfig, DepthMapsSummary, DepthPrior};
use crate::train::depth_auto::{self, AutoCheck};
use crate::train::hull::{self, HullError, HullSdf, InitKind};
use crate::train::metrics::{psnr, ssim};
use crate::train::multiview::MultiViewPrior;
use crate::train::photo_hull::{self, PhotoCarveParams};
use crate::train::unseen::UnseenPrior;
use crate::train::{TrainData, TrainError, Trainer};
use serde::Serialize;
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

/// Where a scene came from.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SceneKind {
    /// A folder given by path.
    #[default]
    Folder,
    /// A DTU scan under the data root.
    Dtu,
    /// A built-in synthetic scene (generated into the cache).
    Builtin,
}

/// A resolved scene: its folder and a short name for output folders.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct ResolvedScene {
    pub dir: PathBuf,
    pub name: String,
    pub kind: SceneKind,
}

/// Resolves a scene name as ../shared/DESIGN.md §2 orders it: a folder; `<data_root>/<name>` or
/// `<data_root>/dtu_<name>`; a built-in synthetic scene (generated once into the cache). An
/// empty name is the embedded default scene.
///
/// A folder in the working directory that holds no scene (no `cameras_sphere.npz`) does not
/// shadow a DTU scan or a built-in scene of the same bare name: `neus-aug reconstruct cup` run
/// beside a folder `cup/` of the user's own files trains the built-in `cup`, with a warning
/// that names the folder. A name written as a path (`./cup`, `runs/cup`, `/data/cup`) is
/// always the folder.
pub fn resolve_scene(
    spec: &str,
    data_root: &Path,
    quiet: bool,
) -> Result<ResolvedScene, ReconstructError> {
    let name = if spec.is_empty() { "default" } else { spec };
    let as_path = Path::new(name);
    let short = |p: &Path| {
        p.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| name.to_string())
    };
    if as_path.is_dir() {
        match shadowed_by_folder(as_path, name, data_root) {
            None => {
                return Ok(ResolvedScene {
                    dir: as_path.into(),
                    name: short(as_path),
                    kind: SceneKind::Folder,
                })
            }
            Some(what) => eprintln!(
                "warning: the folder {name} holds no {}, so '{name}' is taken as {what}; \
                 write ./{name} to load the folder",
                dtu::CAMERA_FILE
            ),
        }
    }
    if let Some(dir) = dtu_scan_dir(data_root, name) {
        return Ok(ResolvedScene {
            name: short(&dir),
            dir,
            kind: SceneKind::Dtu,
        });
    }
    match sim::builtin(name) {
        Ok(_) => {
            let root = sim::default_cache_root()?;
            if !quiet {
                eprintln!(
                    "scene '{name}': built-in synthetic scene (cache {})",
                    root.display()
                );
            }
            let dir = sim::ensure_builtin(name, &root)?;
            Ok(ResolvedScene {
                dir,
                name: name.to_string(),
                kind: SceneKind::Builtin,
            })
        }
        Err(SimError::UnknownScene { known, .. }) => Err(ReconstructError::SceneNotFound {
            name: name.into(),
            root: data_root.display().to_string(),
            known,
        }),
        Err(e) => Err(e.into()),
    }
}

/// What a bare scene `name` resolves to instead of the folder `dir` it names (`dir` is `name`
/// read from the working directory), when that folder holds no scene (no
/// `cameras_sphere.npz`) and the name is not written as a path. A path is absolute, has a
/// separator inside or at the end, or is `.` or `..`. `Some` names the scan under the data
/// root or the built-in scene that takes precedence (see [`resolve_scene`]); `None` keeps the
/// folder: a scene, a path, or a name of nothing else (the loader then says what it lacks).
fn shadowed_by_folder(dir: &Path, name: &str, data_root: &Path) -> Option<String> {
    let typed = Path::new(name);
    let mut parts = typed.components();
    let bare = matches!(
        (parts.next(), parts.next()),
        (Some(std::path::Component::Normal(_)), None)
    );
    let written_as_path = !bare || name.ends_with('/') || name.ends_with(std::path::MAIN_SEPARATOR);
    if written_as_path || dir.join(dtu::CAMERA_FILE).is_file() {
        return None;
    }
    if let Some(c) = dtu_scan_dir(data_root, name) {
        return Some(format!("the scan {}", c.display()));
    }
    sim::builtin(name)
        .ok()
        .map(|_| format!("the built-in synthetic scene '{name}'"))
}

/// The DTU scan folder `name` names under `data_root`: `<data_root>/<name>`, else
/// `<data_root>/dtu_<name>` (DESIGN.md §2), when it is a folder.
fn dtu_scan_dir(data_root: &Path, name: &str) -> Option<PathBuf> {
    [data_root.join(name), data_root.join(format!("dtu_{name}"))]
        .into_iter()
        .find(|c| c.is_dir())
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

/// A progress display: an indicatif bar on a terminal, a line every ~5 % otherwise.
struct Progress {
    bar: Option<indicatif::ProgressBar>,
    total: u64,
    quiet: bool,
    start: Instant,
    last_line: u64,
}

impl Progress {
    fn new(total: u64, start_step: u64, quiet: bool) -> Self {
        use std::io::IsTerminal;
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let b = indicatif::ProgressBar::new(total);
            b.set_style(
                indicatif::ProgressStyle::with_template(
                    "{elapsed_precise} [{bar:28}] {pos}/{len} {msg} eta {eta}",
                )
                .expect("valid template")
                .progress_chars("=> "),
            );
            b.set_position(start_step);
            b
        });
        Self {
            bar,
            total,
            quiet,
            start: Instant::now(),
            last_line: start_step,
        }
    }

    fn update(&mut self, step: u64, msg: String) {
        if let Some(b) = &self.bar {
            b.set_position(step);
            b.set_message(msg);
        } else if !self.quiet
            && (step - self.last_line >= (self.total / 20).max(1) || step == self.total)
        {
            self.last_line = step;
            eprintln!(
                "step {step}/{} {msg} ({:.0} s)",
                self.total,
                self.start.elapsed().as_secs_f64()
            );
        }
    }

    fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

/// The stereo of the depth prior `depth` over the training views, and the prior on it
/// (`train::depth`), with what the stereo found said and summarised.
fn stereo_prior(
    depth: &DepthConfig,
    cameras: &[crate::scene::Camera],
    data: &TrainData,
    quiet: bool,
) -> (DepthPrior, DepthMapsSummary) {
    let t_mvs = Instant::now();
    say(
        quiet,
        format!(
            "depth prior: plane-sweep stereo of {} views ({} planes)",
            cameras.len(),
            depth.mvs.planes
        ),
    );
    let maps = depth_prior::depth_maps(&depth.mvs, cameras, data.views(), data.masks());
    let summary = maps.summary(t_mvs.elapsed().as_secs_f64());
    say(
        quiet,
        format!(
            "depth prior: depth on {} of {} pixels ({:.1} %; {} by the fusion fill, {} by the hole fill) in {:.1} s",
            summary.with_depth,
            summary.considered,
            100.0 * summary.with_depth as f64 / summary.considered.max(1) as f64,
            summary.filled,
            summary.hole_filled,
            summary.seconds
        ),
    );
    if summary.with_depth == 0 {
        say(
            false,
            "warning: the depth prior found no depth (no texture, or no view overlap): it does nothing",
        );
    }
    (
        DepthPrior::new(depth.clone(), cameras.to_vec(), maps),
        summary,
    )
}

/// The automatic switch's check on the field of `state` (`train::depth_auto`): sweeps its
/// views, marches their rays through the field, decides, says so and writes the decision to
/// `path` (`depth_auto.json`).
fn run_auto_check(
    cfg: &RunConfig,
    model: &NeusModel,
    state: &TrainState,
    cameras: &[crate::scene::Camera],
    data: &TrainData,
    path: &Path,
    quiet: bool,
) -> Result<AutoCheck, ReconstructError> {
    let a = &cfg.train.depth.auto;
    let t0 = Instant::now();
    let views = depth_auto::check_views(cameras.len(), a.views);
    let maps = depth_prior::sweep_depths(
        &cfg.train.depth.mvs,
        cameras,
        data.views(),
        data.masks(),
        &views,
    );
    let cams: Vec<&crate::scene::Camera> = views.iter().map(|&i| &cameras[i]).collect();
    let active = model.config.schedule(state.step).active_levels;
    let sdf = |p: &[[f32; 3]]| model.sdf(&state.params, p, active);
    let (rays, in_front) = depth_auto::solid_in_front(
        &sdf,
        &cams,
        &maps,
        model.config.render.radius as f64,
        a.margin as f64,
        a.step as f64,
    );
    let share = if rays > 0 {
        in_front as f64 / rays as f64
    } else {
        0.0
    };
    let triggered = rays >= a.min_rays && share >= a.share as f64;
    let check = AutoCheck {
        step: state.step,
        views,
        rays,
        in_front,
        share,
        margin: a.margin,
        threshold: a.share,
        triggered,
        seconds: t0.elapsed().as_secs_f64(),
    };
    let verdict = if triggered {
        "the field has closed space the stereo sees through (a cavity's lid): depth prior on"
            .to_string()
    } else if rays < a.min_rays {
        format!(
            "fewer than {} rays with a stereo depth: depth prior stays off",
            a.min_rays
        )
    } else {
        "depth prior stays off".to_string()
    };
    say(
        quiet,
        format!(
            "depth prior, automatic switch at step {}: {} of {} rays ({:.1} %, threshold {:.1} %) \
             have solid more than {} (normalised units) in front of their stereo depth, {:.1} s; \
             {verdict}",
            check.step,
            in_front,
            rays,
            100.0 * share,
            100.0 * a.share,
            a.margin,
            check.seconds
        ),
    );
    let text = serde_json::to_string_pretty(&check).expect("the check serialises");
    write_atomic(path, &text)?;
    Ok(check)
}

fn say(quiet: bool, msg: impl AsRef<str>) {
    if !quiet {
        eprintln!("{}", msg.as_ref());
    }
}

/// Runs the whole pipeline. `cfg` must come from [`resolve`] (validated, appearance input set).
pub fn run(cfg: &RunConfig, opts: &RunOptions) -> Result<Metrics, ReconstructError> {
    let t_total = Instant::now();
    let mut timings = Timings::default();
    let quiet = opts.quiet;

    // Scene, and a first look at the output folder (nothing is touched until everything the
    // run needs has loaded and validated).
    let t = Instant::now();
    let scene_ref = resolve_scene(&cfg.scene, &cfg.data_root, quiet)?;
    let out = output_dir(cfg, &scene_ref);
    check_output(&out, opts, false)?;
    let scene = Scene::load(
        &scene_ref.dir,
        &LoadOptions {
            downscale: cfg.data.downscale,
            masks: cfg.data.masks,
        },
    )?;
    timings.load = t.elapsed().as_secs_f64();
    say(
        quiet,
        format!(
            "loaded {} views of {} ({}×{}) in {:.1} s → {}",
            scene.views.len(),
            scene_ref.dir.display(),
            scene.views[0].image.width,
            scene.views[0].image.height,
            timings.load,
            out.display()
        ),
    );

    // Training set.
    let t = Instant::now();
    let n = scene.views.len();
    let heldout = cfg.data.holdout.indices(n)?;
    let candidates: Vec<usize> = (0..n).filter(|i| !heldout.contains(i)).collect();
    let keep = views_fraction(candidates.len(), cfg.data.views_fraction, cfg.seed)?;
    let train_idx: Vec<usize> = keep.iter().map(|&k| candidates[k]).collect();
    let mut images: Vec<RgbImage> = train_idx
        .iter()
        .map(|&i| scene.views[i].image.clone())
        .collect();
    if let Some(d) = &cfg.data.degrade {
        degrade_views(&mut images, d, cfg.seed);
    }
    let masks: Option<Vec<GrayImage>> = train_idx
        .iter()
        .map(|&i| scene.views[i].mask.clone())
        .collect();
    let cameras: Vec<_> = train_idx
        .iter()
        .map(|&i| scene.views[i].camera.clone())
        .collect();
    let sampler = AugSampler::new(images, &cfg.augment)?;
    let data = TrainData::new(&cameras, sampler, masks, cfg.model.render.background)?;
    let model = NeusModel::new(cfg.model.clone())?;

    // The training views that have a mask, with their cameras: the visual-hull start carves
    // them, the mesh clean-up culls with them.
    let masked_views: Vec<(&crate::scene::Camera, &GrayImage)> = train_idx
        .iter()
        .filter_map(|&i| {
            let v = &scene.views[i];
            v.mask.as_ref().map(|m| (&v.camera, m))
        })
        .collect();

    // The visual-hull target, before anything is written: a hull the masks carve away entirely
    // is an input error, and `--force` must not have removed the old outputs for it.
    let all_masked = cfg.data.masks && masked_views.len() == train_idx.len();
    let kind = cfg.train.init.kind;
    if kind == InitKind::VisualHull && !all_masked {
        return Err(HullError::NoMasks("some training views have no mask").into());
    }
    let unseen = cfg.train.unseen.enabled();
    if unseen && !all_masked {
        return Err(HullError::NoMasks(
            "the unseen-space prior (train.unseen) needs one on every training view",
        )
        .into());
    }
    // The masks' visual hull, when the init (or its choice) or the prior needs it: the prior
    // reads it as it is, the init fits its (optionally blurred) copy.
    let wants_hull = all_masked && kind != InitKind::Sphere;
    let (ic, r) = (&cfg.train.init, model.config.render.radius);
    let visual = (wants_hull || unseen).then(|| hull::carve(&masked_views, r, ic.resolution));
    let cover_of = |g: &[bool]| {
        let sr = model.config.field.sdf.sphere_init_radius;
        hull::sphere_cover(g, ic.resolution, r, sr)
    };
    // `sphere_or_hull` takes the masks' hull as it is when it already carves most of the sphere.
    let visual_cover = match (&visual, kind) {
        (Some(v), InitKind::SphereOrHull) => Some(cover_of(v)),
        _ => None,
    };
    let masks_decide = visual_cover.is_some_and(|c| c < ic.sphere_cover_min);
    // Otherwise the photo-consistent carve of that hull (`train::photo_hull`), when asked, for
    // the start only (the unseen-space prior keeps the masks' hull): under `sphere_or_hull` the
    // carved hull is the start when it empties most of the sphere (a concavity the masks
    // cannot see, as a cup's inside). It reads the training images as training sees them
    // (degraded, if asked), before any augmentation.
    let mut photo_carve = None;
    let inside =
        match &visual {
            Some(v) if wants_hull && ic.photo_tau > 0.0 && !masks_decide => {
                let mut g = v.clone();
                let views: Vec<_> = train_idx
                    .iter()
                    .zip(data.views())
                    .map(|(&i, img)| {
                        let view = &scene.views[i];
                        (&view.camera, img, view.mask.as_ref())
                    })
                    .collect();
                let params = PhotoCarveParams {
                    tau: ic.photo_tau,
                    min_views: ic.photo_min_views,
                    max_iterations: ic.photo_max_iterations,
                };
                let rep = photo_hull::photo_carve(&views, &mut g, ic.resolution, r, &params);
                let empty = rep.inside_after == 0;
                say(
                    quiet,
                    format!(
                    "init: the photo-consistency carve removed {:.1} % of the visual hull in {} \
                     passes ({}, {:.1} s){}",
                    100.0 * rep.carved_share(),
                    rep.iterations,
                    if rep.converged { "converged" } else { "pass cap reached" },
                    rep.seconds,
                    if empty {
                        ": nothing left, so the masks' hull is used as it is"
                    } else {
                        ""
                    }
                ),
                );
                photo_carve = Some(rep);
                if empty {
                    visual.clone()
                } else {
                    Some(g)
                }
            }
            _ => visual.clone(),
        };
    let sphere_cover = match (&inside, kind) {
        // The masks' hull's cover is known; only a carved hull needs a new one.
        (Some(inside), InitKind::SphereOrHull) if photo_carve.is_some() => Some(cover_of(inside)),
        _ if kind == InitKind::SphereOrHull => visual_cover,
        _ => None,
    };
    let init_hull = match kind {
        InitKind::Sphere => false,
        InitKind::Auto | InitKind::VisualHull => all_masked,
        InitKind::SphereOrHull => sphere_cover.is_some_and(|c| c < ic.sphere_cover_min),
    };
    if let Some(c) = sphere_cover {
        say(
            quiet,
            format!(
                "init: the {} covers {:.1} % of the init sphere (threshold {:.1} %): {} start",
                if photo_carve.is_some() {
                    "carved hull"
                } else {
                    "visual hull"
                },
                100.0 * c,
                100.0 * ic.sphere_cover_min,
                if init_hull { "hull" } else { "sphere" }
            ),
        );
    }
    // The start is the carved hull only when the carve left something; otherwise it is the
    // masks' hull, whose distance transform the unseen-space prior shares (computed once).
    let carved = photo_carve.as_ref().is_some_and(|rep| rep.inside_after > 0);
    let visual_sdf = match &visual {
        Some(g) if unseen || (init_hull && !carved) => {
            Some(HullSdf::from_occupancy(g, ic.resolution, r)?)
        }
        _ => None,
    };
    let hull_target = match (&inside, &visual_sdf) {
        (Some(g), _) if init_hull && carved => {
            Some(HullSdf::from_occupancy(g, ic.resolution, r)?.smoothed(ic.smooth_voxels))
        }
        (_, Some(h)) if init_hull => Some(h.smoothed(ic.smooth_voxels)),
        _ => None,
    };
    let unseen_hull = visual_sdf.filter(|_| unseen);
    timings.prepare = t.elapsed().as_secs_f64();

    // The output folder: lock it, look again (another process may have finished a run there
    // meanwhile), read a checkpoint to resume; only then remove old outputs and write.
    std::fs::create_dir_all(&out).map_err(io_err(&out))?;
    let lock = RunLock::acquire(&out)?;
    if let Some(pid) = lock.previous {
        say(
            quiet,
            format!(
                "{}: taking over the lock of pid {pid}, which ended without releasing it",
                out.display()
            ),
        );
    }
    check_output(&out, opts, true)?;
    let hash = cfg.training_hash();
    let ckpt_path = out.join("checkpoint.safetensors");
    let train_sizes = data.sizes();
    let resumed: Option<TrainState> = if opts.resume && ckpt_path.is_file() {
        Some(checkpoint::load(
            &ckpt_path,
            &model.layout,
            &cfg.train.optimizer,
            &hash,
            cfg.train
                .error_map
                .enabled()
                .then(|| (&cfg.train.error_map, &train_sizes[..])),
        )?)
    } else {
        None
    };
    if opts.force {
        for f in [
            "metrics.json",
            "mesh.ply",
            "mesh_raw.ply",
            "mesh_closed.ply",
        ] {
            remove_if_present(&out.join(f))?;
        }
        if resumed.is_none() {
            remove_if_present(&ckpt_path)?;
        }
    }
    let config_path = out.join("config.toml");
    let config_toml = cfg.to_toml();
    if std::fs::read_to_string(&config_path).ok().as_deref() != Some(config_toml.as_str()) {
        write_atomic(&config_path, &config_toml)?;
    }

    // Training.
    let t = Instant::now();
    let mut trainer = Trainer::new(
        &model,
        &data,
        &cfg.train,
        cfg.seed,
        cfg.augment.seed ^ cfg.seed,
    );
    if let Some(h) = unseen_hull {
        trainer = trainer.with_unseen_prior(UnseenPrior::new(
            cfg.train.unseen.clone(),
            h,
            cameras.clone(),
        ));
    }
    if cfg.train.multiview.enabled() {
        trainer = trainer.with_multiview_prior(MultiViewPrior::new(
            cfg.train.multiview.clone(),
            &cameras,
            data.views(),
        ));
    }
    let mut depth_maps = None;
    if cfg.train.depth.enabled() {
        let (prior, summary) = stereo_prior(&cfg.train.depth, &cameras, &data, quiet);
        depth_maps = Some(summary);
        trainer = trainer.with_depth_prior(prior);
    }
    // The depth prior's automatic switch (`train::depth_auto`): with the prior off and a mask on
    // every training view, a check after step `auto_step` may turn it on. Its decision goes to
    // `depth_auto.json`, which a resumed run past that step reads instead of checking again.
    let auto_cfg = &cfg.train.depth.auto;
    let auto_step = auto_cfg
        .check_step(cfg.train.iterations)
        .unwrap_or(u64::MAX);
    let auto_on = auto_cfg.enabled
        && !cfg.train.depth.enabled()
        && all_masked
        && auto_step < cfg.train.iterations;
    let auto_path = out.join("depth_auto.json");
    if resumed.is_none() {
        remove_if_present(&auto_path)?;
    }
    let mut depth_auto: Option<AutoCheck> = None;
    // The prior as the switch turns it on, attached to the trainer; its stereo's summary.
    let switch_on = |trainer: &mut Trainer| {
        let on = cfg.train.depth.switched_on(auto_step);
        let (prior, summary) = stereo_prior(&on, &cameras, &data, quiet);
        trainer.set_depth_prior(prior);
        summary
    };
    let mut hull_init = None;
    let mut state: TrainState = match resumed {
        Some(s) => {
            say(quiet, format!("resuming from step {}", s.step));
            s
        }
        None => {
            let mut s = trainer.initial_state();
            if let Some(sdf) = &hull_target {
                let t_hull = Instant::now();
                let ic = &cfg.train.init;
                let active = model.config.schedule(0).active_levels;
                let rep = hull::fit(&model, &mut s.params, sdf, ic, active, cfg.seed)?;
                let mm = scene.normalization.scale;
                let h = HullInitSummary {
                    resolution: ic.resolution,
                    inside_share: rep.inside_share,
                    fit_error_first_mm: rep.l1_first * mm,
                    fit_error_last_mm: rep.l1_last * mm,
                    seconds: t_hull.elapsed().as_secs_f64(),
                };
                say(
                    quiet,
                    format!(
                        "visual hull: {:.1} % of the {}³ grid inside; SDF fit {} steps, mean \
                         |error| {:.2} → {:.2} mm, {:.1} s",
                        100.0 * h.inside_share,
                        h.resolution,
                        ic.steps,
                        h.fit_error_first_mm,
                        h.fit_error_last_mm,
                        h.seconds
                    ),
                );
                hull_init = Some(h);
            }
            s
        }
    };
    let resumed_from = (state.step > 0).then_some(state.step);
    let iters = cfg.train.iterations;
    if auto_on && state.step >= auto_step {
        let recorded = std::fs::read_to_string(&auto_path)
            .ok()
            .and_then(|t| serde_json::from_str::<AutoCheck>(&t).ok());
        let check = match recorded {
            Some(c) => Some(c),
            None if state.step < iters => {
                say(
                    quiet,
                    format!(
                        "depth prior, automatic switch: no record of the check at step {auto_step} \
                         ({} missing or unreadable); checking the resumed field at step {}",
                        auto_path.display(),
                        state.step
                    ),
                );
                Some(run_auto_check(
                    cfg, &model, &state, &cameras, &data, &auto_path, quiet,
                )?)
            }
            // Nothing left to train: nothing to decide.
            None => None,
        };
        if check.as_ref().is_some_and(|c| c.triggered) && state.step < iters {
            depth_maps = Some(switch_on(&mut trainer));
        }
        depth_auto = check;
    }
    let mut progress = Progress::new(iters, state.step, quiet);
    let (mut rays, mut samples) = (0u64, 0u64);
    let mut last = None;
    let t_loop = Instant::now();
    while state.step < iters {
        let report = trainer.step(&mut state)?;
        if auto_on && state.step == auto_step && depth_auto.is_none() {
            let check = run_auto_check(cfg, &model, &state, &cameras, &data, &auto_path, quiet)?;
            if check.triggered && state.step < iters {
                depth_maps = Some(switch_on(&mut trainer));
            }
            depth_auto = Some(check);
        }
        rays += report.rays as u64;
        samples += report.out.n_samples as u64;
        if let Some(why) = &report.skipped {
            say(quiet, format!("step {}: {why}", report.step));
        }
        let secs = t_loop.elapsed().as_secs_f64().max(1e-9);
        let unseen_note = report.unseen.map_or(String::new(), |u| {
            format!(
                " unseen {:.1} % of cells, {}/{} points outside",
                100.0 * u.unseen_share,
                u.positive,
                u.used
            )
        });
        let mv_note = report.multiview.map_or(String::new(), |m| {
            let carve = if m.carve.swept > 0 {
                format!(
                    ", carved {}/{} rays by {:.4}",
                    m.carve.carved, m.carve.swept, m.carve.mean_depth
                )
            } else {
                String::new()
            };
            format!(
                " patch cost {:.3} on {}/{} rays{carve}",
                m.mean_cost, m.used, m.rays
            )
        });
        let depth_note = report.depth.map_or(String::new(), |d| {
            format!(
                " depth on {}/{} rays, carved {}",
                d.with_depth, d.rays, d.carved
            )
        });
        progress.update(
            state.step,
            format!(
                "loss {:.4} psnr {:.2} inv_s {:.0} rays/s {:.0}{unseen_note}{mv_note}{depth_note}",
                report.out.total,
                -10.0 * report.out.mse_all.max(1e-12).log10(),
                report.out.inv_s,
                rays as f64 / secs
            ),
        );
        last = Some(report);
        let every = cfg.train.checkpoint_every;
        let stop = opts.stop_after.is_some_and(|s| state.step >= s);
        if state.step == iters || stop || (every > 0 && state.step.is_multiple_of(every)) {
            checkpoint::save(&ckpt_path, &state, &model.layout, &config_toml, &hash)?;
        }
        if stop {
            progress.finish();
            return Err(ReconstructError::Output {
                path: out,
                problem: format!("stopped after step {} as asked (--stop-after)", state.step),
            });
        }
    }
    progress.finish();
    timings.train = t.elapsed().as_secs_f64();
    let train_secs = t_loop.elapsed().as_secs_f64();
    let train_summary = TrainSummary {
        iterations: iters,
        resumed_from,
        final_loss: last.as_ref().map_or(f64::NAN, |r| r.out.total),
        final_train_psnr: last
            .as_ref()
            .map_or(f64::NAN, |r| -10.0 * r.out.mse_all.max(1e-12).log10()),
        final_inv_s: model.inv_s(&state.params) as f64,
        skipped_steps: state.skipped_steps,
        rays,
        samples,
        samples_per_second: samples as f64 / train_secs.max(1e-9),
        train_views: train_idx.len(),
        heldout_views: heldout.clone(),
        hull_init,
        sphere_cover,
        photo_carve,
        unseen_last: last.as_ref().and_then(|r| r.unseen),
        multiview_last: last.as_ref().and_then(|r| r.multiview),
        depth_maps,
        depth_last: last.as_ref().and_then(|r| r.depth),
        depth_auto,
        error_map: state.error_map.as_ref().map(|m| m.summary()),
    };
    say(
        quiet,
        format!(
            "trained {iters} steps in {:.1} s ({:.0} samples/s), inv_s {:.0}",
            timings.train, train_summary.samples_per_second, train_summary.final_inv_s
        ),
    );

    // Mesh.
    let t = Instant::now();
    let active = model.config.inference_schedule(iters).active_levels;
    let r = model.config.render.radius;
    let sdf = |pts: &[[f32; 3]]| model.sdf(&state.params, pts, active);
    let two = extract_two_pass(
        &sdf,
        &TwoPassOptions {
            min: [-r; 3],
            max: [r; 3],
            coarse_res: cfg.mesh.coarse_res,
            fine_res: cfg.mesh.fine_res,
            pad_fraction: cfg.mesh.pad_fraction,
            mc: McOptions {
                close_radius: cfg.mesh.close_radius,
                ..McOptions::default()
            },
        },
    )?;
    let raw = two.mesh;
    let topo_raw = TopologyReport::of(&raw);
    let cameras: Vec<&crate::scene::Camera> =
        train_idx.iter().map(|&i| &scene.views[i].camera).collect();
    let (mut closed, mut clean) = if cfg.mesh.clean {
        let (m, rep) = clean_mesh(
            &raw,
            &masked_views,
            &cameras,
            &CleanOptions {
                min_area_share: cfg.mesh.clean_min_area_share,
                mask_cull: cfg.mesh.clean_mask_cull,
                dilate_px: cfg.mesh.clean_dilate_px,
                frustum_cull: cfg.mesh.clean_mask_cull,
                remove_enclosed: cfg.mesh.clean_enclosed,
            },
        );
        (m, Some(rep))
    } else {
        (raw.clone(), None)
    };
    // Rule 4 (`mesh::clean`): the scored mesh is the part the training cameras see; the closed
    // surface it was cut from stays beside it, less its wholly unseen components, and the genus
    // is measured on that.
    let (mut mesh, unseen) = match clean.as_mut() {
        Some(rep) => {
            let margin = cfg.mesh.clean_visible_margin_mm / scene.normalization.scale;
            let cut = cull_unseen_parts(
                &closed,
                &cameras,
                cfg.mesh.clean_min_visible_views,
                margin,
                cfg.mesh.clean_min_area_share,
            );
            rep.faces_unseen = cut.faces_unseen;
            rep.unseen_components_removed = cut.unseen_components_removed;
            rep.faces_in_unseen_components = cut.faces_in_unseen_components;
            rep.cut_specks_removed = cut.cut_specks_removed;
            rep.faces_in_cut_specks = cut.faces_in_cut_specks;
            rep.components_after -= cut.unseen_components_removed;
            closed = cut.closed;
            (cut.seen, cut.faces_unseen)
        }
        None => (closed.clone(), 0),
    };
    to_world(&mut closed, &scene.normalization);
    to_world(&mut mesh, &scene.normalization);
    let topo = TopologyReport::of(&closed);
    let topo_seen = if unseen > 0 {
        TopologyReport::of(&mesh)
    } else {
        topo
    };
    if let Some(rep) = clean.as_mut() {
        rep.components_seen = topo_seen.components;
    }
    let raw_path = out.join("mesh_raw.ply");
    if closed.faces.len() != raw.faces.len() {
        let mut raw = raw;
        to_world(&mut raw, &scene.normalization);
        dtu_eval::ply::write_mesh(&raw_path, &raw)?;
    } else if raw_path.is_file() {
        std::fs::remove_file(&raw_path).map_err(io_err(&raw_path))?;
    }
    let closed_path = out.join("mesh_closed.ply");
    if unseen > 0 {
        dtu_eval::ply::write_mesh(&closed_path, &closed)?;
    } else if closed_path.is_file() {
        std::fs::remove_file(&closed_path).map_err(io_err(&closed_path))?;
    }
    dtu_eval::ply::write_mesh(&out.join("mesh.ply"), &mesh)?;
    timings.mesh = t.elapsed().as_secs_f64();
    say(
        quiet,
        format!(
            "mesh: {} vertices, {} faces in {:.1} s",
            mesh.vertices.len(),
            mesh.faces.len(),
            timings.mesh
        ),
    );

    // Evaluation.
    let t = Instant::now();
    let truth = sim::SceneTruth::read(&scene_ref.dir);
    // The true mesh (synthetic scenes), read once for the two figures that use it: the seen
    // floor (below) and the held-out normal error.
    let truth_path = scene_ref.dir.join("gt_mesh.ply");
    let seen_floor_wanted = cfg.eval.enabled
        && cfg.mesh.clean
        && cfg.mesh.clean_min_visible_views > 0
        && truth.floor.is_some()
        && own_truth(&truth, &cfg.eval, &scene_ref);
    let mut truth_mesh = (truth_path.is_file() && (seen_floor_wanted || !heldout.is_empty()))
        .then(|| dtu_eval::ply::read_mesh(&truth_path));
    let mut chamfer_closed = None;
    let mut floor_seen = None;
    let (chamfer, eval_note) = if !cfg.eval.enabled {
        (
            None,
            Some("evaluation disabled (eval.enabled = false)".to_string()),
        )
    } else if mesh.faces.is_empty() {
        // Nothing to score (the SDF never crossed zero in the box, or the clean-up removed
        // everything): the run still reports what it did, and says why there is no Chamfer.
        let note = format!(
            "the mesh is empty ({} raw faces, {} after clean-up): no Chamfer distance; the \
             surface was not recovered (see renders/ and mesh_raw.ply if present)",
            topo_raw.faces,
            mesh.faces.len()
        );
        eprintln!("warning: {note}");
        (None, Some(note))
    } else {
        match find_gt(cfg, &scene_ref, &truth) {
            Err(note) => (None, Some(note)),
            Ok((root, scan)) => {
                let gt = dtu_eval::protocol::GroundTruth::load(&root, scan)?;
                let params = dtu_eval::report::DtuParams::default();
                let e = dtu_eval::protocol::evaluate_mesh(&mesh, &gt, &params, cfg.seed)?;
                if cfg.eval.vis {
                    // DTUeval-python's default `visualize_threshold` (10 mm).
                    dtu_eval::vis::write_dtu(&out, scan, &e, &gt.points, 10.0, params.max_dist)?;
                }
                let figures = |e: &dtu_eval::protocol::DtuEvaluation| ChamferMetrics {
                    mean_d2s: e.mean_d2s,
                    mean_s2d: e.mean_s2d,
                    overall: e.overall(),
                    chamfer_sum: e.chamfer_sum(),
                    gt_root: root.display().to_string(),
                    scan,
                };
                // The closed surface too, when rule 4 cut it: what the unseen side costs.
                if unseen > 0 && !closed.faces.is_empty() {
                    let c = dtu_eval::protocol::evaluate_mesh(&closed, &gt, &params, cfg.seed)?;
                    chamfer_closed = Some(figures(&c));
                }
                // The seen floor: the true mesh cut by rule 4 with these training cameras, where
                // the run is scored against the scene's own truth and the folder has its mesh.
                // A diagnostic: a true mesh it cannot use costs the figure, not the run.
                let seen = match truth_mesh.as_ref().filter(|_| seen_floor_wanted) {
                    None => Ok(None),
                    Some(Err(e)) => Err(e.to_string().trim_end().to_string()),
                    Some(Ok(m)) => {
                        let rule = seen_floor::SeenRule {
                            min_views: cfg.mesh.clean_min_visible_views,
                            margin_mm: cfg.mesh.clean_visible_margin_mm,
                            min_area_share: cfg.mesh.clean_min_area_share,
                        };
                        let norm = &scene.normalization;
                        seen_floor::seen_floor(m, norm, &cameras, &rule, &gt, &params, cfg.seed)
                            .map_err(|e| format!("{}: {e}", truth_path.display()))
                    }
                };
                match seen {
                    Ok(f) => floor_seen = f,
                    Err(e) => eprintln!("warning: no seen floor ({e})"),
                }
                (Some(figures(&e)), None)
            }
        }
    };
    timings.eval = t.elapsed().as_secs_f64();
    let geometry = GeometryVsTruth::new(&truth, &cfg.eval, &scene_ref, chamfer.as_ref(), &topo);
    match (&chamfer, &eval_note) {
        (Some(c), _) => say(
            quiet,
            format!(
                "chamfer: accuracy {:.3} mm, completeness {:.3} mm, sum {:.3} mm (overall {:.3})",
                c.mean_d2s, c.mean_s2d, c.chamfer_sum, c.overall
            ),
        ),
        (None, Some(n)) => say(quiet, format!("no evaluation: {n}")),
        _ => {}
    }
    if let (Some(f), Some(r)) = (geometry.floor_mm, geometry.ratio_to_floor) {
        say(quiet, format!("floor {f:.3} mm: Chamfer {r:.2}× the floor"));
    }
    let ratio_to_floor_seen = match (&chamfer, &floor_seen) {
        (Some(c), Some(f)) if f.chamfer_sum > 0.0 => Some(c.chamfer_sum / f.chamfer_sum),
        _ => None,
    };
    if let (Some(f), Some(r)) = (&floor_seen, ratio_to_floor_seen) {
        say(
            quiet,
            format!(
                "seen floor {:.3} mm (the truth less the {:.1} % of its area that fewer than {} \
                 training cameras see): Chamfer {r:.2}× it",
                f.chamfer_sum,
                100.0 * f.area_share_cut,
                f.min_views
            ),
        );
    }
    if let Some(g) = geometry.gt_genus {
        say(
            quiet,
            format!(
                "genus of the largest component {} (ground truth {g})",
                geometry
                    .genus
                    .map_or("— (empty mesh)".to_string(), |x| x.to_string())
            ),
        );
    }

    // Held-out renders.
    let t = Instant::now();
    let renders = out.join("renders");
    let mut heldout_metrics = Vec::new();
    if !heldout.is_empty() {
        std::fs::create_dir_all(&renders).map_err(io_err(&renders))?;
    }
    let k = cfg.data.render_downscale as usize;
    let sched = model.config.inference_schedule(iters);
    // Ground-truth normals where the scene folder has its mesh (synthetic scenes).
    // A diagnostic as the seen floor is: a true mesh that cannot be read costs the normal
    // error (with a warning), not the run that has already trained.
    let gt_normals = match truth_mesh.take().filter(|_| !heldout.is_empty()) {
        None => None,
        Some(Ok(m)) => normal_error::GtNormals::new(&m, &scene.normalization),
        // The PLY reader's error names the file already.
        Some(Err(e)) => {
            eprintln!(
                "warning: no held-out normal error ({})",
                e.to_string().trim_end()
            );
            None
        }
    };
    let (mut nerr_sum, mut nerr_px) = (0.0f64, 0usize);
    for &v in &heldout {
        let view = &scene.views[v];
        let cam = view.camera.downscaled(k as u32);
        let (origins, dirs) = camera_rays(&cam);
        let (w, h) = (cam.width as usize, cam.height as usize);
        let codes = vec![0u32; origins.len()];
        let p = vec![0f32; origins.len()];
        let o = model.render(
            &state.params,
            &RayBatch {
                origins: &origins,
                dirs: &dirs,
                codes: &codes,
                p: &p,
            },
            sched,
            model.config.render.occupancy.enabled.then_some(&state.occ),
        )?;
        let bg = model.config.render.background;
        let mut gt = view.image.downscaled(k);
        if let Some(m) = view.mask.as_ref().filter(|_| cfg.data.masks) {
            let m = m.downscaled(k);
            for (px, mv) in gt.data.chunks_exact_mut(3).zip(&m.data) {
                for (v, b) in px.iter_mut().zip(bg) {
                    *v = *v * mv + b * (1.0 - mv);
                }
            }
        }
        let rgb = RgbImage {
            width: w,
            height: h,
            data: o.rgb.iter().flatten().copied().collect(),
        };
        let normal = normal_error::normal_image(w, h, &o.normal, &o.opacity, bg);
        rgb.save(&renders.join(format!("view{v:03}_rgb.png")))?;
        normal.save(&renders.join(format!("view{v:03}_normal.png")))?;
        gt.save(&renders.join(format!("view{v:03}_gt.png")))?;
        let normal_error_deg = gt_normals.as_ref().and_then(|g| {
            let (s, n) = g.angular_error(&origins, &dirs, &o.normal, &o.opacity);
            nerr_sum += s;
            nerr_px += n;
            (n > 0).then(|| s / n as f64)
        });
        // Silhouette agreement: a membrane across a hole, or a floater, is opacity where the
        // held-out mask says background.
        let mask_iou = view.mask.as_ref().map(|m| {
            let m = m.downscaled(k);
            let (mut inter, mut union) = (0usize, 0usize);
            for (&mv, &op) in m.data.iter().zip(&o.opacity) {
                let (a, b) = (mv > 0.5, op > 0.5);
                inter += (a && b) as usize;
                union += (a || b) as usize;
            }
            if union == 0 {
                1.0
            } else {
                inter as f64 / union as f64
            }
        });
        heldout_metrics.push(ViewMetrics {
            view: v,
            psnr: psnr(&rgb, &gt),
            ssim: ssim(&rgb, &gt),
            normal_error_deg,
            mask_iou,
        });
    }
    timings.render = t.elapsed().as_secs_f64();
    // Normals and colours into mesh.ply, the turntable, the held-out sheet (`crate::export`).
    let t = Instant::now();
    let e = &cfg.export;
    let (p, ti) = (&state.params, &train_idx);
    crate::export::after_reconstruct(
        e, &model, p, sched, &scene, ti, &mesh, &heldout, &out, quiet,
    )?;
    timings.export = t.elapsed().as_secs_f64();
    let mean = |f: &dyn Fn(&ViewMetrics) -> Option<f64>| -> Option<f64> {
        let v: Vec<f64> = heldout_metrics.iter().filter_map(f).collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    };
    let psnr_heldout = mean(&|m| Some(m.psnr));
    let ssim_heldout = mean(&|m| m.ssim);
    if let Some(p) = psnr_heldout {
        say(
            quiet,
            format!(
                "held-out views {:?}: PSNR {:.2} dB, SSIM {:.4}",
                heldout,
                p,
                ssim_heldout.unwrap_or(f64::NAN)
            ),
        );
    }
    timings.total = t_total.elapsed().as_secs_f64();

    let metrics = Metrics {
        scene: scene_ref,
        preset: cfg.preset,
        augment: cfg.augment.mode,
        seed: cfg.seed,
        config_hash: hash,
        chamfer,
        eval_note,
        psnr_heldout,
        ssim_heldout,
        normal_error_deg: (nerr_px > 0).then(|| nerr_sum / nerr_px as f64),
        floor_mm: geometry.floor_mm,
        ratio_to_floor: geometry.ratio_to_floor,
        floor_seen,
        ratio_to_floor_seen,
        gt_genus: geometry.gt_genus,
        genus_matches: geometry.genus_matches,
        mask_iou_heldout: mean(&|m| m.mask_iou),
        heldout: heldout_metrics,
        train: train_summary,
        chamfer_closed,
        mesh: MeshSummary {
            vertices: mesh.vertices.len(),
            faces: mesh.faces.len(),
            boundary_edges: topo_seen.boundary_edges,
            non_manifold_edges: topo_seen.non_manifold_edges,
            components: topo_seen.components,
            genus: topo.genus,
            closed_faces: topo.faces,
            closed_boundary_edges: topo.boundary_edges,
            largest_genus: geometry.genus,
            raw_genus: topo_raw.genus,
            raw_components: topo_raw.components,
            raw_faces: topo_raw.faces,
            clean,
        },
        timings_s: timings,
        threads: rayon::current_num_threads(),
        version: env!("CARGO_PKG_VERSION").to_string(),
    };
    write_atomic(
        &out.join("metrics.json"),
        &serde_json::to_string_pretty(&metrics).expect("metrics serialise"),
    )?;
    say(
        quiet,
        format!(
            "done in {:.1} s: {}",
            metrics.timings_s.total,
            out.join("metrics.json").display()
        ),
    );
    drop(lock);
    Ok(metrics)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The folder-or-scene decision of [`resolve_scene`]: a folder without `cameras_sphere.npz`
    /// gives way to a DTU scan or built-in scene of the same bare name, and only to them.
    #[test]
    fn a_folder_that_holds_no_scene_does_not_shadow_a_scene_of_its_name() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path().join("dtu");
        std::fs::create_dir_all(root.join("dtu_scan7")).unwrap();
        // The user's own folders, one named like a DTU scan, one like a built-in scene.
        let (scan, cup) = (tmp.path().join("scan7"), tmp.path().join("cup"));
        for d in [&scan, &cup] {
            std::fs::create_dir_all(d).unwrap();
            std::fs::write(d.join("notes.txt"), "mine").unwrap();
        }
        // `dir` is where the folder is; `name` is the scene name as the user typed it.
        let with_base = |name: &str| shadowed_by_folder(&tmp.path().join(name), name, &root);
        assert!(with_base("scan7").unwrap().contains("dtu_scan7"));
        assert!(with_base("cup")
            .unwrap()
            .contains("built-in synthetic scene 'cup'"));
        // A name of nothing else keeps the folder (the loader names what it lacks).
        std::fs::create_dir_all(tmp.path().join("mine")).unwrap();
        assert_eq!(with_base("mine"), None);
        // A folder that holds a scene wins, as DESIGN.md §2 orders.
        std::fs::write(cup.join(dtu::CAMERA_FILE), b"").unwrap();
        assert_eq!(with_base("cup"), None);
        std::fs::remove_file(cup.join(dtu::CAMERA_FILE)).unwrap();
        // A name written as a path is the folder, whatever else it names.
        for written in ["./cup", "cup/", cup.to_str().unwrap()] {
            assert_eq!(shadowed_by_folder(&cup, written, &root), None, "{written}");
        }
        // `.` names the working directory, not the data root (which `root.join(".")` is).
        assert_eq!(shadowed_by_folder(&cup, ".", &root), None);
        assert_eq!(shadowed_by_folder(&cup, "..", &root), None);
    }
}
