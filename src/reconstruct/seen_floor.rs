//! The **seen floor** of a run: the scene's true mesh cut by the clean-up's rule 4
//! ([`crate::mesh::clean`]: a face stays when at least `mesh.clean_min_visible_views` training
//! cameras see its centroid), scored by the same DTU protocol as the run's mesh.
//!
//! The Chamfer floor (`sim::Floor`, `floor_mm` in `metrics.json`) is the whole true mesh scored by
//! the protocol: what a perfect reconstruction would get if it were scored whole. The scored mesh
//! of a run is cut by rule 4, so surface that fewer training cameras see than the rule asks is
//! missing from it whatever the training did: the ground truth keeps every point that some camera
//! sees (`sim::gt`, as DTU's scans hold what the scanner saw), rule 4 keeps what two cameras see.
//! The seen floor is what the perfect reconstruction gets after the same cut, so `chamfer_sum /
//! floor_seen` says how far the training is from what the rig and the rule let it reach, and
//! `floor_seen − floor` what the rule costs on this scene and rig. The cost is small where every
//! surface faces several cameras, and largest on a deep cavity, whose inner wall near the bottom
//! only one camera may see.
//!
//! The visibility test looks at face centroids, so the true mesh is first subdivided
//! ([`crate::mesh::subdivide`]) to edges of at most [`EDGE_MM`] (at most [`MAX_FACES`] faces):
//! the cut then follows the visible region to about a millimetre, as it does on a
//! reconstruction (marching-cubes cells of 0.5–1 mm at the presets' `mesh.fine_res`).

use crate::mesh::clean::{seen_faces, split_unseen, surface_area, SpeckRule};
use crate::mesh::subdivide::subdivide_to;
use crate::mesh::TriMesh;
use crate::scene::dtu::Normalization;
use crate::scene::Camera;
use dtu_eval::error::EvalError;
use dtu_eval::protocol::{evaluate_mesh, GroundTruth};
use dtu_eval::report::DtuParams;
use serde::{Deserialize, Serialize};

/// Longest edge (world mm) the true mesh is subdivided to before the visibility test.
pub const EDGE_MM: f64 = 1.0;
/// Most faces the subdivision may make (the visibility test casts one ray per face and camera).
pub const MAX_FACES: usize = 600_000;

/// Rule 4's settings (`mesh.clean_min_visible_views`, `mesh.clean_visible_margin_mm`,
/// `mesh.clean_min_area_share`, `mesh.clean_specks_by_part`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeenRule {
    pub min_views: usize,
    /// World mm.
    pub margin_mm: f64,
    pub min_area_share: f64,
    /// `mesh.clean_specks_by_part`.
    pub specks: SpeckRule,
}

/// The seen floor (module docs), world mm.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SeenFloor {
    /// Accuracy + completeness of the cut true mesh.
    pub chamfer_sum: f64,
    pub mean_d2s: f64,
    pub mean_s2d: f64,
    /// The rule's `min_views`.
    pub min_views: usize,
    /// Share of the true mesh's area that the cut removes (`0..=1`).
    pub area_share_cut: f64,
    /// Faces of the subdivided true mesh that the rule judged.
    pub faces_judged: usize,
}

/// Cuts `truth_world` (world mm) by rule 4 with `cameras` (the run's training cameras, in the
/// normalised frame of `norm`) and scores what is left by the protocol (`params`, `seed`).
/// `Ok(None)` when the cut leaves nothing to score (no training camera sees the truth).
///
/// The rule judges the subdivided mesh, but an original face whose pieces are all kept (or all
/// cut) is scored as the original face: the protocol samples a triangle on a grid of its own
/// edges, so scoring the subdivided mesh would move the figure by itself (by a few hundredths of
/// a millimetre). Only the faces the cut's edge crosses are scored in pieces, and with
/// no cut the scored mesh is the true mesh itself.
pub fn seen_floor(
    truth_world: &TriMesh,
    norm: &Normalization,
    cameras: &[&Camera],
    rule: &SeenRule,
    gt: &GroundTruth,
    params: &DtuParams,
    seed: u64,
) -> Result<Option<SeenFloor>, EvalError> {
    let (fine, levels) = subdivide_to(truth_world, EDGE_MM, MAX_FACES);
    let fine_n = TriMesh {
        vertices: fine
            .vertices
            .iter()
            .map(|v| norm.to_normalized(v.map(f64::from)).map(|x| x as f32))
            .collect(),
        faces: fine.faces.clone(),
    };
    let seen_fine = seen_faces(
        &fine_n,
        cameras,
        rule.min_views,
        rule.margin_mm / norm.scale,
    );
    // Subdivision keeps the old vertices' indices and puts the 4^levels pieces of face `i`
    // at `i·4^levels ..` (`subdivide_once`), so the two meshes share the vertex list.
    let block = 4usize.pow(levels);
    let faces_judged = fine.faces.len();
    let mut mixed = TriMesh {
        vertices: fine.vertices,
        faces: Vec::with_capacity(truth_world.faces.len()),
    };
    let mut flags = Vec::with_capacity(truth_world.faces.len());
    for (i, f) in truth_world.faces.iter().enumerate() {
        let pieces = i * block..(i + 1) * block;
        let kept = seen_fine[pieces.clone()].iter().filter(|k| **k).count();
        if kept == 0 || kept == block {
            mixed.faces.push(*f);
            flags.push(kept == block);
        } else {
            mixed.faces.extend_from_slice(&fine.faces[pieces.clone()]);
            flags.extend_from_slice(&seen_fine[pieces]);
        }
    }
    let seen = split_unseen(&mixed, &flags, rule.min_area_share, rule.specks).seen;
    if seen.faces.is_empty() {
        return Ok(None);
    }
    let total = surface_area(truth_world);
    let area_share_cut = if seen.faces.len() == truth_world.faces.len() {
        0.0
    } else if total > 0.0 {
        (1.0 - surface_area(&seen) / total).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let e = evaluate_mesh(&seen, gt, params, seed)?;
    Ok(Some(SeenFloor {
        chamfer_sum: e.chamfer_sum(),
        mean_d2s: e.mean_d2s,
        mean_s2d: e.mean_s2d,
        min_views: rule.min_views,
        area_share_cut,
        faces_judged,
    }))
}
