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
use crate::import::perturb::mean_pose_error;
use crate::scene::dtu::write_cameras;
use crate::scene::Camera;
use crate::train::pose_refine::PoseState;
use std::path::Path;

/// Writes `out/refined/` (see the module doc) and returns what the corrections amount to.
pub(super) fn write_refined(
    p: &Prepared,
    state: &PoseState,
    out: &Path,
) -> Result<PoseRefineSummary, ReconstructError> {
    let n = p.scene.normalization;
    let offset = n.center.into();
    let train: Vec<Camera> = p.cameras().into_iter().cloned().collect();
    let fixed = state.corrected(&train);
    let mut world: Vec<Camera> = p
        .scene
        .views
        .iter()
        .map(|v| v.camera.denormalized(n.scale, &offset))
        .collect();
    for (&i, c) in p.train_idx.iter().zip(&fixed) {
        world[i] = c.denormalized(n.scale, &offset);
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
        let imported: Vec<Camera> = p
            .scene
            .views
            .iter()
            .map(|v| v.camera.denormalized(n.scale, &offset))
            .collect();
        let t = pick(&truth);
        let before = mean_pose_error(&ref_list(&t), &ref_list(&pick(&imported)));
        let after = mean_pose_error(&ref_list(&t), &ref_list(&pick(&world)));
        summary.truth = Some(PoseTruth {
            before_rotation_deg: before.rotation_deg,
            before_centre: before.centre,
            after_rotation_deg: after.rotation_deg,
            after_centre: after.centre,
        });
    }
    Ok(summary)
}

fn ref_list(v: &[Camera]) -> Vec<&Camera> {
    v.iter().collect()
}
