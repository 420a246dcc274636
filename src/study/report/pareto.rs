//! The accuracy-against-time study: one point per variant and the Pareto front.

use super::super::stats;
use super::layout::{m_train, Layout, Row};
use super::records::RunRecord;
use serde::Serialize;

/// One pareto variant, averaged over seeds (and scenes).
#[derive(Clone, Debug, Serialize)]
pub(super) struct ParetoRow {
    pub(super) condition: String,
    pub(super) n: usize,
    pub(super) chamfer_mean: Option<f64>,
    pub(super) chamfer_std: Option<f64>,
    pub(super) time_to_mesh_mean: Option<f64>,
    pub(super) train_mean: Option<f64>,
    pub(super) mesh_mean: Option<f64>,
    pub(super) on_front: bool,
}

pub(super) fn pareto_points(lay: &Layout<'_>) -> Vec<ParetoRow> {
    let mut rows: Vec<ParetoRow> = lay
        .conditions
        .iter()
        .map(|c| {
            let row = Row {
                label: String::new(),
                condition: c.clone(),
                scene: None,
            };
            let recs: Vec<&RunRecord> = lay.records.iter().filter(|r| &r.condition == c).collect();
            let ch: Vec<f64> = recs.iter().filter_map(|r| r.chamfer_sum).collect();
            let tm: Vec<f64> = recs
                .iter()
                .filter(|r| r.chamfer_sum.is_some())
                .map(|r| r.time_to_mesh)
                .collect();
            let tr: Vec<f64> = recs.iter().filter_map(|r| m_train(r)).collect();
            let me: Vec<f64> = recs.iter().map(|r| r.time_mesh).collect();
            let _ = &row;
            ParetoRow {
                condition: c.clone(),
                n: ch.len(),
                chamfer_mean: stats::mean(&ch),
                chamfer_std: stats::sample_std(&ch),
                time_to_mesh_mean: stats::mean(&tm),
                train_mean: stats::mean(&tr),
                mesh_mean: stats::mean(&me),
                on_front: false,
            }
        })
        .collect();
    let pts: Vec<Option<(f64, f64)>> = rows
        .iter()
        .map(|r| Some((r.time_to_mesh_mean?, r.chamfer_mean?)))
        .collect();
    let front = pareto_front(&pts);
    for (r, f) in rows.iter_mut().zip(front) {
        r.on_front = f;
    }
    rows
}

/// Which points are on the Pareto front of (time, error), both to be minimised: no other point
/// is at least as good in both and strictly better in one. `None` points are never on it.
pub fn pareto_front(pts: &[Option<(f64, f64)>]) -> Vec<bool> {
    pts.iter()
        .map(|p| {
            let Some((t, e)) = *p else { return false };
            !pts.iter()
                .flatten()
                .any(|&(t2, e2)| t2 <= t && e2 <= e && (t2 < t || e2 < e))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pareto_front_matches_brute_force_definition() {
        let pts = [
            Some((1.0, 5.0)),
            Some((2.0, 3.0)),
            Some((3.0, 3.0)), // dominated by (2, 3)
            Some((4.0, 1.0)),
            None,
            Some((5.0, 2.0)), // dominated by (4, 1)
            Some((1.0, 5.0)), // a tie with the first: neither dominates
        ];
        assert_eq!(
            pareto_front(&pts),
            [true, true, false, true, false, false, true]
        );
    }
}
