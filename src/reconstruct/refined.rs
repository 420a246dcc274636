//! The poses pose refinement learned (`train.pose_refine`), written for reuse: `refined/`
//! in the run folder holds `cameras_sphere.npz` (every view of the scene, the training views at
//! their refined poses, the held-out ones as imported; the scene's `scale_mat`) and a COLMAP
//! text model `sparse/0/{cameras,images,points3D}.txt` of the same cameras (no points), images
//! named like the scene's files. Both are in world units, so a user can train again on them or
//! hand them to COLMAP. Held-out views are rendered at their imported poses.

use super::metrics::{PoseRefineSummary, PoseTruth};
use super::prepare::Prepared;
use super::ReconstructError;
use crate::import::export::colmap_model;
use crate::import::perturb::{mean_pose_error, reprojection_px};
use crate::scene::dtu::write_cameras;
use crate::scene::Camera;
use crate::train::pose_refine::{camera_models, same_model, with_focal_scale, PoseState};
use std::path::Path;

/// Writes `out/refined/` (see the module doc) and returns what the corrections amount to.
/// `downscale`: the factor the run loaded the images at (`data.downscale`).
pub(super) fn write_refined(
    p: &Prepared,
    downscale: u32,
    state: &PoseState,
    out: &Path,
) -> Result<PoseRefineSummary, ReconstructError> {
    let n = p.scene.normalization;
    let offset = n.center.into();
    let train: Vec<Camera> = p.cameras().into_iter().cloned().collect();
    let fixed = state.corrected(&train);
    let imported: Vec<Camera> = p
        .scene
        .views
        .iter()
        .map(|v| v.camera.denormalized(n.scale, &offset))
        .collect();
    let mut world = imported.clone();
    // A learned focal belongs to the camera model: held-out views of a training view's model
    // get it too (their poses stay as imported).
    let (model, _) = camera_models(&train);
    for (w, v) in world.iter_mut().zip(&p.scene.views) {
        if let Some(j) = train.iter().position(|c| same_model(c, &v.camera)) {
            let phi = state.focal.get(model[j]).map_or(0.0, |f| f[0]);
            *w = with_focal_scale(w, phi);
        }
    }
    for (&i, c) in p.train_idx.iter().zip(&fixed) {
        world[i] = c.denormalized(n.scale, &offset);
    }
    // Points of the object's region: a 5³ grid over [-0.5, 0.5]³ of the normalised frame.
    let pts: Vec<nalgebra::Vector3<f64>> = (0..125)
        .map(|i| {
            let g = |k: usize| (k % 5) as f64 * 0.25 - 0.5;
            let x = nalgebra::Vector3::new(g(i), g(i / 5), g(i / 25));
            x * n.scale + offset
        })
        .collect();
    // How far refinement moved what the training images see, in their pixels (before the
    // cameras go back to the images' own resolution below).
    let moved_px = mean_finite(
        p.train_idx
            .iter()
            .map(|&i| reprojection_px(&imported[i], &world[i], &pts)),
    );
    // Back to the images' own pixels when the run downscaled them (`data.downscale`).
    if downscale != 1 {
        for (c, v) in world.iter_mut().zip(&p.scene.views) {
            let (w, h) =
                image::image_dimensions(&v.image_path).map_err(|e| ReconstructError::Output {
                    path: v.image_path.clone(),
                    problem: e.to_string(),
                })?;
            *c = c.upscaled(downscale, w, h);
        }
    }
    let dir = out.join("refined");
    std::fs::create_dir_all(&dir).map_err(super::io_err(&dir))?;
    let refs: Vec<&Camera> = world.iter().collect();
    write_cameras(&dir, &refs, &n)?;
    let names: Vec<String> = p
        .scene
        .views
        .iter()
        .map(|v| {
            v.image_path
                .file_name()
                .map_or_else(String::new, |s| s.to_string_lossy().into_owned())
        })
        .collect();
    let sparse = dir.join("sparse").join("0");
    let problem = |e: crate::import::ImportError| ReconstructError::Output {
        path: sparse.clone(),
        problem: e.to_string(),
    };
    let model = colmap_model(&world, &names, &[]).map_err(problem)?;
    crate::import::colmap::write_text(&model, &sparse).map_err(problem)?;
    let mut summary = PoseRefineSummary::of(state, n.scale);
    summary.moved_px = moved_px;
    let sizes: Vec<(u32, u32)> = world.iter().map(|c| (c.width, c.height)).collect();
    let truth = crate::import::perturb::read_true_cameras(&p.scene.root, &sizes).map_err(|e| {
        ReconstructError::Output {
            path: p.scene.root.clone(),
            problem: e.to_string(),
        }
    })?;
    if let Some(truth) = truth {
        let pick = |cams: &[Camera]| -> Vec<Camera> {
            p.train_idx.iter().map(|&i| cams[i].clone()).collect()
        };
        let t = pick(&truth);
        let before = mean_pose_error(&ref_list(&t), &ref_list(&pick(&imported)));
        let after = mean_pose_error(&ref_list(&t), &ref_list(&pick(&world)));
        let px = |est: &[Camera]| {
            let pairs = t.iter().zip(est);
            mean_finite(pairs.map(|(a, b)| reprojection_px(a, &in_pixels_of(b, a), &pts)))
        };
        let focal_pct = |est: &[Camera]| {
            let pairs = t.iter().zip(est);
            mean_finite(
                pairs.map(|(a, b)| (in_pixels_of(b, a).k[(0, 0)] / a.k[(0, 0)] - 1.0) * 100.0),
            )
        };
        summary.truth = Some(PoseTruth {
            before_focal_pct: focal_pct(&pick(&imported)),
            after_focal_pct: focal_pct(&pick(&world)),
            before_rotation_deg: before.rotation_deg,
            before_centre: before.centre,
            after_rotation_deg: after.rotation_deg,
            after_centre: after.centre,
            before_px: px(&pick(&imported)),
            after_px: px(&pick(&world)),
        });
    }
    Ok(summary)
}

/// The mean of the finite values (a view that sees none of the points gives NaN and is left
/// out); 0 when there are none.
fn mean_finite(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values
        .filter(|v| v.is_finite())
        .fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    sum / n.max(1) as f64
}

/// `est` in the pixels of `truth`'s images (the run may have downscaled its images by an
/// integer factor; `Camera::upscaled` undoes it).
fn in_pixels_of(est: &Camera, truth: &Camera) -> Camera {
    if est.width == truth.width || est.width == 0 {
        est.clone()
    } else {
        est.upscaled(truth.width / est.width, truth.width, truth.height)
    }
}

fn ref_list(v: &[Camera]) -> Vec<&Camera> {
    v.iter().collect()
}
