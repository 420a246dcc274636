//! What a run reports: the types serialised into `metrics.json` (world mm, seconds, degrees).

use super::config::Preset;
use super::ResolvedScene;
use serde::Serialize;

/// Chamfer figures of the mesh (DTU protocol, world mm).
#[derive(Clone, Debug, Serialize)]
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
    pub gt_root: String,
    pub scan: u32,
}

/// PSNR/SSIM of one held-out view.
#[derive(Clone, Debug, Serialize)]
pub struct ViewMetrics {
    pub view: usize,
    pub psnr: f64,
    pub ssim: Option<f64>,
    /// Mean angle (degrees) between rendered and ground-truth normals where both see surface
    /// (`normal_error` module); `None` without a ground-truth mesh in the scene folder.
    pub normal_error_deg: Option<f64>,
    /// Intersection over union of `opacity > 0.5` and `mask > 0.5` (`None` without a mask).
    pub mask_iou: Option<f64>,
}

/// Seconds per phase.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Timings {
    pub load: f64,
    pub prepare: f64,
    pub train: f64,
    pub mesh: f64,
    pub eval: f64,
    pub render: f64,
    pub total: f64,
}

/// Training summary.
#[derive(Clone, Debug, Default, Serialize)]
pub struct TrainSummary {
    pub iterations: u64,
    pub resumed_from: Option<u64>,
    pub final_loss: f64,
    pub final_train_psnr: f64,
    pub final_inv_s: f64,
    pub skipped_steps: u64,
    pub rays: u64,
    pub samples: u64,
    pub samples_per_second: f64,
    pub train_views: usize,
    pub heldout_views: Vec<usize>,
}

/// Mesh summary.
#[derive(Clone, Debug, Serialize)]
pub struct MeshSummary {
    pub vertices: usize,
    pub faces: usize,
    pub boundary_edges: usize,
    pub non_manifold_edges: usize,
    pub components: usize,
    /// Genus of the written (cleaned) mesh (`TopologyReport::genus`).
    pub genus: i64,
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
#[derive(Clone, Debug, Serialize)]
pub struct Metrics {
    pub scene: ResolvedScene,
    pub preset: Preset,
    pub augment: crate::augment::AugMode,
    pub seed: u64,
    pub config_hash: String,
    /// `None` when no ground truth was found (see `eval_note`).
    pub chamfer: Option<ChamferMetrics>,
    pub eval_note: Option<String>,
    pub psnr_heldout: Option<f64>,
    pub ssim_heldout: Option<f64>,
    /// Pixel-weighted mean normal angular error over the held-out views (degrees).
    pub normal_error_deg: Option<f64>,
    /// Mean silhouette IoU over the held-out views that have masks.
    pub mask_iou_heldout: Option<f64>,
    pub heldout: Vec<ViewMetrics>,
    pub train: TrainSummary,
    pub mesh: MeshSummary,
    pub timings_s: Timings,
    pub threads: usize,
    pub version: String,
}
