//! The scene simulator: DTU-style synthetic scenes with ground truth, simulating only the effects
//! a scene calls for.
//!
//! A [`SceneDescription`] (TOML; [`desc`]) names an object (a built-in procedural shape,
//! [`shapes`], or a mesh file), a DTU-like rig ([`rig`]), sampling, ground-truth settings and
//! effects. [`SimScene::prepare`] places the object and builds the ray tracers ([`setup`]);
//! [`SimScene::render_view`] renders a view with obvhs ([`render`]); [`SimScene::ground_truth`]
//! samples the visible surface and builds DTU's observation mask and plane ([`gt`]);
//! [`generate`] writes it all in the DTU layout:
//!
//! ```text
//! <scene>/image/000000.png ...            rendered views (8-bit RGB)
//! <scene>/mask/000.png ...                object masks (0/255; the ground plane is not object)
//! <scene>/cameras_sphere.npz              world_mat_i (world mm) and scale_mat_i
//! <scene>/Points/stl/stl{scan:03}_total.ply   visible surface points (float32, world mm)
//! <scene>/ObsMask/ObsMask{scan}_10.mat     ObsMask, BB, Res (MATLAB v5)
//! <scene>/ObsMask/Plane{scan}.mat          P (MATLAB v5)
//! <scene>/gt_mesh.ply                     the true surface (world mm)
//! <scene>/scene.toml                      the description rendered
//! <scene>/meta.json                       scan, name, seed, counters, GT summary, the true
//!                                         mesh's genus and the Chamfer floor (deterministic)
//! <scene>/timings.json                    wall-clock times and rays per second (vary per run)
//! ```
//! The same description gives the same bytes in every file but `timings.json`.
//!
//! `meta.json` also holds what a reconstruction is judged against beyond Chamfer:
//! `mesh_genus`, the genus of the true mesh's largest component (Euler characteristic,
//! [`crate::mesh::TopologyReport::largest_genus`]), and `floor`, the true mesh itself scored by
//! the DTU protocol against the scene's own ground truth ([`Floor`]): what a perfect
//! reconstruction gets, the sampling and visibility losses of the protocol included. A
//! reconstruction reads both back with [`SceneTruth::read`].
//!
//! The built-in catalog is in [`catalog`]; [`ensure_builtin`] generates a built-in scene once
//! into a cache directory, atomically.

pub mod catalog;
pub mod degrade;
pub mod desc;
pub mod gt;
pub mod render;
pub mod rig;
pub mod setup;
pub mod shapes;
pub mod texture;

pub use catalog::{builtin, CatalogEntry, CATALOG, DEFAULT_SCENE};
pub use desc::SceneDescription;
pub use gt::{GroundTruth, GtStats};
pub use render::{Counters, ViewRender};
pub use setup::SimScene;

use crate::mesh::TopologyReport;
use crate::scene::{write_scene, ImageError, SceneError, ViewOut};
use crate::util::{inspect_output_dir, OutputDir};
use dtu_eval::gt::{GtError, GtPaths};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Bumped whenever the renderer or ground-truth code changes what a description produces, so
/// cached scenes made by older code are not reused. 3: `meta.json` holds the true mesh's genus
/// and the Chamfer floor.
pub const SIM_FORMAT_VERSION: u32 = 3;

/// The seed of the floor's shuffle before downsampling (the DTU protocol's step 2). Any fixed
/// seed would do: the floor moves from one seed to another by far less than the printed precision
/// (`neus-aug eval --mesh gt_mesh.ply --seed S`).
pub const FLOOR_SEED: u64 = 0;

/// Why a synthetic scene cannot be described, prepared or written. Every variant names the key,
/// file or value at fault.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// `neus-aug synth NAME` with a name that is not in the catalog.
    #[error("unknown built-in scene '{name}' (known: {known}; or give a scene .toml file)")]
    UnknownScene { name: String, known: String },
    /// The TOML does not parse or has an unknown key (the message names it).
    #[error("{source_name}: {message}")]
    Toml {
        source_name: String,
        message: String,
    },
    /// A value is out of range or inconsistent with another.
    #[error("scene description: '{key}' {problem}")]
    Invalid { key: String, problem: String },
    /// A mesh file cannot be used.
    #[error("mesh {path}: {problem}")]
    BadMesh { path: PathBuf, problem: String },
    /// The output folder is not empty.
    #[error("output folder {0} exists and is not empty; choose another --out or remove it")]
    OutputExists(PathBuf),
    /// The output path cannot be a folder (a dangling link, a file, ...).
    #[error(transparent)]
    OutputDir(#[from] crate::util::OutputDirError),
    /// No cache directory can be found.
    #[error("no cache directory: set NEUS_AUG_CACHE (or HOME)")]
    NoCacheDir,
    /// A file or directory could not be read or written.
    #[error("cannot access {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Writing the DTU layout failed.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// Writing an image failed.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// Writing a `.mat` file failed.
    #[error(transparent)]
    Gt(#[from] GtError),
    /// Writing a PLY file failed.
    #[error(transparent)]
    Ply(#[from] dtu_eval::ply::PlyError),
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> SimError + '_ {
    move |source| SimError::Io {
        path: path.into(),
        source,
    }
}

/// Options of [`generate`].
#[derive(Default)]
pub struct GenerateOptions<'a> {
    /// Called with a one-line progress message (views rendered, ground truth, writing).
    pub progress: Option<&'a dyn Fn(&str)>,
}

/// Wall-clock times of a generation (seconds) and ray throughput.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Timings {
    /// Building the mesh, rig and BVHs.
    pub prepare_s: f64,
    /// Rendering every view.
    pub render_s: f64,
    /// Sampling the ground truth and its visibility.
    pub gt_s: f64,
    /// Scoring the true mesh by the DTU protocol (the floor).
    pub floor_s: f64,
    /// Writing files.
    pub write_s: f64,
    /// (primary + shadow rays) / render_s.
    pub render_rays_per_s: f64,
    /// (visibility + observation-mask rays) / gt_s.
    pub gt_rays_per_s: f64,
}

/// The Chamfer floor of a scene: its true mesh (`gt_mesh.ply`) scored by the DTU protocol
/// ([`dtu_eval::protocol::evaluate_mesh`], default [`dtu_eval::report::DtuParams`], shuffle seed
/// [`FLOOR_SEED`]) against the scene's own ground truth. World mm.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Floor {
    /// Accuracy + completeness (the paper's Chamfer figure; what `ratio_to_floor` divides by).
    pub chamfer_sum: f64,
    /// Accuracy: mean true mesh → GT points distance (`mean_d2s`).
    pub mean_d2s: f64,
    /// Completeness: mean GT points → true mesh distance (`mean_s2d`).
    pub mean_s2d: f64,
}

/// Scores the true mesh `mesh` (world mm) against `gt` with the DTU protocol ([`Floor`]).
pub fn chamfer_floor(
    mesh: &crate::mesh::TriMesh,
    gt: &dtu_eval::protocol::GroundTruth,
) -> Result<Floor, dtu_eval::error::EvalError> {
    let params = dtu_eval::report::DtuParams::default();
    let e = dtu_eval::protocol::evaluate_mesh(mesh, gt, &params, FLOOR_SEED)?;
    Ok(Floor {
        chamfer_sum: e.chamfer_sum(),
        mean_d2s: e.mean_d2s,
        mean_s2d: e.mean_s2d,
    })
}

/// What a scene folder's `meta.json` says about its ground truth, for judging a reconstruction.
/// Every field is `None` when the folder has no `meta.json` (a real DTU scan) or was written by
/// a simulator that did not record it (format 2 and older).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SceneTruth {
    /// The DTU scan number of the ground-truth files.
    pub scan: Option<u32>,
    /// Genus of the true mesh's largest component; `None` when the true mesh is not a closed,
    /// consistently oriented surface (`mesh_closed_oriented` false: open edges or edges shared
    /// by more than two faces), where the Euler characteristic gives no genus.
    pub genus: Option<i64>,
    /// The Chamfer floor.
    pub floor: Option<Floor>,
}

impl SceneTruth {
    /// Reads `scene_dir/meta.json`. A missing or unparsable file, or a missing key, gives `None`
    /// for what it would have said (a reconstruction still runs; its report says "unknown").
    pub fn read(scene_dir: &Path) -> Self {
        let Some(v) = std::fs::read_to_string(scene_dir.join("meta.json"))
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        else {
            return Self::default();
        };
        Self {
            scan: v
                .get("scan")
                .and_then(|s| s.as_u64())
                .and_then(|s| u32::try_from(s).ok()),
            genus: v
                .get("mesh_genus")
                .and_then(|g| g.as_i64())
                .filter(|_| v.get("mesh_closed_oriented") != Some(&serde_json::Value::Bool(false))),
            floor: v
                .get("floor")
                .and_then(|f| serde_json::from_value::<Floor>(f.clone()).ok())
                .filter(|f| f.chamfer_sum.is_finite()),
        }
    }
}

/// What [`generate`] did.
#[derive(Clone, Debug, Serialize)]
pub struct SynthReport {
    /// The scene folder written.
    pub root: PathBuf,
    /// Render counters summed over views.
    pub counters: Counters,
    /// Ground-truth counts.
    pub gt: GtStats,
    /// Genus of the true mesh's largest component (as in `meta.json`).
    pub mesh_genus: i64,
    /// The Chamfer floor, or why the protocol could not score the true mesh.
    pub floor: Result<Floor, String>,
    /// Timings.
    pub timings: Timings,
}

#[derive(Serialize)]
struct GtMeta {
    points: u64,
    /// Sum of the written f32 coordinates (in f64), a checksum for cross-checks.
    points_sum: [f64; 3],
    points_file: String,
    obs_mask_file: String,
    plane_file: String,
    dims: [usize; 3],
    bb: [[f64; 3]; 2],
    res: f64,
    obs_voxels: u64,
    plane: [f64; 4],
    stats: GtStats,
}

#[derive(Serialize)]
struct Meta<'a> {
    format_version: u32,
    name: &'a str,
    scan: u32,
    seed: u64,
    views: usize,
    resolution: [u32; 2],
    spp: u32,
    distance_mm: f64,
    scale_mat: ScaleMeta,
    mesh_vertices: usize,
    mesh_faces: usize,
    mesh_closed_oriented: bool,
    /// Connected components of the true mesh.
    mesh_components: usize,
    /// Genus of its largest component ([`TopologyReport::largest_genus`]).
    mesh_genus: i64,
    counters: Counters,
    gt: GtMeta,
    /// [`Floor`]; `null` when the protocol cannot score the true mesh (`floor_error` says why).
    floor: Option<Floor>,
    #[serde(skip_serializing_if = "Option::is_none")]
    floor_error: Option<String>,
}

#[derive(Serialize)]
struct ScaleMeta {
    scale: f64,
    center: [f64; 3],
}

/// Renders every view, samples the ground truth, and writes the scene folder `out` (created;
/// it must be absent or empty). See the module doc for the files.
pub fn generate(
    desc: &SceneDescription,
    out: &Path,
    opts: &GenerateOptions,
) -> Result<SynthReport, SimError> {
    let say = |msg: &str| {
        if let Some(p) = opts.progress {
            p(msg)
        }
    };
    if inspect_output_dir(out)? == OutputDir::NotEmpty {
        return Err(SimError::OutputExists(out.into()));
    }
    let t0 = Instant::now();
    let scene = SimScene::prepare(desc)?;
    let prepare_s = t0.elapsed().as_secs_f64();

    let t1 = Instant::now();
    let n = scene.cameras.len();
    let mut views = Vec::with_capacity(n);
    for i in 0..n {
        views.push(scene.render_view(i));
        say(&format!("rendered view {}/{n}", i + 1));
    }
    let render_s = t1.elapsed().as_secs_f64();
    if views.iter().all(|v| v.mask.data.iter().all(|&m| m == 0.0)) {
        // A scene without its object has no ground truth worth scoring (its floor would read
        // 0.000 mm): refuse it rather than write it.
        return Err(SimError::Invalid {
            key: "object".into(),
            problem: format!(
                "covers no pixel in any of the {n} views: check the object's size and the rig \
                 (distance_mm, elevation_deg, resolution)"
            ),
        });
    }
    let counters: Counters = views.iter().map(|v| v.counters).sum();

    say(&format!(
        "sampling ground truth at {} mm and testing visibility",
        desc.gt.spacing_mm
    ));
    let t2 = Instant::now();
    let gt = scene.ground_truth();
    let gt_s = t2.elapsed().as_secs_f64();

    say("scoring the true mesh by the DTU protocol (the Chamfer floor)");
    let t_floor = Instant::now();
    let topo = TopologyReport::of(&scene.mesh_world);
    let protocol_gt = dtu_eval::protocol::GroundTruth {
        points: gt.points.clone(),
        obs_mask: gt.obs_mask.clone(),
        plane: gt.plane,
    };
    let floor = chamfer_floor(&scene.mesh_world, &protocol_gt).map_err(|e| e.to_string());
    drop(protocol_gt);
    let floor_s = t_floor.elapsed().as_secs_f64();

    say(&format!(
        "writing {} ({} views, {} ground-truth points)",
        out.display(),
        n,
        gt.points.len()
    ));
    let t3 = Instant::now();
    std::fs::create_dir_all(out).map_err(io_err(out))?;
    let outs: Vec<ViewOut> = views
        .iter()
        .zip(&scene.cameras)
        .map(|(v, cam)| ViewOut {
            image: &v.image,
            mask: Some(&v.mask),
            camera: cam,
        })
        .collect();
    write_scene(out, &outs, &scene.normalization)?;
    let paths = GtPaths::new(out, desc.scan);
    for p in [&paths.points, &paths.obs_mask] {
        let dir = p.parent().expect("GT paths have a parent");
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    }
    dtu_eval::ply::write_points(&paths.points, &gt.points, None)?;
    gt.obs_mask.write(&paths.obs_mask)?;
    gt.plane.write(&paths.plane)?;
    dtu_eval::ply::write_mesh(&out.join("gt_mesh.ply"), &scene.mesh_world)?;
    let toml_path = out.join("scene.toml");
    std::fs::write(&toml_path, desc.to_toml()).map_err(io_err(&toml_path))?;

    let rel = |p: &Path| {
        p.strip_prefix(out)
            .unwrap_or(p)
            .to_string_lossy()
            .into_owned()
    };
    let mut points_sum = [0f64; 3];
    for p in &gt.points {
        for k in 0..3 {
            points_sum[k] += p[k] as f64;
        }
    }
    let meta = Meta {
        format_version: SIM_FORMAT_VERSION,
        name: &desc.name,
        scan: desc.scan,
        seed: desc.seed,
        views: n,
        resolution: desc.rig.resolution,
        spp: desc.render.spp,
        distance_mm: scene.distance_mm,
        scale_mat: ScaleMeta {
            scale: scene.normalization.scale,
            center: scene.normalization.center,
        },
        mesh_vertices: scene.mesh_world.vertices.len(),
        mesh_faces: scene.mesh_world.faces.len(),
        mesh_closed_oriented: scene.closed_oriented,
        mesh_components: topo.components,
        mesh_genus: topo.largest_genus,
        counters,
        gt: GtMeta {
            points: gt.points.len() as u64,
            points_sum,
            points_file: rel(&paths.points),
            obs_mask_file: rel(&paths.obs_mask),
            plane_file: rel(&paths.plane),
            dims: gt.obs_mask.dims,
            bb: gt.obs_mask.bb,
            res: gt.obs_mask.res,
            obs_voxels: gt.stats.obs_voxels,
            plane: gt.plane.0,
            stats: gt.stats,
        },
        floor: floor.as_ref().ok().copied(),
        floor_error: floor.as_ref().err().cloned(),
    };
    let meta_path = out.join("meta.json");
    std::fs::write(
        &meta_path,
        serde_json::to_string_pretty(&meta).expect("meta serialises"),
    )
    .map_err(io_err(&meta_path))?;
    let write_s = t3.elapsed().as_secs_f64();
    let timings = Timings {
        prepare_s,
        render_s,
        gt_s,
        floor_s,
        write_s,
        render_rays_per_s: (counters.primary_rays + counters.shadow_rays) as f64
            / render_s.max(1e-9),
        gt_rays_per_s: (gt.stats.occlusion_rays + gt.stats.obs_rays) as f64 / gt_s.max(1e-9),
    };
    let timings_path = out.join("timings.json");
    std::fs::write(
        &timings_path,
        serde_json::to_string_pretty(&timings).expect("timings serialise"),
    )
    .map_err(io_err(&timings_path))?;
    Ok(SynthReport {
        root: out.into(),
        counters,
        gt: gt.stats,
        mesh_genus: topo.largest_genus,
        floor,
        timings,
    })
}

/// Writes the scene into a temporary sibling of `out`, then renames it to `out`, so an
/// interrupted run never leaves a folder that looks complete. `out` must be absent or empty.
pub fn generate_atomic(
    desc: &SceneDescription,
    out: &Path,
    opts: &GenerateOptions,
) -> Result<SynthReport, SimError> {
    let out_link = out;
    let resolved;
    let out = match inspect_output_dir(out)? {
        OutputDir::NotEmpty => return Err(SimError::OutputExists(out.into())),
        // A link to an empty folder: the scene replaces that folder, and the link stays.
        OutputDir::Empty if out.is_symlink() => {
            resolved = out.canonicalize().map_err(io_err(out))?;
            resolved.as_path()
        }
        _ => out,
    };
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&parent).map_err(io_err(&parent))?;
    let file_name = out
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    let tmp = parent.join(format!(".{file_name}.tmp-{}-{nanos}", std::process::id()));
    let result = generate(desc, &tmp, opts).and_then(|mut report| {
        // rename(2) replaces an empty directory, so an existing empty `out` is fine.
        std::fs::rename(&tmp, out).map_err(io_err(out))?;
        report.root = out_link.into();
        Ok(report)
    });
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result
}

/// The cache folder name of a description: `<name>-<16 hex digits>` of the format version and
/// the description's TOML.
pub fn cache_key(desc: &SceneDescription) -> String {
    let text = format!("format {SIM_FORMAT_VERSION}\n{}", desc.to_toml());
    format!(
        "{}-{}",
        desc.name,
        crate::util::fnv1a64_hex(text.as_bytes())
    )
}

/// The scene cache: `$NEUS_AUG_CACHE`, else `$XDG_CACHE_HOME/neus-aug/scenes`, else
/// `$HOME/.cache/neus-aug/scenes`.
pub fn default_cache_root() -> Result<PathBuf, SimError> {
    let var = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    if let Some(p) = var("NEUS_AUG_CACHE") {
        return Ok(p);
    }
    if let Some(p) = var("XDG_CACHE_HOME") {
        return Ok(p.join("neus-aug/scenes"));
    }
    var("HOME")
        .map(|h| h.join(".cache/neus-aug/scenes"))
        .ok_or(SimError::NoCacheDir)
}

/// Generates `desc` once into `cache_root/<cache_key>` and returns that folder; later calls
/// return it at once. Generation goes to a temporary folder that is renamed into place, so a
/// killed run never leaves a half scene under the final name; when two processes race, the
/// first rename wins and the other discards its copy.
pub fn ensure_scene(desc: &SceneDescription, cache_root: &Path) -> Result<PathBuf, SimError> {
    let dir = cache_root.join(cache_key(desc));
    if dir.join("meta.json").is_file() {
        return Ok(dir);
    }
    match generate_atomic(desc, &dir, &GenerateOptions::default()) {
        Ok(_) => Ok(dir),
        // Another process finished first: its scene is complete (renames are atomic).
        Err(SimError::OutputExists(_)) | Err(SimError::Io { .. })
            if dir.join("meta.json").is_file() =>
        {
            Ok(dir)
        }
        Err(e) => Err(e),
    }
}

/// [`ensure_scene`] for built-in scene `name`.
pub fn ensure_builtin(name: &str, cache_root: &Path) -> Result<PathBuf, SimError> {
    ensure_scene(&builtin(name)?, cache_root)
}
