//! The evaluation command line, shared by `dtu-eval` and `neus-aug eval`: one argument struct
//! ([`EvalArgs`], a `clap::Args`) and one entry point ([`run`]).
//!
//! - DTU mode: `--mesh M.ply --scan 24 --gt-root DIR` runs the protocol of [`crate::protocol`].
//! - Plain mode: `--mesh A.ply --ref B.ply` compares two point sets or meshes ([`crate::plain`]).
//!
//! `--json OUT` writes the [`Report`]; `--vis-dir DIR` the error-coloured clouds ([`crate::vis`]);
//! `--dump-dir DIR` the intermediate arrays as `.npy` for `scripts/crosscheck_chamfer.py`.

use crate::error::EvalError;
use crate::mesh::TriMesh;
use crate::plain::{self, PlainEvaluation};
use crate::protocol::{self, DtuEvaluation, GroundTruth};
use crate::report::{Details, DtuParams, PlainParams, Report, Stopwatch};
use crate::{ply, vis};
use std::path::{Path, PathBuf};

/// Arguments of the Chamfer evaluation (DTU mode or plain mode).
#[derive(Clone, Debug, clap::Args)]
pub struct EvalArgs {
    /// Mesh (or point cloud) to evaluate, PLY. DTU mode: world coordinates in mm (a NeuS mesh
    /// must first be mapped out of its normalised space with scale_mat). A PLY without faces is
    /// used as a point cloud (DTUeval-python's `--mode pcd`).
    #[arg(long, value_name = "PLY")]
    pub mesh: PathBuf,
    /// DTU scan number (DTU mode, with --gt-root).
    #[arg(long)]
    pub scan: Option<u32>,
    /// DTU ground-truth root: the folder holding Points/stl/ and ObsMask/ (DTU's "SampleSet/MVS
    /// Data").
    #[arg(long, value_name = "DIR")]
    pub gt_root: Option<PathBuf>,
    /// Plain mode: the reference point cloud or mesh (PLY) to compare --mesh with.
    #[arg(long = "ref", value_name = "PLY")]
    pub reference: Option<PathBuf>,
    /// Write the report as JSON here.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Seed of the shuffle that precedes downsampling.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Surface sampling density, also DTU's downsampling radius (mm).
    #[arg(long, default_value_t = 0.2)]
    pub density: f64,
    /// DTU mode: margin around the observation box (mm; 2x above).
    #[arg(long, default_value_t = 60.0)]
    pub patch_size: f64,
    /// Outlier cut: distances >= this are left out of the means (DTU default 20 mm; plain mode
    /// default: none).
    #[arg(long)]
    pub max_dist: Option<f64>,
    /// Plain mode: greedy downsampling radius applied to both sets (default: none).
    #[arg(long)]
    pub downsample: Option<f64>,
    /// Write error-coloured point clouds (DTUeval-python's colours) into this folder.
    #[arg(long, value_name = "DIR")]
    pub vis_dir: Option<PathBuf>,
    /// Distance shown as full red in the coloured clouds.
    #[arg(long, default_value_t = 10.0)]
    pub vis_threshold: f64,
    /// Write intermediate arrays (.npy) into this folder, for the Python cross-check.
    #[arg(long, value_name = "DIR")]
    pub dump_dir: Option<PathBuf>,
    /// Refuse meshes whose sampling would exceed this many points.
    #[arg(long, default_value_t = protocol::DEFAULT_MAX_SAMPLES)]
    pub max_samples: u64,
}

impl EvalArgs {
    /// The arguments of `dtu-eval --mesh MESH` with every other option at its command-line
    /// default (taken from the clap definition itself, so the two cannot drift apart). Set
    /// `scan` + `gt_root` for DTU mode or `reference` for plain mode with struct update syntax.
    pub fn new(mesh: impl Into<PathBuf>) -> Self {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            args: EvalArgs,
        }
        let mesh: PathBuf = mesh.into();
        let argv = [
            std::ffi::OsString::from("dtu-eval"),
            "--mesh".into(),
            mesh.into_os_string(),
        ];
        Cli::try_parse_from(argv)
            .expect("`--mesh PATH` alone is a complete command line")
            .args
    }
}

/// Runs the evaluation the arguments describe, writes the requested files and returns the
/// report (the caller prints [`Report::summary`]).
pub fn run(args: &EvalArgs) -> Result<Report, EvalError> {
    check_outputs(args)?;
    let usage = |m: &str| Err(EvalError::Usage(m.into()));
    match (&args.scan, &args.gt_root, &args.reference) {
        (Some(scan), Some(root), None) => run_dtu(args, *scan, root),
        (None, None, Some(reference)) => run_plain(args, reference),
        (Some(_), None, None) => usage("--scan needs --gt-root DIR (DTU's \"SampleSet/MVS Data\")"),
        (None, Some(_), None) => usage("--gt-root needs --scan N (the DTU scan number)"),
        (None, None, None) => usage(
            "nothing to compare --mesh with: give --scan N --gt-root DIR (DTU mode) or --ref PLY \
             (plain mode)",
        ),
        _ => usage(
            "give either --scan N --gt-root DIR (DTU mode) or --ref PLY (plain mode), not both",
        ),
    }
}

/// Refuses unusable output paths before any work: a `--json` target that exists and is not a
/// regular file, and a `--vis-dir` / `--dump-dir` that exists and is not a folder.
fn check_outputs(args: &EvalArgs) -> Result<(), EvalError> {
    if let Some(path) = &args.json {
        crate::atomic::check_replaceable(path).map_err(|source| EvalError::Io {
            path: path.into(),
            source,
        })?;
    }
    for (flag, dir) in [("--vis-dir", &args.vis_dir), ("--dump-dir", &args.dump_dir)] {
        if let Some(dir) = dir.as_ref().filter(|d| d.exists() && !d.is_dir()) {
            return Err(EvalError::Usage(format!(
                "{flag} {} exists and is not a folder; name a folder (it is created if missing)",
                dir.display()
            )));
        }
    }
    Ok(())
}

fn run_dtu(args: &EvalArgs, scan: u32, root: &Path) -> Result<Report, EvalError> {
    if args.downsample.is_some() {
        return Err(EvalError::Usage(
            "--downsample is for plain mode; DTU mode downsamples at --density".into(),
        ));
    }
    let params = DtuParams {
        density: args.density,
        patch_size: args.patch_size,
        max_dist: args.max_dist.unwrap_or(DtuParams::default().max_dist),
    };
    protocol::check_params(&params)?;
    let mut sw = Stopwatch::new();
    let gt = GroundTruth::load(root, scan)?;
    sw.lap("read_gt");
    let mesh = ply::read_mesh(&args.mesh)?;
    sw.lap("read_mesh");
    let what = args.mesh.display().to_string();
    let samples = protocol::sample_and_shuffle(
        &mesh,
        params.density,
        args.seed,
        args.max_samples,
        &what,
        &mut sw,
    )?;
    if let Some(dir) = &args.dump_dir {
        vis::create_dir(dir)?;
        npy_points(&dir.join("samples.npy"), &samples)?;
        sw.skip();
    }
    let mut eval = protocol::evaluate_samples(&samples, &gt, &params, sw)?;
    drop(samples);
    eval.counts.mesh_vertices = mesh.vertices.len() as u64;
    eval.counts.mesh_faces = mesh.faces.len() as u64;
    if args.dump_dir.is_some() {
        // The dumps list every distance, those at or beyond max_dist (not searched) included.
        eval.exact_outliers(&gt)?;
    }
    let report = dtu_report(args, scan, root, &params, &eval);
    write_outputs_dtu(args, scan, &eval, &gt, &params, &report)?;
    Ok(report)
}

fn dtu_report(
    args: &EvalArgs,
    scan: u32,
    root: &Path,
    params: &DtuParams,
    eval: &DtuEvaluation,
) -> Report {
    Report {
        mean_d2s: eval.mean_d2s,
        mean_s2d: eval.mean_s2d,
        overall: eval.overall(),
        chamfer_sum: eval.chamfer_sum(),
        mesh: args.mesh.display().to_string(),
        details: Details::Dtu {
            scan,
            gt_root: root.display().to_string(),
            params: params.clone(),
            counts: eval.counts.clone(),
        },
        seed: args.seed,
        timings_s: eval.stages.clone(),
        version: env!("CARGO_PKG_VERSION").into(),
    }
}

fn write_outputs_dtu(
    args: &EvalArgs,
    scan: u32,
    eval: &DtuEvaluation,
    gt: &GroundTruth,
    params: &DtuParams,
    report: &Report,
) -> Result<(), EvalError> {
    if let Some(dir) = &args.dump_dir {
        npy_points(&dir.join("data_down.npy"), &eval.data_down)?;
        npy_f64(&dir.join("d2s.npy"), &eval.d2s)?;
        npy_f64(&dir.join("s2d.npy"), &eval.s2d)?;
    }
    if let Some(dir) = &args.vis_dir {
        vis::write_dtu(
            dir,
            scan,
            eval,
            &gt.points,
            args.vis_threshold,
            params.max_dist,
        )?;
    }
    if let Some(path) = &args.json {
        write_json(path, report)?;
    }
    Ok(())
}

/// Reads a PLY as a point set: sampled (vertices + `MeshSupSamp` samples) when it has faces,
/// its vertices as they are otherwise. Returns the points and the mesh.
fn read_as_points(path: &Path, args: &EvalArgs) -> Result<(Vec<[f32; 3]>, TriMesh), EvalError> {
    let mesh = ply::read_mesh(path)?;
    let what = path.display().to_string();
    protocol::check_mesh(&mesh, args.density, args.max_samples, &what)?;
    let points = if mesh.faces.is_empty() {
        mesh.vertices.clone()
    } else {
        crate::sample::sample_mesh(&mesh, args.density)
    };
    Ok((points, mesh))
}

fn run_plain(args: &EvalArgs, reference: &Path) -> Result<Report, EvalError> {
    let params = PlainParams {
        density: args.density,
        downsample: args.downsample,
        max_dist: args.max_dist,
    };
    plain::check_params(&params)?;
    let mut sw = Stopwatch::new();
    let (data, _) = read_as_points(&args.mesh, args)?;
    let (refp, _) = read_as_points(reference, args)?;
    sw.lap("read_and_sample");
    let mut eval = plain::evaluate_points(data, refp, &params, args.seed, sw)?;
    if args.dump_dir.is_some() {
        // The dumps list every distance, those at or beyond max_dist (not searched) included.
        eval.exact_outliers()?;
    }
    let report = Report {
        mean_d2s: eval.mean_d2s,
        mean_s2d: eval.mean_s2d,
        overall: (eval.mean_d2s + eval.mean_s2d) / 2.0,
        chamfer_sum: eval.mean_d2s + eval.mean_s2d,
        mesh: args.mesh.display().to_string(),
        details: Details::Plain {
            reference: reference.display().to_string(),
            params: params.clone(),
            counts: eval.counts.clone(),
        },
        seed: args.seed,
        timings_s: eval.stages.clone(),
        version: env!("CARGO_PKG_VERSION").into(),
    };
    write_outputs_plain(args, &eval, &params, &report)?;
    Ok(report)
}

fn write_outputs_plain(
    args: &EvalArgs,
    eval: &PlainEvaluation,
    params: &PlainParams,
    report: &Report,
) -> Result<(), EvalError> {
    if let Some(dir) = &args.dump_dir {
        vis::create_dir(dir)?;
        npy_points(&dir.join("data.npy"), &eval.data)?;
        npy_points(&dir.join("ref.npy"), &eval.reference)?;
        npy_f64(&dir.join("d2s.npy"), &eval.d2s)?;
        npy_f64(&dir.join("s2d.npy"), &eval.s2d)?;
    }
    if let Some(dir) = &args.vis_dir {
        vis::write_plain(dir, eval, args.vis_threshold, params.max_dist)?;
    }
    if let Some(path) = &args.json {
        write_json(path, report)?;
    }
    Ok(())
}

/// Writes `report` as pretty JSON, atomically ([`crate::atomic::write_atomic`]); a target that is
/// not a regular file is refused.
pub fn write_json(path: &Path, report: &Report) -> Result<(), EvalError> {
    let text = serde_json::to_string_pretty(report).expect("a report always serialises");
    write_atomic(path, text.as_bytes())
}

fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), EvalError> {
    let io_err = |source| EvalError::Io {
        path: path.into(),
        source,
    };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(io_err)?;
    }
    crate::atomic::write_atomic(path, bytes).map_err(io_err)
}

/// Writes `[n][3]` `f32` points as a `.npy` (`<f4`, shape `(n, 3)`, C order).
fn npy_points(path: &Path, points: &[[f32; 3]]) -> Result<(), EvalError> {
    use npyz::WriterBuilder;
    let mut buf = Vec::with_capacity(points.len() * 12 + 128);
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[points.len() as u64, 3])
        .writer(&mut buf)
        .begin_nd()
        .map_err(|source| EvalError::Io {
            path: path.into(),
            source,
        })?;
    w.extend(points.iter().flatten().copied())
        .and_then(|_| w.finish())
        .map_err(|source| EvalError::Io {
            path: path.into(),
            source,
        })?;
    write_atomic(path, &buf)
}

/// Writes `[n]` `f64` values as a `.npy` (`<f8`).
fn npy_f64(path: &Path, values: &[f64]) -> Result<(), EvalError> {
    use npyz::WriterBuilder;
    let mut buf = Vec::with_capacity(values.len() * 8 + 128);
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[values.len() as u64])
        .writer(&mut buf)
        .begin_nd()
        .map_err(|source| EvalError::Io {
            path: path.into(),
            source,
        })?;
    w.extend(values.iter().copied())
        .and_then(|_| w.finish())
        .map_err(|source| EvalError::Io {
            path: path.into(),
            source,
        })?;
    write_atomic(path, &buf)
}
