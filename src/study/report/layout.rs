//! The collected runs arranged by condition, scene, arm and seed: table rows, cells, means,
//! standard deviations and paired differences.

use super::super::grid::arm_name;
use super::super::plan::StudyPlan;
use super::super::stats;
use super::records::RunRecord;
use crate::augment::AugMode;
use serde::Serialize;

/// A row of the tables: one scene of one condition, or (`scene: None`) the mean over scenes.
#[derive(Clone, Debug, Serialize)]
pub(super) struct Row {
    pub(super) label: String,
    pub(super) condition: String,
    pub(super) scene: Option<String>,
}

/// The collected runs arranged by condition, scene, arm and seed.
pub(super) struct Layout<'a> {
    pub(super) plan: &'a StudyPlan,
    pub(super) records: &'a [RunRecord],
    pub(super) conditions: Vec<String>,
    pub(super) scenes: Vec<String>,
    pub(super) arms: Vec<AugMode>,
}

pub(super) fn push_unique<T: PartialEq + Clone>(v: &mut Vec<T>, x: &T) {
    if !v.contains(x) {
        v.push(x.clone());
    }
}

pub(super) type Metric = fn(&RunRecord) -> Option<f64>;

pub(super) fn m_chamfer(r: &RunRecord) -> Option<f64> {
    r.chamfer_sum
}
pub(super) fn m_acc(r: &RunRecord) -> Option<f64> {
    r.accuracy
}
pub(super) fn m_comp(r: &RunRecord) -> Option<f64> {
    r.completeness
}
pub(super) fn m_psnr(r: &RunRecord) -> Option<f64> {
    r.psnr
}
pub(super) fn m_ssim(r: &RunRecord) -> Option<f64> {
    r.ssim
}
pub(super) fn m_train(r: &RunRecord) -> Option<f64> {
    Some(r.time_train).filter(|_| !r.reused_training)
}
pub(super) fn m_mesh_time(r: &RunRecord) -> Option<f64> {
    Some(r.time_to_mesh)
}

impl<'a> Layout<'a> {
    pub(super) fn new(plan: &'a StudyPlan, records: &'a [RunRecord]) -> Self {
        let (mut conditions, mut scenes, mut arms) = (Vec::new(), Vec::new(), Vec::new());
        for r in &plan.runs {
            push_unique(&mut conditions, &r.condition);
            push_unique(&mut scenes, &r.scene_label());
            push_unique(&mut arms, &r.arm);
        }
        Self {
            plan,
            records,
            conditions,
            scenes,
            arms,
        }
    }

    pub(super) fn rows(&self) -> Vec<Row> {
        let mut rows = Vec::new();
        let many_scenes = self.scenes.len() > 1;
        let many_conds = self.conditions.len() > 1;
        for c in &self.conditions {
            for s in &self.scenes {
                let label = match (many_conds, many_scenes) {
                    (false, _) => s.clone(),
                    (true, false) => c.clone(),
                    (true, true) => format!("{c} · {s}"),
                };
                rows.push(Row {
                    label,
                    condition: c.clone(),
                    scene: Some(s.clone()),
                });
            }
            if many_scenes {
                rows.push(Row {
                    label: if many_conds {
                        format!("{c} · mean")
                    } else {
                        "mean".into()
                    },
                    condition: c.clone(),
                    scene: None,
                });
            }
        }
        rows
    }

    /// `(seed, value)` of the runs in one cell, in seed order.
    pub(super) fn cell(&self, cond: &str, scene: &str, arm: AugMode, f: Metric) -> Vec<(u64, f64)> {
        let name = arm_name(arm);
        let mut v: Vec<(u64, f64)> = self
            .records
            .iter()
            .filter(|r| r.condition == cond && r.scene == scene && r.arm == name)
            .filter_map(|r| f(r).map(|x| (r.seed, x)))
            .collect();
        v.sort_by_key(|p| p.0);
        v
    }

    pub(super) fn values(&self, cond: &str, scene: &str, arm: AugMode, f: Metric) -> Vec<f64> {
        self.cell(cond, scene, arm, f)
            .into_iter()
            .map(|p| p.1)
            .collect()
    }

    /// Scenes of `cond` where every arm has at least one value: the mean rows compare like with
    /// like.
    pub(super) fn complete_scenes(&self, cond: &str, f: Metric) -> Vec<&String> {
        self.scenes
            .iter()
            .filter(|s| {
                self.arms
                    .iter()
                    .all(|&a| !self.values(cond, s, a, f).is_empty())
            })
            .collect()
    }

    /// Mean of a row (mean over seeds, or mean over complete scenes of those means).
    pub(super) fn row_mean(&self, row: &Row, arm: AugMode, f: Metric) -> Option<f64> {
        match &row.scene {
            Some(s) => stats::mean(&self.values(&row.condition, s, arm, f)),
            None => {
                let per: Vec<f64> = self
                    .complete_scenes(&row.condition, f)
                    .into_iter()
                    .filter_map(|s| stats::mean(&self.values(&row.condition, s, arm, f)))
                    .collect();
                stats::mean(&per)
            }
        }
    }

    /// Std of a row over seeds; for a mean row, `sqrt(mean of per-scene variances)`.
    pub(super) fn row_std(&self, row: &Row, arm: AugMode, f: Metric) -> Option<f64> {
        match &row.scene {
            Some(s) => stats::sample_std(&self.values(&row.condition, s, arm, f)),
            None => {
                let vars: Vec<f64> = self
                    .complete_scenes(&row.condition, f)
                    .into_iter()
                    .filter_map(|s| stats::sample_std(&self.values(&row.condition, s, arm, f)))
                    .map(|x| x * x)
                    .collect();
                stats::mean(&vars).map(f64::sqrt)
            }
        }
    }

    pub(super) fn row_n(&self, row: &Row, arm: AugMode, f: Metric) -> usize {
        match &row.scene {
            Some(s) => self.values(&row.condition, s, arm, f).len(),
            None => self
                .scenes
                .iter()
                .map(|s| self.values(&row.condition, s, arm, f).len())
                .sum(),
        }
    }

    pub(super) fn planned_n(&self, row: &Row, arm: AugMode) -> usize {
        self.plan
            .runs
            .iter()
            .filter(|r| {
                r.condition == row.condition
                    && r.arm == arm
                    && row.scene.as_ref().is_none_or(|s| *s == r.scene_label())
            })
            .count()
    }

    /// Paired differences `arm − baseline` of a row, one stratum per scene.
    pub(super) fn paired(&self, row: &Row, arm: AugMode, f: Metric) -> Vec<Vec<f64>> {
        let scenes: Vec<&String> = match &row.scene {
            Some(s) => vec![s],
            None => self.scenes.iter().collect(),
        };
        scenes
            .into_iter()
            .map(|s| {
                pairs(
                    &self.cell(&row.condition, s, arm, f),
                    &self.cell(&row.condition, s, AugMode::None, f),
                )
            })
            .collect()
    }

    pub(super) fn has_baseline_and_others(&self) -> bool {
        self.arms.contains(&AugMode::None) && self.arms.len() > 1
    }
}

/// Differences `a − b` of the seeds both have.
pub(super) fn pairs(a: &[(u64, f64)], b: &[(u64, f64)]) -> Vec<f64> {
    a.iter()
        .filter_map(|(s, x)| b.iter().find(|(t, _)| t == s).map(|(_, y)| x - y))
        .collect()
}

/// Every value of a row (all its scenes when `scene` is `None`), in plan order.
pub(super) fn all_values(lay: &Layout<'_>, row: &Row, arm: AugMode, f: Metric) -> Vec<f64> {
    match &row.scene {
        Some(s) => lay.values(&row.condition, s, arm, f),
        None => lay
            .scenes
            .iter()
            .flat_map(|s| lay.values(&row.condition, s, arm, f))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    pub(super) fn pairs_match_seeds() {
        let a = [(0, 1.0), (1, 2.0), (3, 5.0)];
        let b = [(1, 1.5), (0, 0.5), (2, 9.0)];
        assert_eq!(pairs(&a, &b), vec![0.5, 0.5]);
    }
}
