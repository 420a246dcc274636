//! `neus-aug synth`: render a synthetic scene into the DTU layout, ground truth included.

use anyhow::{bail, Context};
use neus_aug::import::export;
use neus_aug::import::perturb::Perturbation;
use neus_aug::sim::{self, GenerateOptions, SceneDescription};
use std::path::{Path, PathBuf};

/// Render a built-in or described scene (or a mesh file) into the DTU layout with its ground
/// truth (Points/stl, ObsMask, Plane). `neus-aug synth --list` shows the built-in scenes.
#[derive(Debug, clap::Args)]
pub struct SynthArgs {
    /// A built-in scene name (see --list; `default` is the default scene) or a scene .toml file.
    /// With --mesh and no scene, the default scene's rig and effects are used.
    pub scene: Option<String>,
    /// Output folder (created; must be absent or empty).
    #[arg(long, required_unless_present_any = ["list", "print_toml"])]
    pub out: Option<PathBuf>,
    /// List the built-in scenes and exit.
    #[arg(long)]
    pub list: bool,
    /// Print the resolved scene description (TOML, options applied) and exit without rendering:
    /// a starting point for a scene file of your own.
    #[arg(long)]
    pub print_toml: bool,
    /// Image size WIDTHxHEIGHT (default from the scene: 400x300).
    #[arg(long, value_parser = parse_resolution)]
    pub resolution: Option<[u32; 2]>,
    /// Number of views (default from the scene: 49).
    #[arg(long)]
    pub views: Option<usize>,
    /// Seed of every random choice (textures, exposure, light jitter, degradations).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Render this mesh (.ply or .obj) instead of the scene's object, scaled into the rig.
    #[arg(long)]
    pub mesh: Option<PathBuf>,
    /// The mesh file's up axis: +x, -x, +y, -y, +z or -z.
    #[arg(long, requires = "mesh", allow_hyphen_values = true)]
    pub up_axis: Option<String>,
    /// Samples per pixel (default from the scene: 4).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Ground-truth point spacing in mm (default from the scene: 0.2).
    #[arg(long)]
    pub gt_spacing: Option<f64>,
    /// Add a degradation KIND:q (gaussian, motion-blur, poisson, salt-pepper, speckle) after the
    /// scene's own; repeatable, applied in order.
    #[arg(long = "degrade", value_name = "KIND:q")]
    pub degrade: Vec<String>,
    /// DTU scan number used in the ground-truth file names.
    #[arg(long)]
    pub scan: Option<u32>,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
    /// Also write the true cameras for the importers: `colmap` writes DIR/colmap/sparse/0/*.txt
    /// (PINHOLE, ground-truth points as points3D; import with `--images DIR/image`),
    /// `transforms` writes DIR/transforms.json. Repeatable.
    #[arg(long, value_enum)]
    pub export: Vec<ExportFormat>,
    /// Perturb every pose after rendering by exactly DEG degrees (about a random axis through
    /// the camera's centre) and DIST world units (mm; a random direction), and optionally every
    /// focal length by FOCAL percent, seeded by --seed: the scene's cameras_sphere.npz then holds
    /// the perturbed cameras and cameras_sphere_true.npz the true ones, which `reconstruct` with
    /// `train.pose_refine.enabled = true` measures against.
    #[arg(long, value_name = "DEG,DIST[,FOCAL]", value_parser = parse_perturbation)]
    pub perturb_poses: Option<Perturbation>,
}

fn parse_perturbation(s: &str) -> Result<Perturbation, String> {
    let bad = || {
        format!(
            "'{s}' is not DEG,DIST[,FOCAL] (e.g. 0.5,3: half a degree and 3 mm; 0,0,5: the \
             focal 5 % long)"
        )
    };
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse().map_err(|_| bad()))
        .collect::<Result<_, _>>()?;
    if !(2..=3).contains(&v.len()) {
        return Err(bad());
    }
    if !(v.iter().all(|x| x.is_finite()) && v[0] >= 0.0 && v[1] >= 0.0) {
        return Err(format!("'{s}': DEG and DIST must be finite and ≥ 0"));
    }
    Ok(Perturbation {
        degrees: v[0],
        dist: v[1],
        focal_pct: v.get(2).copied().unwrap_or(0.0),
    })
}

/// Camera formats `synth --export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// COLMAP text model in DIR/colmap/sparse/0.
    Colmap,
    /// instant-ngp / nerfstudio DIR/transforms.json.
    Transforms,
}

/// Most views `synth` renders (`--views` or the scene's `rig.views`): DTU has 49 or 64, and each
/// view's image is held in memory while the scene is written.
const MAX_VIEWS: usize = 1000;

fn parse_resolution(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT (e.g. 400x300)"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("'{s}' is not WIDTHxHEIGHT (e.g. 400x300)"))
    };
    let (w, h) = (parse(w)?, parse(h)?);
    if w == 0 || h == 0 {
        return Err(format!(
            "resolution {w}x{h} is empty: width and height must be at least 1"
        ));
    }
    Ok([w, h])
}

fn describe(args: &SynthArgs) -> anyhow::Result<SceneDescription> {
    let mut desc = match args.scene.as_deref() {
        Some(s) if s.ends_with(".toml") || Path::new(s).is_file() => {
            SceneDescription::load(Path::new(s))?
        }
        Some(name) => sim::builtin(name)?,
        None if args.mesh.is_some() => sim::builtin(sim::DEFAULT_SCENE)?,
        None => bail!("give a scene name (see `neus-aug synth --list`), a scene .toml, or --mesh"),
    };
    if let Some(mesh) = &args.mesh {
        use_mesh(&mut desc, mesh);
        if let Some(up) = &args.up_axis {
            desc.object.up_axis = toml::Value::String(up.clone())
                .try_into()
                .map_err(|_| anyhow::anyhow!("--up-axis '{up}' is not one of +x -x +y -y +z -z"))?;
        }
    }
    if let Some(r) = args.resolution {
        desc.rig.resolution = r;
    }
    if let Some(v) = args.views {
        desc.rig.views = v;
    }
    if let Some(s) = args.seed {
        desc.seed = s;
    }
    if let Some(s) = args.spp {
        desc.render.spp = s;
    }
    if let Some(g) = args.gt_spacing {
        desc.gt.spacing_mm = g;
    }
    if let Some(s) = args.scan {
        desc.scan = s;
    }
    desc.effects.degrade.extend(args.degrade.iter().cloned());
    desc.validate()?;
    if desc.rig.views > MAX_VIEWS {
        bail!(
            "rig.views = {} is too many: at most {MAX_VIEWS} views (DTU has 49 or 64; every view \
             is rendered and held in memory)",
            desc.rig.views
        );
    }
    Ok(desc)
}

/// Makes `desc` render `mesh` instead of its own object (named after the file, scan 100), with
/// the scene's rig, lighting and effects.
pub(super) fn use_mesh(desc: &mut SceneDescription, mesh: &Path) {
    desc.object.shape = None;
    desc.object.mesh = Some(mesh.to_path_buf());
    desc.name = mesh
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "mesh".into());
    desc.scan = 100;
    desc.summary = format!("mesh {}", mesh.display());
}

pub fn run(args: SynthArgs) -> anyhow::Result<()> {
    if args.list {
        for e in &sim::CATALOG {
            let default = if e.name == sim::DEFAULT_SCENE {
                " [default]"
            } else {
                ""
            };
            println!("{:<8} scan {:>3}  {}{default}", e.name, e.scan, e.summary);
        }
        return Ok(());
    }
    let desc = describe(&args)?;
    if args.print_toml {
        print!("{}", desc.to_toml());
        return Ok(());
    }
    let out = args.out.clone().context("--out DIR is required")?;
    let quiet = args.quiet;
    let progress = move |msg: &str| {
        if !quiet {
            eprintln!("[synth] {msg}");
        }
    };
    let report = sim::generate_atomic(
        &desc,
        &out,
        &GenerateOptions {
            progress: Some(&progress),
        },
    )
    .with_context(|| format!("cannot synthesise scene '{}'", desc.name))?;
    let t = &report.timings;
    println!(
        "wrote {} ({} views {}x{}, scan {}): {} ground-truth points; render {:.2} s ({:.2} M rays/s), \
         ground truth {:.2} s",
        report.root.display(),
        desc.rig.views,
        desc.rig.resolution[0],
        desc.rig.resolution[1],
        desc.scan,
        report.gt.visible,
        t.render_s,
        t.render_rays_per_s / 1e6,
        t.gt_s
    );
    // The floor (computed once by the simulator and stored in meta.json): the ground-truth mesh
    // itself scored by the DTU protocol, what a perfect reconstruction would get, the sampling
    // and visibility losses of the protocol included.
    match &report.floor {
        Ok(f) => println!(
            "floor: {:.3} mm Chamfer sum (accuracy {:.3}, completeness {:.3}): the ground-truth mesh \
             scored by the DTU protocol; ground-truth genus {}",
            f.chamfer_sum, f.mean_d2s, f.mean_s2d, report.mesh_genus
        ),
        Err(e) => println!(
            "floor: not computed ({e}); ground-truth genus {}",
            report.mesh_genus
        ),
    }
    if let Some(p) = &args.perturb_poses {
        let e = neus_aug::import::perturb::perturb_scene(&out, p, desc.seed)
            .with_context(|| format!("cannot perturb the poses of {}", out.display()))?;
        println!(
            "perturbed every pose by {:.3}° and {:.3} mm, every focal length by {} % (true \
             cameras: {})",
            e.rotation_deg,
            e.centre,
            p.focal_pct,
            out.join(neus_aug::import::perturb::TRUE_CAMERA_FILE)
                .display()
        );
    }
    for format in &args.export {
        let written = match format {
            ExportFormat::Colmap => export::export_colmap(&out, &out.join("colmap")),
            ExportFormat::Transforms => export::export_transforms(&out, &out),
        }
        .with_context(|| format!("cannot export {format:?} cameras of {}", out.display()))?;
        println!("exported {format:?} cameras: {}", written.display());
    }
    Ok(())
}
