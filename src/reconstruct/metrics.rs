//! What a run reports: the types serialised into `metrics.json` (world mm, seconds, degrees), and
//! read back by the study reports (`study::report::records`). Fields added after the first
//! release carry `#[serde(default)]`, so older records still load; the figures a report needs
//! (configuration hash, Chamfer means, training steps, timings) stay required.

use super::config::Preset;
use super::ResolvedScene;
use serde::{Deserialize, Deserializer, Serialize};

/// Reads a float that JSON may hold as `null`: `serde_json` writes NaN and ±∞ as `null` (a run
/// that reused another's training has no final loss; a perfect render has an infinite PSNR).
fn f64_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// Chamfer figures of the mesh (DTU protocol, world mm).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ChamferMetrics {
    /// Accuracy: mean mesh → GT distance (DTUeval-python `mean_d2s`).
    pub mean_d2s: f64,
    /// Completeness: mean GT → mesh distance (`mean_s2d`).
    pub mean_s2d: f64,
    /// `(acc + comp) / 2`, what DTUeval-python prints as "overall".
    pub overall: f64,
    /// `acc + comp`, what the paper reports.
    pub chamfer_sum: f64,
    /// Ground-truth root and scan used.
    #[serde(default)]
    pub gt_root: String,
    #[serde(default)]
    pub scan: u32,
}

/// PSNR/SSIM of one held-out view.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ViewMetrics {
    pub view: usize,
    #[serde(deserialize_with = "f64_or_nan")]
    pub psnr: f64,
    pub ssim: Option<f64>,
    /// Mean angle (degrees) between rendered and ground-truth normals where both see surface
    /// (`normal_error` module); `None` without a ground-truth mesh in the scene folder.
    #[serde(default)]
    pub normal_error_deg: Option<f64>,
    /// Intersection over union of `opacity > 0.5` and `mask > 0.5` (`None` without a mask).
    pub mask_iou: Option<f64>,
}

/// Seconds per phase.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Timings {
    pub load: f64,
    pub prepare: f64,
    pub train: f64,
    #[serde(default)]
    pub mesh: f64,
    pub eval: f64,
    pub render: f64,
    /// The export step (`crate::export`: coloured `mesh.ply`, turntable, sheet, textured mesh).
    #[serde(default)]
    pub export: f64,
    pub total: f64,
}

/// Training summary.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct TrainSummary {
    pub iterations: u64,
    pub resumed_from: Option<u64>,
    #[serde(default, deserialize_with = "f64_or_nan")]
    pub final_loss: f64,
    #[serde(default, deserialize_with = "f64_or_nan")]
    pub final_train_psnr: f64,
    #[serde(default, deserialize_with = "f64_or_nan")]
    pub final_inv_s: f64,
    #[serde(default)]
    pub skipped_steps: u64,
    #[serde(default)]
    pub rays: u64,
    #[serde(default)]
    pub samples: u64,
    #[serde(default, deserialize_with = "f64_or_nan")]
    pub samples_per_second: f64,
    #[serde(default)]
    pub train_views: usize,
    #[serde(default)]
    pub heldout_views: Vec<usize>,
    /// The visual-hull start, when the run had one (`train.init`); `null` for the sphere init
    /// and for resumed runs (the start happened in the first process).
    #[serde(default)]
    pub hull_init: Option<HullInitSummary>,
    /// `train.init.kind = "sphere_or_hull"`: the share of the init sphere's volume inside the
    /// masks' visual hull, which chose the start (`hull_init` is set when the hull was taken);
    /// absent for the other kinds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sphere_cover: Option<f64>,
    /// The stereo of the depth prior (`train.depth`); absent when off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_maps: Option<crate::mvs::DepthMapsSummary>,
    /// The depth prior at the last step (`train.depth`); absent when off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_last: Option<crate::train::depth::DepthStep>,
    /// The depth prior's automatic switch (`train.depth.auto`): what its check found; absent
    /// when it did not run (the prior asked for, no masks, switched off, or `paper`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_auto: Option<crate::train::depth_auto::AutoCheck>,
    /// Why the automatic switch, on, did not check (its step falls outside the run); absent
    /// otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_auto_skipped: Option<String>,
    /// Error-map sampling at the end of training (`train.error_map`); absent when off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error_map: Option<crate::train::error_map::ErrorMapSummary>,
    /// What pose refinement learned (`train.pose_refine`); absent when off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose_refine: Option<PoseRefineSummary>,
}

/// The corrections pose refinement learned (`train::pose_refine`), over the training views; the
/// refined cameras are in the run folder's `refined/`.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct PoseRefineSummary {
    pub views: usize,
    /// Mean and largest rotation of a correction, degrees.
    pub mean_rotation_deg: f64,
    pub max_rotation_deg: f64,
    /// Mean and largest move of a camera's centre, world units (mm on DTU).
    pub mean_translation: f64,
    pub max_translation: f64,
    /// With the focal learned (`train.pose_refine.focal`): the focal scale `e^φ` learned for each
    /// camera model (views sharing an intrinsic matrix); absent otherwise.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub focal_scale: Vec<f64>,
    /// Mean distance in training pixels (the images' own unless `data.downscale`) by which the
    /// refined training cameras move the projections of the object's region from the imported
    /// ones' (the grid of `truth`): how much refinement changed what the images see.
    #[serde(default)]
    pub moved_px: f64,
    /// Against the true cameras of a scene whose poses were perturbed (`synth
    /// --perturb-poses`): mean error of the training views before and after refinement.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth: Option<PoseTruth>,
    /// With the gate (`train.pose_refine.gate`): the steps listened, whether it decided, the
    /// views it let move and the median of its statistic; absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gate: Option<crate::train::pose_refine::GateSummary>,
}

/// Mean pose error of the training views against the truth (`import::perturb::pose_error`),
/// as imported and as refined: rotation in degrees, centre in world units.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct PoseTruth {
    pub before_rotation_deg: f64,
    pub before_centre: f64,
    pub after_rotation_deg: f64,
    pub after_centre: f64,
    /// Mean distance in pixels between where the true and the imported (refined) cameras put
    /// points of the object's region (`import::perturb::reprojection_px`, a 5³ grid in the
    /// normalised frame's cube of half-side 0.5).
    #[serde(default)]
    pub before_px: f64,
    #[serde(default)]
    pub after_px: f64,
    /// Mean relative error of the focal length `fx_est/fx_true − 1`, percent.
    #[serde(default)]
    pub before_focal_pct: f64,
    #[serde(default)]
    pub after_focal_pct: f64,
}

impl PoseRefineSummary {
    /// Of `state`, with `scale` world units per normalised unit.
    pub fn of(state: &crate::train::pose_refine::PoseState, scale: f64) -> Self {
        let n = state.corrections.len().max(1) as f64;
        let rot: Vec<f64> = state
            .corrections
            .iter()
            .map(|c| c.omega.norm().to_degrees())
            .collect();
        let tr: Vec<f64> = state
            .corrections
            .iter()
            .map(|c| c.t.norm() * scale)
            .collect();
        Self {
            views: state.corrections.len(),
            mean_rotation_deg: rot.iter().sum::<f64>() / n,
            max_rotation_deg: rot.iter().copied().fold(0.0, f64::max),
            mean_translation: tr.iter().sum::<f64>() / n,
            max_translation: tr.iter().copied().fold(0.0, f64::max),
            focal_scale: state.focal_scales(),
            moved_px: 0.0,
            truth: None,
            gate: state.gate.as_ref().map(|g| g.summary()),
        }
    }
}

/// What the visual-hull start did (`train::hull`), in world millimetres.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct HullInitSummary {
    /// Voxels per axis of the hull grid.
    pub resolution: usize,
    /// Share of the grid inside the hull.
    pub inside_share: f64,
    /// Mean |SDF − hull distance| over the first and last fit steps' points (mm).
    pub fit_error_first_mm: f64,
    pub fit_error_last_mm: f64,
    /// Wall time of the fit (s; the carving counts in `timings_s.prepare`).
    pub seconds: f64,
}

/// Mesh summary.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct MeshSummary {
    /// Vertices, faces, boundary and non-manifold edges and components of the scored mesh
    /// (`mesh.ply`: after every clean-up rule, the unseen faces of rule 4 included).
    pub vertices: usize,
    pub faces: usize,
    pub boundary_edges: usize,
    pub non_manifold_edges: usize,
    pub components: usize,
    /// Genus of the closed cleaned mesh (rules 1–3 of `mesh::clean`, before rule 4 cuts the
    /// unseen side away: `mesh_closed.ply`, or `mesh.ply` when rule 4 removed nothing), summed
    /// over its components (`TopologyReport::genus`).
    pub genus: i64,
    /// Faces and boundary edges of that closed cleaned mesh (records before rule 4: 0).
    pub closed_faces: usize,
    pub closed_boundary_edges: usize,
    /// Genus of the closed cleaned mesh's largest component (`TopologyReport::largest_genus`):
    /// what `genus_matches` compares with the ground truth's. `None` for an empty mesh and in
    /// records written before it existed.
    pub largest_genus: Option<i64>,
    /// Genus of the raw marching-cubes mesh: what the SDF itself represents (closed mesh).
    pub raw_genus: i64,
    /// Components of the raw mesh.
    pub raw_components: usize,
    /// Faces of the raw mesh.
    pub raw_faces: usize,
    /// What the clean-up removed (`None` when `mesh.clean = false`).
    pub clean: Option<crate::mesh::clean::CleanReport>,
}

/// Everything `metrics.json` holds.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Metrics {
    #[serde(default)]
    pub scene: ResolvedScene,
    #[serde(default)]
    pub preset: Preset,
    #[serde(default)]
    pub augment: crate::augment::AugMode,
    #[serde(default)]
    pub seed: u64,
    pub config_hash: String,
    /// The scored mesh's (`mesh.ply`) figures; `None` when no ground truth was found (see
    /// `eval_note`).
    pub chamfer: Option<ChamferMetrics>,
    /// The same protocol on the closed cleaned mesh (`mesh_closed.ply`), when rule 4 of
    /// `mesh::clean` cut faces from it: what the surface no camera sees costs.
    #[serde(default)]
    pub chamfer_closed: Option<ChamferMetrics>,
    #[serde(default)]
    pub eval_note: Option<String>,
    pub psnr_heldout: Option<f64>,
    pub ssim_heldout: Option<f64>,
    /// Pixel-weighted mean normal angular error over the held-out views (degrees).
    #[serde(default)]
    pub normal_error_deg: Option<f64>,
    /// Mean silhouette IoU over the held-out views that have masks.
    #[serde(default)]
    pub mask_iou_heldout: Option<f64>,
    /// The scene's Chamfer floor (mm): its true mesh scored by the same protocol, from the
    /// scene's `meta.json` (`sim::Floor`). `None` for scenes without one (real DTU, scenes made
    /// by an older simulator) and when the Chamfer used other ground truth (`eval.gt_root`).
    #[serde(default)]
    pub floor_mm: Option<f64>,
    /// `chamfer.chamfer_sum / floor_mm` (1 would be perfect); `None` when either is missing.
    #[serde(default)]
    pub ratio_to_floor: Option<f64>,
    /// The seen floor (`reconstruct::seen_floor`): the true mesh (`gt_mesh.ply`) cut by rule 4
    /// of the clean-up with this run's training cameras, scored by the same protocol. `None`
    /// where `floor_mm` is, without `gt_mesh.ply`, without rule 4, and in older records.
    #[serde(default)]
    pub floor_seen: Option<super::seen_floor::SeenFloor>,
    /// `chamfer.chamfer_sum / floor_seen.chamfer_sum`; `None` when either is missing.
    #[serde(default)]
    pub ratio_to_floor_seen: Option<f64>,
    /// Genus of the true mesh's largest component (`meta.json`'s `mesh_genus`); `None` unknown.
    #[serde(default)]
    pub gt_genus: Option<i64>,
    /// `mesh.largest_genus == gt_genus` (an empty mesh does not match); `None` when the truth
    /// is unknown.
    #[serde(default)]
    pub genus_matches: Option<bool>,
    #[serde(default)]
    pub heldout: Vec<ViewMetrics>,
    pub train: TrainSummary,
    #[serde(default)]
    pub mesh: MeshSummary,
    pub timings_s: Timings,
    #[serde(default)]
    pub threads: usize,
    #[serde(default)]
    pub version: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn old_records_load_and_the_required_figures_stay_required() {
        // What the first releases wrote, trimmed to what a study needs: it loads, the fields
        // added later take their defaults.
        let old = r#"{"config_hash":"abc","chamfer":{"mean_d2s":0.4,"mean_s2d":0.5,"overall":0.45,
            "chamfer_sum":0.9},"psnr_heldout":31.0,"ssim_heldout":0.98,
            "train":{"iterations":2000,"resumed_from":null},
            "timings_s":{"load":0,"prepare":0,"train":1,"mesh":0,"eval":0,"render":0,"total":1},
            "mesh":{"vertices":3,"faces":1,"boundary_edges":3,"non_manifold_edges":0,"components":1}}"#;
        let m: Metrics = serde_json::from_str(old).unwrap();
        // NaN and ∞ are written as null and read back as NaN.
        let reused = old.replace(
            "\"resumed_from\":null",
            "\"resumed_from\":null,\"final_loss\":null",
        );
        let r: Metrics = serde_json::from_str(&reused).unwrap();
        assert!(r.train.final_loss.is_nan());
        assert_eq!(m.chamfer.as_ref().unwrap().chamfer_sum, 0.9);
        assert_eq!(
            (m.mesh.components, m.mesh.genus, m.train.iterations),
            (1, 0, 2000)
        );
        assert!(m.normal_error_deg.is_none() && m.mesh.clean.is_none());
        // The geometry figures are unknown in old records, not zero or false.
        assert_eq!(
            (m.floor_mm, m.ratio_to_floor, m.gt_genus, m.genus_matches),
            (None, None, None, None)
        );
        assert_eq!(m.mesh.largest_genus, None);
        assert_eq!((m.floor_seen, m.ratio_to_floor_seen), (None, None));
        // A record without its Chamfer sum or its hash is an error, not a zero.
        let bad = old.replace(",\n            \"chamfer_sum\":0.9", "");
        assert!(serde_json::from_str::<Metrics>(&bad).is_err());
        let bad = old.replace("\"config_hash\":\"abc\",", "");
        assert!(serde_json::from_str::<Metrics>(&bad).is_err());
    }
}
