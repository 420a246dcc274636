//! `neus-aug stereo-check` (hidden): the depth prior's stereo (`mvs::depth_maps`, with a run's
//! configuration) against the scene's true mesh (`gt_mesh.ply`, written by `synth`). Every depth
//! the stereo gives is compared with the true surface's along the same pixel ray; a depth behind
//! the truth tells the prior that the space in front of it is free, so the field is pushed to
//! carve solid material there.

use anyhow::{bail, Context};
use glam::Vec3A;
use neus_aug::mesh::trace::Tracer;
use neus_aug::reconstruct::{parse_set, resolve, training_views, Preset};
use neus_aug::scene::{LoadOptions, Scene};
use obvhs::triangle::Triangle;
use std::path::PathBuf;

/// The depth prior's stereo against the scene's true mesh (diagnosis hook).
#[derive(Debug, clap::Args)]
pub struct StereoCheckArgs {
    /// A scene folder with `gt_mesh.ply` (one `neus-aug synth` wrote).
    pub scene: PathBuf,
    /// Preset whose `[train.depth.mvs]` and `[data]` keys are used.
    #[arg(long, value_enum, default_value = "fast")]
    pub preset: Preset,
    /// Set a config field (repeatable), e.g. `--set train.depth.mvs.min_consistent=3`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// A stereo depth within this distance of the truth counts as right (mm).
    #[arg(long, default_value_t = 1.0)]
    pub tol_mm: f64,
    /// Also say, for the depths behind the truth, what the prior's photo check
    /// (`train.depth.photo_check`) would do once the field's surface is the true one: keep the
    /// span (the true surface matches across the views better than the depth) or carve it.
    #[arg(long)]
    pub photo: bool,
}

/// Counts of one kind of stereo depth (measured, fusion fill, hole fill).
#[derive(Default)]
struct Tally {
    right: usize,
    behind: usize,
    in_front: usize,
    no_truth: usize,
}

impl Tally {
    fn add(&mut self, t: f64, truth: Option<f64>, tol: f64) {
        match truth {
            None => self.no_truth += 1,
            Some(g) if t > g + tol => self.behind += 1,
            Some(g) if t < g - tol => self.in_front += 1,
            Some(_) => self.right += 1,
        }
    }
    fn line(&self, name: &str) -> String {
        let n = (self.right + self.behind + self.in_front + self.no_truth).max(1) as f64;
        let pc = |k: usize| 100.0 * k as f64 / n;
        format!(
            "{name:<14} {:>8} {:>7.1} % {:>7.1} % {:>7.1} % {:>7.1} %",
            self.right + self.behind + self.in_front + self.no_truth,
            pc(self.right),
            pc(self.behind),
            pc(self.in_front),
            pc(self.no_truth)
        )
    }
}

pub fn run(args: StereoCheckArgs) -> anyhow::Result<()> {
    let mut ov = Vec::new();
    for s in &args.set {
        ov.push(parse_set(s)?);
    }
    let cfg = resolve(Some(args.preset), None, &ov)?;
    let gt_path = args.scene.join("gt_mesh.ply");
    if !gt_path.is_file() {
        bail!(
            "{}: no gt_mesh.ply (the check needs a scene `neus-aug synth` wrote)",
            args.scene.display()
        );
    }
    let scene = Scene::load(
        &args.scene,
        &LoadOptions {
            downscale: cfg.data.downscale,
            masks: cfg.data.masks,
        },
    )?;
    let keep = training_views(&cfg, scene.views.len())?;
    let views: Vec<_> = keep.iter().map(|&i| &scene.views[i]).collect();
    let cameras: Vec<_> = views.iter().map(|v| v.camera.clone()).collect();
    let images: Vec<_> = views.iter().map(|v| v.image.clone()).collect();
    let masks: Option<Vec<_>> = views.iter().map(|v| v.mask.clone()).collect();
    let norm = &scene.normalization;
    let gt = dtu_eval::ply::read_mesh(&gt_path).context("the true mesh")?;
    let to_norm = |p: [f32; 3]| {
        Vec3A::new(
            ((p[0] as f64 - norm.center[0]) / norm.scale) as f32,
            ((p[1] as f64 - norm.center[1]) / norm.scale) as f32,
            ((p[2] as f64 - norm.center[2]) / norm.scale) as f32,
        )
    };
    let tris: Vec<Triangle> = gt
        .faces
        .iter()
        .map(|f| Triangle {
            v0: to_norm(gt.vertices[f[0] as usize]),
            v1: to_norm(gt.vertices[f[1] as usize]),
            v2: to_norm(gt.vertices[f[2] as usize]),
        })
        .collect();
    if tris.is_empty() {
        bail!("{}: the true mesh has no faces", gt_path.display());
    }
    let tracer = Tracer::new(&tris);
    eprintln!(
        "stereo of {} views ({} planes) …",
        cameras.len(),
        cfg.train.depth.mvs.planes
    );
    let maps = neus_aug::mvs::depth_maps(&cfg.train.depth.mvs, &cameras, &images, masks.as_deref());
    let tol = args.tol_mm / norm.scale;
    let photo = args.photo.then(|| {
        let m = cfg.train.depth.photo_mvs();
        neus_aug::mvs::PhotoCost::new(&m, &cameras, &images, masks.as_deref())
    });
    // Depths behind the truth: kept by the photo check, the true surface's cost undefined,
    // above `max_cost`, and matched better by the depth.
    let (mut behind, mut kept, mut undefined, mut above, mut worse) = (0usize, 0, 0, 0, 0);
    let (mut measured, mut fused, mut holes) =
        (Tally::default(), Tally::default(), Tally::default());
    for (v, cam) in cameras.iter().enumerate() {
        let w = maps.width[v];
        for (k, &t) in maps.t[v].iter().enumerate() {
            if !t.is_finite() {
                continue;
            }
            let (x, y) = ((k % w) as f64 + 0.5, (k / w) as f64 + 0.5);
            let (o, d) = cam.ray(x, y);
            let hit = tracer
                .closest(
                    Vec3A::new(o.x as f32, o.y as f32, o.z as f32),
                    Vec3A::new(d.x as f32, d.y as f32, d.z as f32),
                )
                .map(|(i, t)| (i, t as f64));
            if let (Some(pc), Some((i, tg))) = (&photo, hit) {
                if t as f64 > tg + tol {
                    let tri = &tris[i as usize];
                    let n = (tri.v1 - tri.v0).cross(tri.v2 - tri.v0).normalize();
                    // Facing the camera: the outward side the ray sees.
                    let s = if n.dot(Vec3A::new(d.x as f32, d.y as f32, d.z as f32)) > 0.0 {
                        -1.0
                    } else {
                        1.0
                    };
                    let n = [n.x, n.y, n.z].map(|c| (s * c) as f64);
                    let (px, py) = (k % w, k / w);
                    let c = pc.costs(v, px, py, &[(tg, Some(n)), (t as f64, None)]);
                    let (at_truth, at_depth) = (c[0], c[1]);
                    behind += 1;
                    if !cfg.train.depth.photo_carves(at_truth, at_depth) {
                        kept += 1;
                    } else if at_truth.is_nan() {
                        undefined += 1;
                    } else if at_truth > cfg.train.depth.mvs.max_cost {
                        above += 1;
                    } else {
                        worse += 1;
                    }
                }
            }
            let hit = hit.map(|h| h.1);
            let tally = if maps.hole_filled[v][k] {
                &mut holes
            } else if maps.filled[v][k] {
                &mut fused
            } else {
                &mut measured
            };
            tally.add(t as f64, hit, tol);
        }
    }
    println!(
        "stereo depths of {} against its true mesh (tolerance {} mm; behind: the prior would carve \
         solid material in front of the depth)",
        args.scene.display(),
        args.tol_mm
    );
    println!(
        "{:<14} {:>8} {:>9} {:>9} {:>9} {:>9}",
        "depth", "pixels", "right", "behind", "in front", "no truth"
    );
    println!("{}", measured.line("measured"));
    println!("{}", fused.line("fusion fill"));
    println!("{}", holes.line("hole fill"));
    let mut all = Tally::default();
    for t in [&measured, &fused, &holes] {
        all.right += t.right;
        all.behind += t.behind;
        all.in_front += t.in_front;
        all.no_truth += t.no_truth;
    }
    println!("{}", all.line("all"));
    if args.photo {
        let pc = |k: usize| 100.0 * k as f64 / behind.max(1) as f64;
        println!(
            "photo check, with the true surface as the field's: of {behind} depths behind the \
             truth, {kept} ({:.1} %) kept from carving; carved: {undefined} ({:.1} %) with no \
             cost at the truth, {above} ({:.1} %) above max_cost there, {worse} ({:.1} %) \
             matched better at the depth (by more than photo_margin {})",
            pc(kept),
            pc(undefined),
            pc(above),
            pc(worse),
            cfg.train.depth.photo_margin
        );
    }
    Ok(())
}
