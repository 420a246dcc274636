//! Stages 4 and 5, *extract* and *clean*: two-pass marching cubes on the trained SDF, then the
//! clean-up of `mesh::clean`, the meshes mapped back to world millimetres through `scale_mat`
//! and written (`mesh.ply`, and `mesh_closed.ply` / `mesh_raw.ply` when the clean-up changed
//! them).

use super::prepare::Prepared;
use super::{io_err, say, ReconstructError, RunConfig};
use crate::mesh::clean::{clean_mesh, cull_unseen_parts, CleanOptions, CleanReport};
use crate::mesh::{extract_two_pass, to_world, McOptions, TopologyReport, TriMesh, TwoPassOptions};
use crate::render::model::NeusModel;
use crate::scene::{Camera, GrayImage, Scene};
use crate::train::checkpoint::TrainState;
use crate::train::pose_refine::PoseState;
use std::path::Path;
use std::time::Instant;

/// The meshes of a run, in world millimetres, with their topology.
pub(super) struct Meshes {
    /// The scored mesh (`mesh.ply`): cleaned, the part the training cameras see.
    pub mesh: TriMesh,
    /// The closed cleaned surface it was cut from (`mesh_closed.ply` when they differ).
    pub closed: TriMesh,
    /// Faces rule 4 cut from `closed` (0: `mesh` is `closed`).
    pub unseen_faces: usize,
    pub clean: Option<CleanReport>,
    /// Topology of the raw marching-cubes mesh, of `closed` and of `mesh`.
    pub topo_raw: TopologyReport,
    pub topo: TopologyReport,
    pub topo_seen: TopologyReport,
    pub secs: f64,
}

/// Stage 4: the raw marching-cubes mesh of the SDF of `state` (normalised frame).
pub(super) fn extract(
    cfg: &RunConfig,
    p: &Prepared,
    state: &TrainState,
) -> Result<TriMesh, ReconstructError> {
    let fine = cfg.mesh.fine_res;
    marching_cubes_of(cfg, &p.model, &state.params, cfg.train.iterations, fine)
}

/// The two-pass marching cubes of `reconstruct` (coarse over the box `[-r, r]³`, then
/// `fine_res` points per axis over the coarse mesh's padded bounds, with the configured closing)
/// on the SDF of `params` with the hash levels active at the end of `iterations` steps. The mesh
/// is in the normalised frame.
pub fn marching_cubes_of(
    cfg: &RunConfig,
    model: &NeusModel,
    params: &[f32],
    iterations: u64,
    fine_res: usize,
) -> Result<TriMesh, ReconstructError> {
    let active = model.config.inference_schedule(iterations).active_levels;
    let r = model.config.render.radius;
    let sdf = |pts: &[[f32; 3]]| model.sdf(params, pts, active);
    let two = extract_two_pass(
        &sdf,
        &TwoPassOptions {
            min: [-r; 3],
            max: [r; 3],
            coarse_res: cfg.mesh.coarse_res,
            fine_res,
            pad_fraction: cfg.mesh.pad_fraction,
            mc: McOptions {
                close_radius: cfg.mesh.close_radius,
                ..McOptions::default()
            },
        },
    )?;
    Ok(two.mesh)
}

/// The clean-up of `reconstruct` on `raw` (normalised frame): rules 1–3 of `mesh::clean` with the
/// masked training views and cameras, then rule 4's cut to the faces that
/// `mesh.clean_min_visible_views` cameras see. `scale`: world mm per normalised unit. Returns
/// `(closed, seen, report, faces cut by rule 4)`; without `mesh.clean`, `raw` twice.
pub fn clean_cut(
    cfg: &RunConfig,
    raw: &TriMesh,
    masked: &[(&Camera, &GrayImage)],
    cameras: &[&Camera],
    scale: f64,
) -> (TriMesh, TriMesh, Option<CleanReport>, usize) {
    if !cfg.mesh.clean {
        return (raw.clone(), raw.clone(), None, 0);
    }
    let (closed, mut rep) = clean_mesh(
        raw,
        masked,
        cameras,
        &CleanOptions {
            min_area_share: cfg.mesh.clean_min_area_share,
            mask_cull: cfg.mesh.clean_mask_cull,
            dilate_px: cfg.mesh.clean_dilate_px,
            frustum_cull: cfg.mesh.clean_mask_cull,
            remove_enclosed: cfg.mesh.clean_enclosed,
        },
    );
    let margin = cfg.mesh.clean_visible_margin_mm / scale;
    let cut = cull_unseen_parts(
        &closed,
        cameras,
        cfg.mesh.clean_min_visible_views,
        margin,
        cfg.mesh.clean_min_area_share,
        cfg.mesh.speck_rule(),
    );
    rep.faces_unseen = cut.faces_unseen;
    rep.unseen_components_removed = cut.unseen_components_removed;
    rep.faces_in_unseen_components = cut.faces_in_unseen_components;
    rep.cut_specks_removed = cut.cut_specks_removed;
    rep.faces_in_cut_specks = cut.faces_in_cut_specks;
    rep.components_after -= cut.unseen_components_removed;
    (cut.closed, cut.seen, Some(rep), cut.faces_unseen)
}

/// The training views `train` (indices into `scene.views`, training order) that have a mask,
/// each with its camera from `cameras` (the same order): what the visual hull carves with and
/// the clean-up culls with.
pub fn masked_views<'a>(
    scene: &'a Scene,
    train: &[usize],
    cameras: impl IntoIterator<Item = &'a Camera>,
) -> Vec<(&'a Camera, &'a GrayImage)> {
    train
        .iter()
        .zip(cameras)
        .filter_map(|(&i, c)| scene.views[i].mask.as_ref().map(|m| (c, m)))
        .collect()
}

/// The cameras (normalised frame) of the training views `train` where training left them:
/// corrected by pose refinement's state `pose` when it ran ([`PoseState::corrected`]), the
/// imported ones otherwise (exactly, also where refinement moved no camera).
pub fn trained_cameras(scene: &Scene, train: &[usize], pose: Option<&PoseState>) -> Vec<Camera> {
    let imported: Vec<Camera> = train
        .iter()
        .map(|&i| scene.views[i].camera.clone())
        .collect();
    match pose {
        Some(ps) => ps.corrected(&imported),
        None => imported,
    }
}

/// Stage 5: the clean-up of `raw` (rules 1–3, then rule 4's cut to what the training cameras
/// see), in world mm, written to `out`. `cameras`: the training cameras in training order
/// (normalised frame), as refined when pose refinement ran: the masks and the visibility are
/// judged where training put each view. An empty result is an error that names the cause.
pub(super) fn clean_and_write(
    cfg: &RunConfig,
    p: &Prepared,
    cameras: &[Camera],
    raw: TriMesh,
    out: &Path,
    quiet: bool,
    t: Instant,
) -> Result<Meshes, ReconstructError> {
    let topo_raw = TopologyReport::of(&raw);
    let scale = p.scene.normalization.scale;
    let masked = masked_views(&p.scene, &p.train_idx, cameras);
    let cameras: Vec<&Camera> = cameras.iter().collect();
    let (mut closed, mut mesh, mut clean, unseen_faces) =
        clean_cut(cfg, &raw, &masked, &cameras, scale);
    let norm = &p.scene.normalization;
    to_world(&mut closed, norm);
    to_world(&mut mesh, norm);
    let topo = TopologyReport::of(&closed);
    let topo_seen = if unseen_faces > 0 {
        TopologyReport::of(&mesh)
    } else {
        topo
    };
    if let Some(rep) = clean.as_mut() {
        rep.components_seen = topo_seen.components;
    }
    let raw_path = out.join("mesh_raw.ply");
    if closed.faces.len() != raw.faces.len() || mesh.faces.is_empty() {
        let mut raw = raw;
        to_world(&mut raw, norm);
        dtu_eval::ply::write_mesh(&raw_path, &raw)?;
    } else if raw_path.is_file() {
        std::fs::remove_file(&raw_path).map_err(io_err(&raw_path))?;
    }
    if mesh.faces.is_empty() {
        return Err(ReconstructError::EmptyMesh(empty_mesh_cause(
            &topo_raw,
            clean.as_ref(),
            &raw_path,
        )));
    }
    let closed_path = out.join("mesh_closed.ply");
    if unseen_faces > 0 {
        dtu_eval::ply::write_mesh(&closed_path, &closed)?;
    } else if closed_path.is_file() {
        std::fs::remove_file(&closed_path).map_err(io_err(&closed_path))?;
    }
    dtu_eval::ply::write_mesh(&out.join("mesh.ply"), &mesh)?;
    let secs = t.elapsed().as_secs_f64();
    say(
        quiet,
        format!(
            "mesh: {} vertices, {} faces in {secs:.1} s",
            mesh.vertices.len(),
            mesh.faces.len()
        ),
    );
    Ok(Meshes {
        mesh,
        closed,
        unseen_faces,
        clean,
        topo_raw,
        topo,
        topo_seen,
        secs,
    })
}

/// Why the scored mesh came out empty, in words.
fn empty_mesh_cause(raw: &TopologyReport, clean: Option<&CleanReport>, raw_path: &Path) -> String {
    if raw.faces == 0 {
        return "the trained SDF never crosses zero inside the region: no surface was recovered \
                (see renders/ of a run with held-out views, and check that the cameras look at \
                the object)"
            .into();
    }
    let kept = clean.map_or(0, |c| c.faces_unseen);
    format!(
        "marching cubes found {} faces, and the clean-up removed all of them{}; the raw mesh is \
         in {}",
        raw.faces,
        if kept > 0 {
            " (no face is seen by enough training cameras: mesh.clean_min_visible_views)"
        } else {
            " (outside the masks, too small, or enclosed)"
        },
        raw_path.display()
    )
}
