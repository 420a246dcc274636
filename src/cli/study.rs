//! `neus-aug study GRID` and `neus-aug study collect DIR`.

use anyhow::Context;
use neus_aug::augment::AugMode;
use neus_aug::reconstruct::Preset;
use neus_aug::sim::{self, GenerateOptions};
use neus_aug::study::{self, grid, jobs, plan, report, Grid, StudyOptions};
use std::path::{Path, PathBuf};

/// Run one of the paper's experiment grids on the built-in scenes (each run a `reconstruct`
/// with its own folder; finished runs are skipped, interrupted ones resume), or aggregate a
/// study folder into tables and plots.
///
/// Grids: table2 (baseline/DIA/SIA on every scene), reduced (IA off/on × 10/25/50/75 % of the
/// views), degraded and degraded-mild (IA off/on × five degradations), pareto (Chamfer against
/// time, one factor at a time), smoke (a quick check), hard (every built-in scene at the
/// baseline, plus DIA/SIA on torus and double-torus: Chamfer against its floor, genus against
/// the truth, components, normal error), outside (the hard report on every mesh of --meshes,
/// each rendered into a scene of the study folder as `synth --mesh` does). Examples:
///
///   neus-aug study table2 --out studies/table2        (runs, resumable; then writes report/)
///   neus-aug study collect studies/table2             (tables and plots from what exists)
///   neus-aug study collect studies/table2 --scenes blob,torus --seeds 3 --to DIR   (a part)
///   neus-aug study reduced --emit-jobs studies/red    (jobs.txt, slurm.sbatch, parallel.sh)
///   python3 scripts/fetch_outside.py && neus-aug study outside   (meshes from outside)
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct StudyArgs {
    /// A grid (table2, reduced, degraded, degraded-mild, pareto, smoke, hard, outside),
    /// `collect`, or `list`.
    pub grid: String,
    /// For `collect`: the study folder.
    pub dir: Option<PathBuf>,
    /// Scenes, comma-separated: built-in names, `all`, folders or DTU scans (default: every
    /// built-in scene for table2 and hard, the default scene otherwise). For `collect`: report
    /// only these scenes, named as the report names them.
    #[arg(long)]
    pub scenes: Option<String>,
    /// For `outside`: the folder of meshes (.ply, .obj) to render and reconstruct, one scene
    /// each under STUDY/scenes/ (made once; an existing scene is kept).
    #[arg(long, value_name = "DIR", default_value = "target/outside")]
    pub meshes: PathBuf,
    /// Seeds per cell, 0..N (default: 3; pareto 1; smoke and outside 2). For `collect`: report
    /// only seeds 0..N.
    #[arg(long)]
    pub seeds: Option<u32>,
    /// Preset every run starts from.
    #[arg(long, value_enum, default_value = "fast")]
    pub preset: Preset,
    /// The augmentation of the "IA on" arm (reduced, degraded, degraded-mild).
    #[arg(long, value_enum, default_value = "sia")]
    pub ia: AugMode,
    /// A TOML config applied to every run after the preset (copied into the study folder).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Set a config field of every run (repeatable), e.g. `--set train.iterations=500`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// The study folder (default `studies/<grid>-<preset>`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the plan (runs and their command lines) and exit, writing nothing (`outside`
    /// lists the scenes it would render instead of rendering them).
    #[arg(long)]
    pub dry_run: bool,
    /// Plan the study in DIR and write jobs.txt, slurm.sbatch and parallel.sh instead of running.
    #[arg(long, value_name = "DIR")]
    pub emit_jobs: Option<PathBuf>,
    /// For `collect`: write the report here instead of DIR/report.
    #[arg(long)]
    pub to: Option<PathBuf>,
    /// For `collect` of a pareto study: draw another pareto study's front beside this one's
    /// (its folder, its report folder, or its pareto.csv), e.g. an older build's.
    #[arg(long, value_name = "DIR|CSV")]
    pub reference_front: Option<PathBuf>,
    /// Legend name of `--reference-front`.
    #[arg(long, default_value = "reference")]
    pub reference_label: String,
    /// Where DTU scans live (to recognise `--scenes scan24`).
    #[arg(long, env = "NEUS_AUG_DATA", default_value = "data/dtu")]
    pub data_root: PathBuf,
    /// No progress output from the runs.
    #[arg(long, short)]
    pub quiet: bool,
    /// Another study folder whose finished runs of the same configuration count as runs of this
    /// one (repeatable): e.g. the reduced grid's 100 % cells from a Table 2 study.
    #[arg(long, value_name = "DIR")]
    pub reuse_records: Vec<PathBuf>,
    /// Another study folder whose finished runs of the same training lend their final
    /// checkpoint (repeatable): a run of the same id, scene, seed, data, augmentation, model and
    /// optimisation, differing only in mesh, evaluation or export settings, then only
    /// re-extracts, scores and renders (e.g. a clean-up rule turned off over a finished study).
    /// Its record's times are the re-extraction's.
    #[arg(long, value_name = "DIR")]
    pub reuse_training: Vec<PathBuf>,
    /// Run at most N of the unfinished runs (seed-major plan order), then write the report and
    /// stop; the next call continues.
    #[arg(long, value_name = "N")]
    pub runs: Option<usize>,
}

pub fn run(args: StudyArgs) -> anyhow::Result<()> {
    match args.grid.as_str() {
        "collect" => return run_collect(&args),
        "list" => {
            for g in Grid::ALL {
                println!("{:<14} {}", g.name(), g.summary());
            }
            return Ok(());
        }
        _ => {}
    }
    let g: Grid = args.grid.parse()?;
    if let Some(d) = &args.dir {
        anyhow::bail!(
            "unexpected argument {} (only `collect` takes a folder; use --out DIR)",
            d.display()
        );
    }
    let mut opts = StudyOptions::new(g);
    opts.preset = args.preset;
    let dir = study_dir(&args, g, &opts)?;
    if let Some(list) = &args.scenes {
        opts.scenes = grid::parse_scenes(list, &args.data_root)?;
    } else if g == Grid::Outside {
        opts.scenes = Vec::new();
        let render = !args.dry_run;
        for folder in outside_scenes(&args.meshes, &dir.join("scenes"), args.quiet, render)? {
            if Path::new(&folder).is_dir() {
                opts.scenes
                    .extend(grid::parse_scenes(&folder, &args.data_root)?);
            } else {
                // A scene a dry run did not render: planned by the path it will have.
                opts.scenes.push(folder);
            }
        }
    }
    if let Some(n) = args.seeds {
        opts.seeds = n;
    }
    opts.ia = args.ia;
    opts.sets = args.set.clone();
    opts.base_config = args.config.is_some();
    if let Some(c) = &args.config {
        anyhow::ensure!(c.is_file(), "--config {}: no such file", c.display());
    }
    for d in &args.reuse_training {
        anyhow::ensure!(
            d.join("runs").is_dir(),
            "--reuse-training {}: not a study folder with runs (its runs/ is missing)",
            d.display()
        );
    }
    anyhow::ensure!(
        args.reuse_training.is_empty() || args.emit_jobs.is_none(),
        "--reuse-training works only when the study runs here, not with --emit-jobs (copy the \
         finished checkpoints into the job folders' runs instead)"
    );
    let (plan, cfgs) = plan::make_plan(&opts, args.config.as_deref(), &dir)?;
    if args.dry_run {
        println!(
            "# study {} → {} ({} runs); each line as run from the study folder",
            g,
            dir.display(),
            plan.runs.len()
        );
        for r in &plan.runs {
            println!(
                "{:<40} {}",
                r.id,
                jobs::reconstruct_args(r, &plan.options)
                    .iter()
                    .map(|a| jobs::shell_quote(a))
                    .collect::<Vec<_>>()
                    .join(" ")
            );
        }
        return Ok(());
    }
    if args.emit_jobs.is_some() {
        let e = study::run::emit_jobs(&dir, &plan, &cfgs, args.config.as_deref())?;
        println!(
            "wrote {} jobs to {}\n  Slurm:        cd {} && sbatch slurm.sbatch\n  GNU parallel: bash {} [JOBS]\n  then:         neus-aug study collect {}",
            e.count,
            e.jobs.display(),
            dir.display(),
            e.parallel.display(),
            dir.display()
        );
        return Ok(());
    }
    study::execute(
        &dir,
        &plan,
        &cfgs,
        args.config.as_deref(),
        &study::ExecOptions {
            quiet: args.quiet,
            reuse_records: args.reuse_records.clone(),
            reuse_training: args.reuse_training.clone(),
            max_runs: args.runs,
        },
    )
    .with_context(|| format!("study {} in {}", g, dir.display()))?;
    Ok(())
}

/// The study folder: `--out` or `--emit-jobs` (the same when both are given), else
/// `studies/<grid>-<preset>`.
fn study_dir(args: &StudyArgs, g: Grid, opts: &StudyOptions) -> anyhow::Result<PathBuf> {
    Ok(match (&args.out, &args.emit_jobs) {
        (Some(o), Some(e)) if o != e => {
            anyhow::bail!(
                "--out {} and --emit-jobs {} name different folders; give one",
                o.display(),
                e.display()
            )
        }
        (_, Some(e)) => e.clone(),
        (Some(o), None) => o.clone(),
        (None, None) => {
            PathBuf::from("studies").join(format!("{}-{}", g.name(), opts.preset.name()))
        }
    })
}

/// The `outside` grid's scenes: every `.ply` and `.obj` file of `meshes` (sorted by name)
/// rendered, as `neus-aug synth --mesh FILE` renders it (the default scene's rig, lighting and
/// effects), into `scenes/<file stem>`. A scene folder that already holds a finished scene
/// (`meta.json`) is kept, so a study resumes without rendering again. With `render` false (a
/// dry run) nothing is rendered: a missing scene is only announced, and its folder is returned
/// as an absolute path. Returns the folders.
fn outside_scenes(
    meshes: &Path,
    scenes: &Path,
    quiet: bool,
    render: bool,
) -> anyhow::Result<Vec<String>> {
    let fetch = "python3 scripts/fetch_outside.py downloads the outside set into target/outside";
    let entries = std::fs::read_dir(meshes).with_context(|| {
        format!(
            "--meshes {}: cannot read the folder ({fetch})",
            meshes.display()
        )
    })?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && p.extension()
                    .is_some_and(|e| e.eq_ignore_ascii_case("ply") || e.eq_ignore_ascii_case("obj"))
        })
        .collect();
    files.sort();
    anyhow::ensure!(
        !files.is_empty(),
        "--meshes {}: no .ply or .obj file ({fetch})",
        meshes.display()
    );
    let mut out = Vec::with_capacity(files.len());
    for (i, mesh) in files.iter().enumerate() {
        let mut desc = sim::builtin(sim::DEFAULT_SCENE)?;
        super::synth::use_mesh(&mut desc, mesh);
        // `--scenes` lists are comma-separated, and so is the plan's scene list.
        anyhow::ensure!(
            !desc.name.contains(','),
            "{}: a mesh file name with a comma cannot name a scene; rename the file",
            mesh.display()
        );
        let folder = scenes.join(&desc.name);
        let rendered = folder.join("meta.json").is_file();
        if !rendered && !render {
            if !quiet {
                eprintln!(
                    "[outside] {}/{}: would render {} into {} (not in a dry run)",
                    i + 1,
                    files.len(),
                    mesh.display(),
                    folder.display()
                );
            }
            desc.validate()?;
            let abs = std::path::absolute(&folder)
                .with_context(|| format!("{}: cannot make the path absolute", folder.display()))?;
            out.push(abs.display().to_string());
            continue;
        }
        if !rendered {
            if !quiet {
                eprintln!(
                    "[outside] {}/{}: rendering {} into {}",
                    i + 1,
                    files.len(),
                    mesh.display(),
                    folder.display()
                );
            }
            desc.validate()?;
            sim::generate_atomic(&desc, &folder, &GenerateOptions { progress: None })
                .with_context(|| format!("cannot render the scene of {}", mesh.display()))?;
        }
        out.push(folder.display().to_string());
    }
    Ok(out)
}

fn run_collect(args: &StudyArgs) -> anyhow::Result<()> {
    let dir = args
        .dir
        .as_ref()
        .context("usage: neus-aug study collect DIR")?;
    let to = args
        .to
        .clone()
        .unwrap_or_else(|| dir.join(report::REPORT_DIR));
    let reference = args
        .reference_front
        .as_deref()
        .map(|p| report::read_reference_front(p, &args.reference_label))
        .transpose()
        .context("--reference-front")?;
    let subset = study::Subset {
        scenes: args.scenes.as_ref().map(|l| {
            l.split(',')
                .map(|s| s.trim().to_string())
                .filter(|s| !s.is_empty())
                .collect()
        }),
        seeds: args.seeds,
    };
    let opts = study::CollectOptions {
        reference: reference.as_ref(),
        subset,
    };
    let c = study::collect_with(dir, &to, &opts)
        .with_context(|| format!("collect {}", dir.display()))?;
    println!(
        "collected {} of {} runs from {} into {}{}",
        c.collected,
        c.planned,
        dir.display(),
        to.display(),
        if c.missing.is_empty() {
            String::new()
        } else {
            format!(" ({} not finished)", c.missing.len())
        }
    );
    Ok(())
}
