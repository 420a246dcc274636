//! Stage 8, *write*: every stage's figures gathered into `metrics.json`, written last (its
//! presence marks a finished run).

use super::evaluate::Evaluation;
use super::extract::Meshes;
use super::folder::RunFolder;
use super::heldout::Heldout;
use super::prepare::Prepared;
use super::training::Trained;
use super::{say, write_atomic, MeshSummary, Metrics, ReconstructError, RunConfig, Timings};
use std::time::Instant;

/// What stages 3 to 7 produced.
pub(super) struct Stages {
    pub trained: Trained,
    pub meshes: Meshes,
    pub ev: Evaluation,
    pub views: Heldout,
    /// Stage 7b, the exported files (`crate::export`), seconds.
    pub export_secs: f64,
}

/// Stage 8 (see the module doc).
pub(super) fn write_metrics(
    cfg: &RunConfig,
    p: &Prepared,
    folder: &RunFolder,
    s: Stages,
    t_total: Instant,
    quiet: bool,
) -> Result<Metrics, ReconstructError> {
    let Stages {
        trained,
        meshes: m,
        ev,
        views,
        export_secs,
    } = s;
    let timings = Timings {
        load: p.load_secs,
        prepare: p.prepare_secs,
        train: trained.secs,
        mesh: m.secs,
        eval: ev.secs,
        render: views.secs,
        export: export_secs,
        total: t_total.elapsed().as_secs_f64(),
    };
    let g = ev.geometry;
    let metrics = Metrics {
        scene: p.scene_ref.clone(),
        preset: cfg.preset,
        augment: cfg.augment.mode,
        seed: cfg.seed,
        config_hash: folder.hash.clone(),
        chamfer: ev.chamfer,
        eval_note: ev.note,
        psnr_heldout: views.psnr,
        ssim_heldout: views.ssim,
        normal_error_deg: views.normal_error_deg,
        floor_mm: g.floor_mm,
        ratio_to_floor: g.ratio_to_floor,
        floor_seen: ev.floor_seen,
        ratio_to_floor_seen: ev.ratio_to_floor_seen,
        gt_genus: g.gt_genus,
        genus_matches: g.genus_matches,
        mask_iou_heldout: views.mask_iou,
        heldout: views.views,
        train: trained.summary,
        chamfer_closed: ev.chamfer_closed,
        mesh: MeshSummary {
            vertices: m.mesh.vertices.len(),
            faces: m.mesh.faces.len(),
            boundary_edges: m.topo_seen.boundary_edges,
            non_manifold_edges: m.topo_seen.non_manifold_edges,
            components: m.topo_seen.components,
            genus: m.topo.genus,
            closed_faces: m.topo.faces,
            closed_boundary_edges: m.topo.boundary_edges,
            largest_genus: g.genus,
            raw_genus: m.topo_raw.genus,
            raw_components: m.topo_raw.components,
            raw_faces: m.topo_raw.faces,
            clean: m.clean,
        },
        timings_s: timings,
        threads: rayon::current_num_threads(),
        version: env!("CARGO_PKG_VERSION").to_string(),
    };
    let path = folder.out.join("metrics.json");
    write_atomic(
        &path,
        &serde_json::to_string_pretty(&metrics).expect("metrics serialise"),
    )?;
    say(
        quiet,
        format!(
            "done in {:.1} s: {}",
            metrics.timings_s.total,
            path.display()
        ),
    );
    Ok(metrics)
}
