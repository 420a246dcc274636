//! The scene's ground truth as a run uses it: where the DTU point clouds are
//! ([`find_gt`]), and the geometry figures judged against the simulator's truth in `meta.json`
//! ([`GeometryVsTruth`]: the Chamfer floor, the ratio to it, the genus against the true one).

use super::{ChamferMetrics, EvalConfig, ResolvedScene, RunConfig};
use crate::mesh::TopologyReport;
use crate::sim;
use std::path::PathBuf;

/// Finds ground truth for the scene: `eval.gt_root` (+ scan) or the scene folder itself
/// (synthetic scenes). Returns `(root, scan)` or a note saying why there is none.
pub(super) fn find_gt(
    cfg: &RunConfig,
    scene: &ResolvedScene,
    truth: &sim::SceneTruth,
) -> Result<(PathBuf, u32), String> {
    let meta_scan = truth.scan;
    let name_scan = || {
        let digits: String = scene
            .name
            .trim_start_matches("dtu_")
            .trim_start_matches("scan")
            .chars()
            .take_while(|c| c.is_ascii_digit())
            .collect();
        digits.parse::<u32>().ok()
    };
    let scan = cfg
        .eval
        .scan
        .or(meta_scan)
        .or_else(name_scan)
        .ok_or_else(|| format!("no scan number for scene '{}' (set eval.scan)", scene.name))?;
    let root = cfg
        .eval
        .gt_root
        .clone()
        .unwrap_or_else(|| scene.dir.clone());
    let paths = dtu_eval::gt::GtPaths::new(&root, scan);
    for p in [&paths.points, &paths.obs_mask, &paths.plane] {
        if !p.is_file() {
            return Err(format!(
                "no ground truth: {} is missing (set eval.gt_root to DTU's 'SampleSet/MVS Data')",
                p.display()
            ));
        }
    }
    Ok((root, scan))
}

/// Whether the run is scored against the scene's own truth (the floor's, `meta.json`'s): not
/// with `eval.gt_root` or `eval.scan` pointing elsewhere.
pub(super) fn own_truth(truth: &sim::SceneTruth, eval: &EvalConfig, scene: &ResolvedScene) -> bool {
    eval.gt_root.as_ref().is_none_or(|r| *r == scene.dir)
        && eval.scan.is_none_or(|s| truth.scan == Some(s))
}

/// The geometry figures judged against the scene's truth (`meta.json`, [`sim::SceneTruth`]).
pub(super) struct GeometryVsTruth {
    pub(super) floor_mm: Option<f64>,
    pub(super) ratio_to_floor: Option<f64>,
    /// Genus of the written mesh's largest component (`None` for an empty mesh).
    pub(super) genus: Option<i64>,
    pub(super) gt_genus: Option<i64>,
    pub(super) genus_matches: Option<bool>,
}

impl GeometryVsTruth {
    /// The floor applies only when the scene is scored against its own ground truth (the
    /// floor's): not with `eval.gt_root` or `eval.scan` pointing elsewhere. It is reported even
    /// when there is no Chamfer figure (an empty mesh); the ratio then is `None`. An empty mesh
    /// has no genus, so it does not match a known one.
    pub(super) fn new(
        truth: &sim::SceneTruth,
        eval: &EvalConfig,
        scene: &ResolvedScene,
        chamfer: Option<&ChamferMetrics>,
        topo: &TopologyReport,
    ) -> Self {
        let own_gt = own_truth(truth, eval, scene);
        let floor_mm = truth
            .floor
            .filter(|_| own_gt)
            .map(|f| f.chamfer_sum)
            .filter(|f| *f > 0.0);
        let ratio_to_floor = match (chamfer, floor_mm) {
            (Some(c), Some(f)) => Some(c.chamfer_sum / f),
            _ => None,
        };
        let genus = (topo.faces > 0).then_some(topo.largest_genus);
        Self {
            floor_mm,
            ratio_to_floor,
            genus,
            gt_genus: truth.genus,
            genus_matches: truth.genus.map(|g| genus == Some(g)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruct::SceneKind;

    #[test]
    fn geometry_is_judged_only_against_the_scenes_own_truth() {
        let scene = ResolvedScene {
            dir: PathBuf::from("/scenes/torus"),
            name: "torus".into(),
            kind: SceneKind::Folder,
        };
        let truth = sim::SceneTruth {
            scan: Some(102),
            genus: Some(1),
            floor: Some(sim::Floor {
                chamfer_sum: 0.25,
                mean_d2s: 0.15,
                mean_s2d: 0.10,
            }),
        };
        let chamfer = ChamferMetrics {
            mean_d2s: 0.4,
            mean_s2d: 0.6,
            overall: 0.5,
            chamfer_sum: 1.0,
            gt_root: scene.dir.display().to_string(),
            scan: 102,
        };
        let torus = TopologyReport {
            vertices: 4,
            faces: 8,
            edges: 12,
            boundary_edges: 0,
            non_manifold_edges: 0,
            misoriented_edges: 0,
            degenerate_faces: 0,
            unreferenced_vertices: 0,
            components: 2,
            euler_characteristic: 0,
            boundary_loops: 0,
            genus: 3,
            largest_genus: 1,
        };
        let eval = EvalConfig::default();
        let g = GeometryVsTruth::new(&truth, &eval, &scene, Some(&chamfer), &torus);
        assert_eq!((g.floor_mm, g.ratio_to_floor), (Some(0.25), Some(4.0)));
        // The largest component decides, not the total genus over components.
        assert_eq!(
            (g.genus, g.gt_genus, g.genus_matches),
            (Some(1), Some(1), Some(true))
        );
        // Other ground truth: no floor, no ratio; the genus is the object's and still compares.
        for eval in [
            EvalConfig {
                gt_root: Some("/dtu".into()),
                ..EvalConfig::default()
            },
            EvalConfig {
                scan: Some(24),
                ..EvalConfig::default()
            },
        ] {
            let g = GeometryVsTruth::new(&truth, &eval, &scene, Some(&chamfer), &torus);
            assert_eq!((g.floor_mm, g.ratio_to_floor), (None, None));
            assert_eq!(g.genus_matches, Some(true));
        }
        // An empty mesh: the floor is reported, no ratio, and no genus to match.
        let empty = TopologyReport {
            faces: 0,
            largest_genus: 0,
            ..torus
        };
        let g = GeometryVsTruth::new(&truth, &eval, &scene, None, &empty);
        assert_eq!((g.floor_mm, g.ratio_to_floor), (Some(0.25), None));
        assert_eq!((g.genus, g.genus_matches), (None, Some(false)));
        // A scene that knows nothing (real DTU): everything unknown, nothing false.
        let g = GeometryVsTruth::new(
            &sim::SceneTruth::default(),
            &eval,
            &scene,
            Some(&chamfer),
            &torus,
        );
        assert_eq!(
            (g.floor_mm, g.ratio_to_floor, g.gt_genus, g.genus_matches),
            (None, None, None, None)
        );
    }
}
