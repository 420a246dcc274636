//! `neus-aug export RUN`: the coloured and textured meshes of a finished run, from its
//! checkpoint and `config.toml`, without training again (`neus_aug::export`).

use anyhow::{bail, Context};
use neus_aug::export::{self, check, ExportError, Formats, SurfaceField, ViewDirection};
use neus_aug::mesh::to_world;
use neus_aug::reconstruct::{
    clean_cut, config::MAX_MESH_RES, marching_cubes_of, masked_views, resolve_scene,
    trained_cameras, training_views, RunConfig,
};
use neus_aug::render::model::NeusModel;
use neus_aug::scene::{Camera, LoadOptions, Scene};
use neus_aug::train::checkpoint;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A file format of `--format`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// `mesh.ply`: positions, normals and colours per vertex (binary PLY).
    Ply,
    /// `mesh_textured.obj` + `.mtl` + `.png`.
    Obj,
    /// `mesh_textured.glb` (binary glTF 2.0, texture embedded).
    Glb,
}

/// Export a finished run's mesh with the trained colours: `mesh.ply` (vertex normals and
/// colours), a textured OBJ + MTL + PNG and a GLB, and `turntable.gif`, into `RUN/export/` by
/// default. Colours are the colour network's at the surface seen head-on (identity appearance,
/// p = 0).
#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// The run folder (`reconstruct --out`): config.toml, checkpoint.safetensors, mesh.ply.
    pub run: PathBuf,
    /// What to write, comma-separated.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "ply,obj,glb")]
    pub format: Vec<Format>,
    /// Texture side in texels (16..=16384).
    #[arg(long, default_value_t = 1024)]
    pub texture_size: u32,
    /// Extract the mesh again with this many grid points per axis in the refined marching-cubes
    /// pass (the run's clean-up applied), instead of reading the run's mesh.ply.
    #[arg(long)]
    pub resolution: Option<usize>,
    /// Output folder (default RUN/export).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Also render the held-out views from the network, the textured mesh and the
    /// vertex-coloured mesh, print their PSNRs against the truth, and write check.json and the
    /// renders (check/) into the output folder.
    #[arg(long)]
    pub check: bool,
    /// View direction of the colour query (default: the run's `export.view_direction`).
    #[arg(long, value_enum)]
    pub view_direction: Option<ViewDirArg>,
    /// No progress output.
    #[arg(long, short)]
    pub quiet: bool,
}

/// `--view-direction`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ViewDirArg {
    /// The training cameras' directions to the point, weighted towards head-on.
    Cameras,
    /// Along the inward normal.
    HeadOn,
}

impl From<ViewDirArg> for ViewDirection {
    fn from(v: ViewDirArg) -> Self {
        match v {
            ViewDirArg::Cameras => ViewDirection::Cameras,
            ViewDirArg::HeadOn => ViewDirection::HeadOn,
        }
    }
}

fn say(quiet: bool, msg: impl AsRef<str>) {
    if !quiet {
        eprintln!("{}", msg.as_ref());
    }
}

/// The run's configuration (`RUN/config.toml`), checked.
fn run_config(run: &Path) -> anyhow::Result<RunConfig> {
    let path = run.join("config.toml");
    let text = std::fs::read_to_string(&path).with_context(|| {
        format!(
            "cannot read {}: is {} a `reconstruct` run folder?",
            path.display(),
            run.display()
        )
    })?;
    let cfg = RunConfig::from_saved_toml(&text, &path.display().to_string())?;
    cfg.validate()
        .with_context(|| format!("{} is not a valid configuration", path.display()))?;
    Ok(cfg)
}

/// `reconstruct`'s mesh phase at refined resolution `fine_res`: two-pass marching cubes, the
/// clean-up and the cut to the faces the training cameras see, mapped to world mm. `cameras`:
/// the training cameras in training order (normalised frame), as the run refined them.
fn extract(
    cfg: &RunConfig,
    model: &NeusModel,
    params: &[f32],
    step: u64,
    scene: &Scene,
    cameras: &[Camera],
    fine_res: usize,
) -> anyhow::Result<dtu_eval::mesh::TriMesh> {
    let raw = marching_cubes_of(cfg, model, params, step, fine_res)?;
    let train = training_views(cfg, scene.views.len())?;
    let masked = masked_views(scene, &train, cameras);
    let cameras: Vec<&Camera> = cameras.iter().collect();
    let (_, mut mesh, _, _) = clean_cut(cfg, &raw, &masked, &cameras, scene.normalization.scale);
    to_world(&mut mesh, &scene.normalization);
    Ok(mesh)
}

pub fn run(args: ExportArgs) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let quiet = args.quiet;
    let run = &args.run;
    if !run.is_dir() {
        bail!(
            "{} is not a folder (give a `reconstruct` run folder)",
            run.display()
        );
    }
    // Options first: a bad one costs nothing.
    export::check_texture_size(args.texture_size).map_err(|why| ExportError::Option {
        option: "--texture-size",
        value: args.texture_size.to_string(),
        why,
    })?;
    if let Some(r) = args.resolution {
        if !(2..=MAX_MESH_RES).contains(&r) {
            bail!(
                "--resolution {r} is invalid: must be in 2..={MAX_MESH_RES} grid points per axis"
            );
        }
    }
    let formats = Formats {
        ply: args.format.contains(&Format::Ply),
        obj: args.format.contains(&Format::Obj),
        glb: args.format.contains(&Format::Glb),
    };
    let cfg = run_config(run)?;
    let ckpt = run.join("checkpoint.safetensors");
    if !ckpt.is_file() {
        bail!(
            "no checkpoint {}: the run has not saved its trained network (still at its first \
             steps, or not a run folder); nothing to export",
            ckpt.display()
        );
    }
    let out = args.out.clone().unwrap_or_else(|| run.join("export"));
    if args.resolution.is_some()
        && formats.ply
        && out.canonicalize().ok() == run.canonicalize().ok()
    {
        bail!(
            "--out {} with --resolution would replace the run's scored mesh.ply; choose another \
             --out",
            out.display()
        );
    }

    let scene_ref = resolve_scene(&cfg.scene, &cfg.data_root, quiet)?;
    let scene = Scene::load(
        &scene_ref.dir,
        &LoadOptions {
            downscale: cfg.data.downscale,
            masks: cfg.data.masks,
        },
    )?;
    let model = NeusModel::new(cfg.model.clone())?;
    let train = training_views(&cfg, scene.views.len())?;
    // With pose refinement the checkpoint holds the corrections; the clean-up judges the masks
    // and the visibility with the refined cameras, as `reconstruct` does.
    let refined = cfg.train.pose_refine.enabled.then_some(train.len());
    let state = checkpoint::load(
        &ckpt,
        &model.layout,
        &cfg.train.optimizer,
        &cfg.training_hash(),
        None,
        refined,
    )
    .with_context(|| {
        format!(
            "the checkpoint does not belong to {}",
            run.join("config.toml").display()
        )
    })?;
    if state.step < cfg.train.iterations || !run.join("metrics.json").is_file() {
        say(
            false,
            format!(
                "warning: {} holds an unfinished run (step {} of {}); exporting its checkpoint",
                run.display(),
                state.step,
                cfg.train.iterations
            ),
        );
    }
    let cameras = trained_cameras(&scene, &train, state.pose.as_ref());
    let sched = model.config.inference_schedule(state.step);
    let field = SurfaceField::new(&model, &state.params, sched)?.with_view(
        args.view_direction
            .map_or(cfg.export.view_direction, Into::into),
        &export::camera_centres(&scene, &train),
    );

    let t_mesh = Instant::now();
    let (mesh, mesh_src) = match args.resolution {
        Some(res) => (
            extract(
                &cfg,
                &model,
                &state.params,
                state.step,
                &scene,
                &cameras,
                res,
            )?,
            PathBuf::from(format!("the mesh extracted at resolution {res}")),
        ),
        None => {
            let p = run.join(export::MESH_PLY);
            (dtu_eval::ply::read_mesh(&p)?, p)
        }
    };
    let mesh_s = t_mesh.elapsed().as_secs_f64();
    let t_col = Instant::now();
    let colored = export::color_mesh(&field, &mesh, &scene.normalization, &mesh_src)?;
    let color_s = t_col.elapsed().as_secs_f64();
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut written = Vec::new();
    if formats.ply {
        export::ply::write_colored_ply(&out.join(export::MESH_PLY), &colored)?;
        written.push(export::MESH_PLY.to_string());
    }
    let textured = if formats.obj || formats.glb || args.check {
        let t = export::texture_mesh(&field, &colored, &scene.normalization, args.texture_size)?;
        if formats.obj || formats.glb {
            let cams: Vec<Camera> = scene.views.iter().map(|v| v.camera.clone()).collect();
            export::write_textured(
                &out,
                &t,
                &formats,
                export::scene_up(&cams),
                scene.normalization.center,
            )?;
            if formats.obj {
                written.extend(
                    [
                        export::TEXTURED_OBJ,
                        export::TEXTURED_MTL,
                        export::TEXTURED_PNG,
                    ]
                    .map(String::from),
                );
            }
            if formats.glb {
                written.push(export::TEXTURED_GLB.into());
            }
        }
        Some(t)
    } else {
        None
    };
    let t_turn = Instant::now();
    let frames = cfg.export.turntable_frames;
    if frames > 0 {
        let n = &scene.normalization;
        let world: Vec<Camera> = scene
            .views
            .iter()
            .map(|v| v.camera.denormalized(n.scale, &n.center.into()))
            .collect();
        let orbit = export::turntable::Orbit::around(&world, &mesh, n.center);
        let s = match &textured {
            Some(t) => export::raycast::MeshScene::textured(t),
            None => export::raycast::MeshScene::vertex_colored(&colored),
        };
        export::turntable::write_turntable(
            &out.join(export::TURNTABLE_GIF),
            &s,
            &orbit,
            frames,
            cfg.export.turntable_size,
            model.config.render.background,
        )?;
        written.push(export::TURNTABLE_GIF.into());
    }
    let turn_s = t_turn.elapsed().as_secs_f64();

    say(
        quiet,
        format!(
            "{}: {} vertices, {} faces; colours in {color_s:.2} s ({} fallbacks){}",
            mesh_src.display(),
            mesh.vertices.len(),
            mesh.faces.len(),
            colored.fallbacks,
            if args.resolution.is_some() {
                format!(", extracted in {mesh_s:.1} s")
            } else {
                String::new()
            }
        ),
    );
    if let Some(t) = &textured {
        let s = &t.uv.stats;
        say(
            quiet,
            format!(
                "texture {0}×{0}: unwrap {1:.2} s ({2} charts, {3:.1} % of the atlas used, {4:.3} UV \
                 vertices per vertex, padding {5}); bake {6:.2} s ({7} texels, {8} by dilation, {9} \
                 fallbacks)",
                args.texture_size,
                s.seconds,
                s.charts,
                100.0 * s.utilization,
                s.vertex_ratio,
                s.padding,
                t.texture.seconds,
                t.texture.baked,
                t.texture.dilated,
                t.texture.fallbacks
            ),
        );
    }
    let mut summary = serde_json::json!({
        "run": run.display().to_string(),
        "mesh": mesh_src.display().to_string(),
        "vertices": mesh.vertices.len(),
        "faces": mesh.faces.len(),
        "step": state.step,
        "color_fallbacks": colored.fallbacks,
        "seconds": { "mesh": mesh_s, "colors": color_s, "turntable": turn_s },
        "written": written,
    });
    if let Some(t) = &textured {
        summary["texture"] = serde_json::json!({
            "size": args.texture_size,
            "unwrap": t.uv.stats,
            "bake_seconds": t.texture.seconds,
            "texels": t.texture.baked,
            "dilated": t.texture.dilated,
            "fallbacks": t.texture.fallbacks,
        });
    }

    if args.check {
        let k = cfg.data.render_downscale as usize;
        let bg = model.config.render.background;
        let heldout = cfg.data.holdout.indices(scene.views.len())?;
        if heldout.is_empty() {
            bail!("--check needs held-out views, and the run held none out (data.holdout = 0)");
        }
        let views: Vec<check::CheckView> = heldout
            .iter()
            .map(|&v| {
                let view = &scene.views[v];
                let mut truth = view.image.downscaled(k);
                if let Some(m) = view.mask.as_ref().filter(|_| cfg.data.masks) {
                    let m = m.downscaled(k);
                    for (px, mv) in truth.data.chunks_exact_mut(3).zip(&m.data) {
                        for (c, b) in px.iter_mut().zip(bg) {
                            *c = *c * mv + b * (1.0 - mv);
                        }
                    }
                }
                check::CheckView {
                    view: v,
                    camera: view.camera.downscaled(k as u32),
                    truth,
                }
            })
            .collect();
        let dir = out.join("check");
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let rt = check::round_trip(
            &check::CheckInputs {
                field: &field,
                model: &model,
                params: &state.params,
                occupancy: model.config.render.occupancy.enabled.then_some(&state.occ),
                sched,
                normalization: &scene.normalization,
                colored: &colored,
                textured: textured.as_ref(),
                save_dir: Some(&dir),
            },
            &views,
        )?;
        println!(
            "view  network  textured  vertex-colours  along-rays  (PSNR dB against the held-out truth)"
        );
        for v in &rt.views {
            println!(
                "{:4}  {:7.2}  {:8.2}  {:14.2}  {:10.2}",
                v.view,
                v.network,
                v.textured.unwrap_or(f64::NAN),
                v.vertex_colors,
                v.along_rays
            );
        }
        println!(
            "mean  {:7.2}  {:8.2}  {:14.2}  {:10.2}   gaps: textured {:.2} dB (bar 2), vertex colours {:.2} dB (bar 4)",
            rt.network,
            rt.textured.unwrap_or(f64::NAN),
            rt.vertex_colors,
            rt.along_rays,
            rt.textured_gap.unwrap_or(f64::NAN),
            rt.vertex_gap
        );
        summary["check"] = serde_json::to_value(&rt)?;
    }
    summary["seconds"]["total"] = serde_json::json!(t0.elapsed().as_secs_f64());
    let p = out.join("export.json");
    dtu_eval::atomic::write_atomic(&p, serde_json::to_string_pretty(&summary)?.as_bytes())
        .with_context(|| format!("cannot write {}", p.display()))?;
    say(
        quiet,
        format!(
            "wrote {} into {} in {:.1} s",
            written.join(", "),
            out.display(),
            t0.elapsed().as_secs_f64()
        ),
    );
    Ok(())
}
