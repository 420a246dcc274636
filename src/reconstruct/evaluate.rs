//! Stage 6, *evaluate*: the DTU Chamfer protocol (`dtu_eval`) on the scored mesh when ground
//! truth is found, the closed surface's figure when rule 4 of the clean-up cut it, the seen
//! floor, and the geometry against the simulator's truth (floor, genus).

use super::extract::Meshes;
use super::prepare::Prepared;
use super::seen_floor::{self, SeenFloor};
use super::truth::{find_gt, own_truth, GeometryVsTruth};
use super::{say, ChamferMetrics, ReconstructError, RunConfig};
use crate::sim;
use dtu_eval::protocol::{evaluate_mesh, DtuEvaluation, GroundTruth};
use dtu_eval::report::DtuParams;
use dtu_eval::TriMesh;
use std::path::Path;
use std::time::Instant;

/// What the evaluation found.
pub(super) struct Evaluation {
    pub chamfer: Option<ChamferMetrics>,
    /// Why there is no Chamfer figure, when there is none.
    pub note: Option<String>,
    pub chamfer_closed: Option<ChamferMetrics>,
    pub floor_seen: Option<SeenFloor>,
    pub ratio_to_floor_seen: Option<f64>,
    pub geometry: GeometryVsTruth,
    /// The scene's true mesh (`gt_mesh.ply`), read once here for the held-out normal error
    /// (`Err`: it could not be read; `None`: not needed or not there).
    pub truth_mesh: Option<Result<TriMesh, dtu_eval::ply::PlyError>>,
    pub secs: f64,
}

/// Stage 6 (see the module doc).
pub(super) fn evaluate(
    cfg: &RunConfig,
    p: &Prepared,
    m: &Meshes,
    out: &Path,
    quiet: bool,
) -> Result<Evaluation, ReconstructError> {
    let t = Instant::now();
    let scene_ref = &p.scene_ref;
    let truth = sim::SceneTruth::read(&scene_ref.dir);
    let truth_path = scene_ref.dir.join("gt_mesh.ply");
    let seen_floor_wanted = cfg.eval.enabled
        && cfg.mesh.clean
        && cfg.mesh.clean_min_visible_views > 0
        && truth.floor.is_some()
        && own_truth(&truth, &cfg.eval, scene_ref);
    let truth_mesh = (truth_path.is_file() && (seen_floor_wanted || !p.heldout.is_empty()))
        .then(|| dtu_eval::ply::read_mesh(&truth_path));
    let (mut chamfer_closed, mut floor_seen) = (None, None);
    let (chamfer, note) = if !cfg.eval.enabled {
        (
            None,
            Some("evaluation disabled (eval.enabled = false)".to_string()),
        )
    } else {
        match find_gt(cfg, scene_ref, &truth) {
            Err(note) => (None, Some(note)),
            Ok((root, scan)) => {
                let gt = GroundTruth::load(&root, scan)?;
                let params = DtuParams::default();
                let e = evaluate_mesh(&m.mesh, &gt, &params, cfg.seed)?;
                if cfg.eval.vis {
                    // DTUeval-python's default `visualize_threshold` (10 mm).
                    dtu_eval::vis::write_dtu(out, scan, &e, &gt.points, 10.0, params.max_dist)?;
                }
                let figures = |e: &DtuEvaluation| ChamferMetrics {
                    mean_d2s: e.mean_d2s,
                    mean_s2d: e.mean_s2d,
                    overall: e.overall(),
                    chamfer_sum: e.chamfer_sum(),
                    gt_root: root.display().to_string(),
                    scan,
                };
                // The closed surface too, when rule 4 cut it: what the unseen side costs.
                if m.unseen_faces > 0 && !m.closed.faces.is_empty() {
                    let c = evaluate_mesh(&m.closed, &gt, &params, cfg.seed)?;
                    chamfer_closed = Some(figures(&c));
                }
                // The seen floor: the true mesh cut by rule 4 with these training cameras. A
                // diagnostic: a true mesh it cannot use costs the figure, not the run.
                let seen = match truth_mesh.as_ref().filter(|_| seen_floor_wanted) {
                    None => Ok(None),
                    Some(Err(e)) => Err(e.to_string().trim_end().to_string()),
                    Some(Ok(gt_mesh)) => {
                        let rule = seen_floor::SeenRule {
                            min_views: cfg.mesh.clean_min_visible_views,
                            margin_mm: cfg.mesh.clean_visible_margin_mm,
                            min_area_share: cfg.mesh.clean_min_area_share,
                            specks: cfg.mesh.speck_rule(),
                        };
                        let (norm, cams) = (&p.scene.normalization, p.cameras());
                        seen_floor::seen_floor(gt_mesh, norm, &cams, &rule, &gt, &params, cfg.seed)
                            .map_err(|e| format!("{}: {e}", truth_path.display()))
                    }
                };
                match seen {
                    Ok(f) => floor_seen = f,
                    Err(e) => eprintln!("warning: no seen floor ({e})"),
                }
                (Some(figures(&e)), None)
            }
        }
    };
    let geometry = GeometryVsTruth::new(&truth, &cfg.eval, scene_ref, chamfer.as_ref(), &m.topo);
    let ratio_to_floor_seen = match (&chamfer, &floor_seen) {
        (Some(c), Some(f)) if f.chamfer_sum > 0.0 => Some(c.chamfer_sum / f.chamfer_sum),
        _ => None,
    };
    let ev = Evaluation {
        chamfer,
        note,
        chamfer_closed,
        floor_seen,
        ratio_to_floor_seen,
        geometry,
        truth_mesh,
        secs: t.elapsed().as_secs_f64(),
    };
    ev.say(quiet);
    Ok(ev)
}

impl Evaluation {
    /// The figures, on the terminal.
    fn say(&self, quiet: bool) {
        match (&self.chamfer, &self.note) {
            (Some(c), _) => say(
                quiet,
                format!(
                    "chamfer: accuracy {:.3} mm, completeness {:.3} mm, sum {:.3} mm (overall \
                     {:.3})",
                    c.mean_d2s, c.mean_s2d, c.chamfer_sum, c.overall
                ),
            ),
            (None, Some(n)) => say(quiet, format!("no evaluation: {n}")),
            _ => {}
        }
        let g = &self.geometry;
        if let (Some(f), Some(r)) = (g.floor_mm, g.ratio_to_floor) {
            say(quiet, format!("floor {f:.3} mm: Chamfer {r:.2}× the floor"));
        }
        if let (Some(f), Some(r)) = (&self.floor_seen, self.ratio_to_floor_seen) {
            say(
                quiet,
                format!(
                    "seen floor {:.3} mm (the truth less the {:.1} % of its area that fewer than \
                     {} training cameras see): Chamfer {r:.2}× it",
                    f.chamfer_sum,
                    100.0 * f.area_share_cut,
                    f.min_views
                ),
            );
        }
        if let Some(gt) = g.gt_genus {
            say(
                quiet,
                format!(
                    "genus of the largest component {} (ground truth {gt})",
                    g.genus
                        .map_or("— (empty mesh)".to_string(), |x| x.to_string())
                ),
            );
        }
    }
}
