//! Stage 1, *prepare*: the scene resolved and loaded, the training set (held-out views, views
//! fraction, degradation, augmentation), the model, and the shape training starts from (the
//! sphere, or the masks' visual hull). Nothing in the output folder is touched here, so a bad
//! input is refused before a `--force` could cost anything.

use super::output::check_output;
use super::scene_ref::{resolve_scene, ResolvedScene};
use super::{output_dir, say, ReconstructError, RunConfig, RunOptions};
use crate::augment::{degrade_views, views_fraction, AugSampler};
use crate::render::model::NeusModel;
use crate::render::rays::ray_aabb;
use crate::render::BackgroundKind;
use crate::scene::{Camera, GrayImage, LoadOptions, RgbImage, Scene};
use crate::train::hull::{self, HullError, HullSdf, InitKind};
use crate::train::TrainData;
use std::path::PathBuf;
use std::time::Instant;

/// Everything a run trains on, loaded and validated.
pub(super) struct Prepared {
    pub scene_ref: ResolvedScene,
    pub scene: Scene,
    /// The run folder (not created yet).
    pub out: PathBuf,
    /// Held-out view indices (sorted).
    pub heldout: Vec<usize>,
    /// Training view indices, in training order.
    pub train_idx: Vec<usize>,
    pub data: TrainData,
    pub model: NeusModel,
    /// Every training view has a mask and the run uses masks.
    pub all_masked: bool,
    /// The SDF the start is fitted to (the visual hull), when the start is the hull.
    pub hull_target: Option<HullSdf>,
    /// `train.init.kind = "sphere_or_hull"`: the share of the init sphere inside the hull.
    pub sphere_cover: Option<f64>,
    /// FNV-1a 64 of what training reads (cameras, images, masks), hex: a resumed run must see
    /// the inputs it started with.
    pub input_digest: String,
    /// Seconds spent loading the scene and preparing the training set.
    pub load_secs: f64,
    pub prepare_secs: f64,
}

impl Prepared {
    /// The training cameras (normalised frame), in training order.
    pub fn cameras(&self) -> Vec<&Camera> {
        self.train_idx
            .iter()
            .map(|&i| &self.scene.views[i].camera)
            .collect()
    }

    /// The training views that have a mask, with their imported cameras: the visual hull
    /// carves them ([`super::extract::masked_views`]).
    pub fn masked_views(&self) -> Vec<(&Camera, &GrayImage)> {
        super::extract::masked_views(&self.scene, &self.train_idx, self.cameras())
    }
}

/// The training views of a scene of `n` views (indices into `Scene::views`, in training order):
/// every view not held out (`data.holdout`), less those `data.views_fraction` leaves out (a draw
/// seeded by `seed`, so `export` and a resumed run see the same set).
pub fn training_views(cfg: &RunConfig, n: usize) -> Result<Vec<usize>, ReconstructError> {
    let heldout = cfg.data.holdout.indices(n)?;
    let candidates: Vec<usize> = (0..n).filter(|i| !heldout.contains(i)).collect();
    let keep = views_fraction(candidates.len(), cfg.data.views_fraction, cfg.seed)?;
    Ok(keep.iter().map(|&k| candidates[k]).collect())
}

/// Stage 1 (see the module doc).
pub(super) fn prepare(cfg: &RunConfig, opts: &RunOptions) -> Result<Prepared, ReconstructError> {
    let (t, quiet) = (Instant::now(), opts.quiet);
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
    let load_secs = t.elapsed().as_secs_f64();
    say(
        quiet,
        format!(
            "loaded {} views of {} ({}×{}) in {load_secs:.1} s → {}",
            scene.views.len(),
            scene_ref.dir.display(),
            scene.views[0].image.width,
            scene.views[0].image.height,
            out.display()
        ),
    );

    let t = Instant::now();
    let heldout = cfg.data.holdout.indices(scene.views.len())?;
    let train_idx = training_views(cfg, scene.views.len())?;
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
    let cameras: Vec<Camera> = train_idx
        .iter()
        .map(|&i| scene.views[i].camera.clone())
        .collect();
    check_rays_meet_region(&cameras, cfg.model.render.radius)?;
    let input_digest = digest(&scene, &train_idx);
    let all_masked = cfg.data.masks && masks.is_some();
    if !all_masked && cfg.model.background.kind == BackgroundKind::None {
        eprintln!(
            "warning: training without masks and without a learned background: the field \
             must explain the whole image, background included, inside the object's sphere, \
             which costs the surface dearly; set `--set model.background.kind=\"nerfpp\"` (a \
             NeRF++ background outside the sphere, as NeuS trains without masks)"
        );
    }
    let sampler = AugSampler::new(images, &cfg.augment)?;
    let data = TrainData::new(&cameras, sampler, masks, cfg.model.render.background)?;
    let model = NeusModel::new(cfg.model.clone())?;
    let mut prepared = Prepared {
        scene_ref,
        scene,
        out,
        heldout,
        train_idx,
        data,
        model,
        all_masked,
        hull_target: None,
        sphere_cover: None,
        input_digest,
        load_secs,
        prepare_secs: 0.0,
    };
    let (target, cover) = initial_shape(cfg, &prepared, quiet)?;
    prepared.hull_target = target;
    prepared.sphere_cover = cover;
    prepared.prepare_secs = t.elapsed().as_secs_f64();
    Ok(prepared)
}

/// The shape the SDF starts from (`train::hull`): `(the visual hull's SDF when the start is the
/// hull, the hull's cover of the init sphere for `sphere_or_hull`)`. A hull the masks carve
/// away entirely is an input error, raised here before anything is written.
fn initial_shape(
    cfg: &RunConfig,
    p: &Prepared,
    quiet: bool,
) -> Result<(Option<HullSdf>, Option<f64>), ReconstructError> {
    let ic = &cfg.train.init;
    let kind = ic.kind;
    if kind == InitKind::VisualHull && !p.all_masked {
        return Err(HullError::NoMasks("some training views have no mask").into());
    }
    if kind == InitKind::Sphere || !p.all_masked {
        return Ok((None, None));
    }
    let r = p.model.config.render.radius;
    let visual = hull::carve(&p.masked_views(), r, ic.resolution);
    let sphere_cover = (kind == InitKind::SphereOrHull).then(|| {
        let sr = p.model.config.field.sdf.sphere_init_radius;
        hull::sphere_cover(&visual, ic.resolution, r, sr)
    });
    let init_hull = match kind {
        InitKind::Sphere => false,
        InitKind::Auto | InitKind::VisualHull => true,
        InitKind::SphereOrHull => sphere_cover.is_some_and(|c| c < ic.sphere_cover_min),
    };
    if let Some(c) = sphere_cover {
        say(
            quiet,
            format!(
                "init: the visual hull covers {:.1} % of the init sphere (threshold {:.1} %): {} \
                 start",
                100.0 * c,
                100.0 * ic.sphere_cover_min,
                if init_hull { "hull" } else { "sphere" }
            ),
        );
    }
    let target = if init_hull {
        Some(HullSdf::from_occupancy(&visual, ic.resolution, r)?)
    } else {
        None
    };
    Ok((target, sphere_cover))
}

/// FNV-1a 64 over the training views' camera matrices, image pixels and masks, in training
/// order, hex.
fn digest(scene: &Scene, train_idx: &[usize]) -> String {
    let mut h = crate::util::Fnv1a64::default();
    let mut bytes = Vec::new();
    for &i in train_idx {
        bytes.clear();
        let v = &scene.views[i];
        let c = &v.camera;
        for x in c.k.iter().chain(c.r.iter()).chain(c.center.iter()) {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
        bytes.extend_from_slice(&c.width.to_le_bytes());
        bytes.extend_from_slice(&c.height.to_le_bytes());
        for x in &v.image.data {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
        if let Some(m) = &v.mask {
            for x in &m.data {
                bytes.extend_from_slice(&x.to_le_bytes());
            }
        }
        h.write(&bytes);
    }
    h.hex()
}

/// Refuses a run in which no training ray meets the box `[-r, r]³` of the normalised frame
/// (a grid of 17 × 17 pixels of every camera is tried): the region is not in front of any
/// camera, and training would see nothing.
fn check_rays_meet_region(cameras: &[Camera], r: f32) -> Result<(), ReconstructError> {
    const N: u32 = 17;
    let meets = cameras.iter().any(|c| {
        (0..N * N).any(|k| {
            let u = (k % N) as f64 / (N - 1) as f64 * c.width as f64;
            let v = (k / N) as f64 / (N - 1) as f64 * c.height as f64;
            let (o, d) = c.ray(u, v);
            let f = |x: nalgebra::Vector3<f64>| [x.x as f32, x.y as f32, x.z as f32];
            ray_aabb(f(o), f(d), r).is_some()
        })
    });
    if meets {
        Ok(())
    } else {
        Err(ReconstructError::NothingTrained(format!(
            "no ray of the {} training cameras meets the reconstruction region (the box of \
             half-width {r} about the origin of the normalised frame, which cameras_sphere.npz's \
             scale_mat defines): the object is not in front of the cameras; check the \
             normalisation (for an import, its --roi-center / --roi-radius)",
            cameras.len()
        )))
    }
}
