//! The geometry against the ground truth: the `hard` grid's `report.md`, and the section other
//! grids' reports add when their runs recorded it.
//!
//! Per scene and arm, mean over seeds: Chamfer, the scene's floor (its true mesh scored by the
//! same protocol, `sim::Floor`), the ratio to the floor, how many runs' largest component has the
//! true genus, components before → after clean-up, the held-out normal error and PSNR, the seen
//! floor (the true mesh cut by rule 4 of the clean-up, `reconstruct::seen_floor`) and the ratio
//! to it; then the suite mean of the ratios, genus on the scenes with holes per arm, and every
//! run.

use super::super::grid::arm_title;
use super::format::{fmt_opt, intro, md_table, paired_section};
use super::layout::{m_chamfer, m_psnr, Layout, Metric, Row};
use super::records::{GeometryRecord, RunRecord};
use super::DiffSummary;
use crate::augment::AugMode;
use serde::Serialize;
use std::fmt::Write as _;

/// The ratio to the floor every scene should stay within ("Chamfer ≤ 4× its floor").
pub(super) const RATIO_TARGET: f64 = 4.0;

fn geo(r: &RunRecord) -> Option<&GeometryRecord> {
    r.geometry.as_ref()
}
fn m_floor(r: &RunRecord) -> Option<f64> {
    geo(r)?.floor_mm
}
fn m_ratio(r: &RunRecord) -> Option<f64> {
    geo(r)?.ratio_to_floor
}
fn m_ratio_seen(r: &RunRecord) -> Option<f64> {
    geo(r)?.ratio_to_floor_seen
}
fn m_normal(r: &RunRecord) -> Option<f64> {
    geo(r)?.normal_error_deg
}
fn m_components_raw(r: &RunRecord) -> Option<f64> {
    geo(r)?.components_raw.map(|c| c as f64)
}
fn m_components(r: &RunRecord) -> Option<f64> {
    geo(r)?.components.map(|c| c as f64)
}

/// One (condition, scene, arm) cell of the geometry table, aggregated over seeds.
#[derive(Clone, Debug, Serialize)]
pub(super) struct GeometryCell {
    pub(super) condition: String,
    pub(super) scene: String,
    pub(super) arm: String,
    /// Runs collected / planned.
    pub(super) n: usize,
    pub(super) planned: usize,
    pub(super) chamfer_mean: Option<f64>,
    pub(super) floor_mm: Option<f64>,
    pub(super) ratio_mean: Option<f64>,
    /// Runs whose largest component has the true genus, of `genus_known` runs with a verdict.
    pub(super) genus_matches: usize,
    pub(super) genus_known: usize,
    /// The reconstructions' genus per seed (seed order), and the truth's.
    pub(super) genus: Vec<Option<i64>>,
    pub(super) gt_genus: Option<i64>,
    pub(super) components_raw_mean: Option<f64>,
    pub(super) components_mean: Option<f64>,
    pub(super) normal_error_mean: Option<f64>,
    pub(super) psnr_mean: Option<f64>,
    /// The seen floor (the same for every seed of a cell: same scene, same training views).
    pub(super) floor_seen_mm: Option<f64>,
    pub(super) ratio_seen_mean: Option<f64>,
}

/// What `summary.json` holds of the geometry (`geometry`).
#[derive(Clone, Debug, Serialize)]
pub(super) struct GeometrySummary {
    pub(super) cells: Vec<GeometryCell>,
    /// Per condition: the mean over scenes of the per-scene mean ratio to the floor (baseline
    /// arm), and over how many scenes.
    pub(super) suite: Vec<SuiteMean>,
}

#[derive(Clone, Debug, Serialize)]
pub(super) struct SuiteMean {
    pub(super) condition: String,
    pub(super) arm: String,
    pub(super) ratio_mean: Option<f64>,
    pub(super) chamfer_mean: Option<f64>,
    pub(super) floor_mean: Option<f64>,
    /// Mean over scenes of the per-scene mean ratio to the seen floor.
    pub(super) ratio_seen_mean: Option<f64>,
    /// Scenes with a ratio, and those whose mean ratio is at most [`RATIO_TARGET`].
    pub(super) scenes: usize,
    pub(super) scenes_within_target: usize,
    /// Median and largest per-scene mean ratio to the floor, and the scene with the largest.
    pub(super) ratio_median: Option<f64>,
    pub(super) ratio_worst: Option<f64>,
    pub(super) worst_scene: Option<String>,
    /// Runs of the arm whose largest component has the true genus, of those with a verdict.
    pub(super) genus_right_runs: usize,
    pub(super) genus_known_runs: usize,
}

/// Median of the finite values of `x` (type-7 quantile at ½: the mean of the two middle values
/// for an even count); `None` when there is none.
fn median(x: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = x.iter().copied().filter(|v| v.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    (!v.is_empty()).then(|| super::super::stats::quantile_sorted(&v, 0.5))
}

/// The arm the suite means are taken over: the baseline when the study has one.
fn suite_arm(lay: &Layout<'_>) -> AugMode {
    if lay.arms.contains(&AugMode::None) {
        AugMode::None
    } else {
        lay.arms[0]
    }
}

fn records_of<'a>(
    lay: &'a Layout<'_>,
    cond: &str,
    scene: &str,
    arm: AugMode,
) -> Vec<&'a RunRecord> {
    let name = super::super::grid::arm_name(arm);
    let mut v: Vec<&RunRecord> = lay
        .records
        .iter()
        .filter(|r| r.condition == cond && r.scene == scene && r.arm == name)
        .collect();
    v.sort_by_key(|r| r.seed);
    v
}

/// Every planned (condition, scene, arm) cell in plan order, aggregated.
pub(super) fn summarise(lay: &Layout<'_>) -> GeometrySummary {
    let mut cells = Vec::new();
    let mut suite = Vec::new();
    let sa = suite_arm(lay);
    for c in &lay.conditions {
        for s in &lay.scenes {
            for &a in &lay.arms {
                let row = Row {
                    label: String::new(),
                    condition: c.clone(),
                    scene: Some(s.clone()),
                };
                let planned = lay.planned_n(&row, a);
                if planned == 0 {
                    continue;
                }
                let recs = records_of(lay, c, s, a);
                let verdicts: Vec<bool> =
                    recs.iter().filter_map(|r| geo(r)?.genus_matches).collect();
                let mean = |f: Metric| lay.row_mean(&row, a, f);
                cells.push(GeometryCell {
                    condition: c.clone(),
                    scene: s.clone(),
                    arm: super::super::grid::arm_name(a).into(),
                    n: recs.len(),
                    planned,
                    chamfer_mean: mean(m_chamfer),
                    floor_mm: recs.iter().find_map(|r| m_floor(r)),
                    ratio_mean: mean(m_ratio),
                    genus_matches: verdicts.iter().filter(|v| **v).count(),
                    genus_known: verdicts.len(),
                    genus: recs.iter().map(|r| geo(r).and_then(|g| g.genus)).collect(),
                    gt_genus: recs.iter().find_map(|r| geo(r)?.gt_genus),
                    components_raw_mean: mean(m_components_raw),
                    components_mean: mean(m_components),
                    normal_error_mean: mean(m_normal),
                    psnr_mean: mean(m_psnr),
                    floor_seen_mm: recs.iter().find_map(|r| geo(r)?.floor_seen),
                    ratio_seen_mean: mean(m_ratio_seen),
                });
            }
        }
        let per_scene: Vec<&GeometryCell> = cells
            .iter()
            .filter(|x| &x.condition == c && x.arm == super::super::grid::arm_name(sa))
            .collect();
        let avg = |f: &dyn Fn(&GeometryCell) -> Option<f64>| {
            let v: Vec<f64> = per_scene.iter().filter_map(|x| f(x)).collect();
            super::super::stats::mean(&v)
        };
        let ratios: Vec<f64> = per_scene.iter().filter_map(|x| x.ratio_mean).collect();
        let worst = per_scene
            .iter()
            .filter_map(|x| Some((x.ratio_mean?, x.scene.clone())))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        suite.push(SuiteMean {
            condition: c.clone(),
            arm: super::super::grid::arm_name(sa).into(),
            ratio_mean: avg(&|x| x.ratio_mean),
            chamfer_mean: avg(&|x| x.chamfer_mean),
            floor_mean: avg(&|x| x.floor_mm),
            ratio_seen_mean: avg(&|x| x.ratio_seen_mean),
            scenes: per_scene.iter().filter(|x| x.ratio_mean.is_some()).count(),
            scenes_within_target: per_scene
                .iter()
                .filter(|x| x.ratio_mean.is_some_and(|r| r <= RATIO_TARGET))
                .count(),
            ratio_median: median(&ratios),
            ratio_worst: worst.as_ref().map(|w| w.0),
            worst_scene: worst.map(|w| w.1),
            genus_right_runs: per_scene.iter().map(|x| x.genus_matches).sum(),
            genus_known_runs: per_scene.iter().map(|x| x.genus_known).sum(),
        });
    }
    GeometrySummary { cells, suite }
}

fn genus_list(cell: &GeometryCell) -> String {
    if cell.genus.is_empty() {
        return "—".into();
    }
    let got: Vec<String> = cell
        .genus
        .iter()
        .map(|g| g.map_or("—".into(), |x| x.to_string()))
        .collect();
    format!(
        "{} ({})",
        got.join(", "),
        cell.gt_genus.map_or("?".into(), |x| x.to_string())
    )
}

fn components(raw: Option<f64>, clean: Option<f64>) -> String {
    format!("{} → {}", fmt_opt(raw, 1), fmt_opt(clean, 1))
}

/// The geometry tables (see the module doc); `##` sections appended to `md`.
pub(super) fn geometry_section(md: &mut String, lay: &Layout<'_>) {
    let sum = summarise(lay);
    let many_conds = lay.conditions.len() > 1;
    let _ = writeln!(
        md,
        "## Geometry against the ground truth (mean over seeds)\n\n\
         Floor: the scene's true mesh scored by the same protocol (what a perfect reconstruction \
         gets; `meta.json` of the scene); ratio = Chamfer / floor, per run then averaged (the \
         target is ≤ 4). Genus: of the largest component of the written (cleaned) mesh, per seed, \
         with the truth's in parentheses; `=` counts the runs where they agree. Components: \
         before → after clean-up. Normal error: mean angle between rendered and true normals on \
         the held-out views (°). PSNR: held-out views (dB). Seen floor: the true mesh less what \
         fewer training cameras see than the clean-up's rule 4 keeps, scored the same way (what \
         a perfect reconstruction gets after that cut); × seen = Chamfer / seen floor.\n"
    );
    let t: Vec<Vec<String>> = sum
        .cells
        .iter()
        .map(|x| {
            vec![
                if many_conds {
                    format!("{} · {}", x.condition, x.scene)
                } else {
                    x.scene.clone()
                },
                arm_title(arm_of(&x.arm)).to_string(),
                format!("{}/{}", x.n, x.planned),
                fmt_opt(x.chamfer_mean, 3),
                fmt_opt(x.floor_mm, 3),
                fmt_opt(x.ratio_mean, 2),
                if x.genus_known == 0 {
                    "—".into()
                } else {
                    format!("{}/{}", x.genus_matches, x.genus_known)
                },
                genus_list(x),
                components(x.components_raw_mean, x.components_mean),
                fmt_opt(x.normal_error_mean, 1),
                fmt_opt(x.psnr_mean, 2),
                fmt_opt(x.floor_seen_mm, 3),
                fmt_opt(x.ratio_seen_mean, 2),
            ]
        })
        .collect();
    md_table(
        md,
        &[
            "scene",
            "arm",
            "runs",
            "Chamfer",
            "floor",
            "ratio",
            "genus =",
            "genus (truth)",
            "components",
            "normal error (°)",
            "PSNR",
            "seen floor",
            "× seen",
        ]
        .map(String::from),
        &t,
    );
    for m in &sum.suite {
        let _ = writeln!(
            md,
            "Suite mean{} ({}, {} scene(s) with a ratio): ratio to the floor **{}**; Chamfer {} mm \
             against a mean floor of {} mm. Scenes within {}× their floor: {}/{}. Ratio to the \
             seen floor: {}. Median ratio {}, worst {}; the true genus in {} of {} runs.\n",
            if many_conds {
                format!(" of {}", m.condition)
            } else {
                String::new()
            },
            arm_title(arm_of(&m.arm)),
            m.scenes,
            m.ratio_mean.map_or("—".into(), |x| format!("{x:.2}×")),
            fmt_opt(m.chamfer_mean, 3),
            fmt_opt(m.floor_mean, 3),
            RATIO_TARGET,
            m.scenes_within_target,
            m.scenes,
            m.ratio_seen_mean.map_or("—".into(), |x| format!("{x:.2}×")),
            m.ratio_median.map_or("—".into(), |x| format!("{x:.2}×")),
            match (m.ratio_worst, &m.worst_scene) {
                (Some(x), Some(s)) => format!("{x:.2}× ({s})"),
                _ => "—".into(),
            },
            m.genus_right_runs,
            m.genus_known_runs,
        );
    }

    // Genus on the scenes with holes, every arm: right in how many runs ("9 of 9").
    let holed: Vec<&GeometryCell> = sum
        .cells
        .iter()
        .filter(|x| x.gt_genus.is_some_and(|g| g >= 1) && x.genus_known > 0)
        .collect();
    if !holed.is_empty() {
        let _ = writeln!(
            md,
            "### Genus on the scenes with holes (runs matching the truth / runs)\n"
        );
        let mut header = vec!["scene".to_string()];
        header.extend(lay.arms.iter().map(|a| arm_title(*a).to_string()));
        header.push("all arms".into());
        let mut labels: Vec<(String, String)> = Vec::new();
        for x in &holed {
            let k = (x.condition.clone(), x.scene.clone());
            if !labels.contains(&k) {
                labels.push(k);
            }
        }
        let count = |cells: &mut dyn Iterator<Item = &&GeometryCell>| {
            let (m, n) = cells.fold((0, 0), |(m, n), x| (m + x.genus_matches, n + x.genus_known));
            if n == 0 {
                "—".to_string()
            } else {
                format!("{m}/{n}")
            }
        };
        let mut t = Vec::new();
        for (c, s) in &labels {
            let mut line = vec![if many_conds {
                format!("{c} · {s}")
            } else {
                s.clone()
            }];
            let of = |x: &&&GeometryCell| &x.condition == c && &x.scene == s;
            for &a in &lay.arms {
                let name = super::super::grid::arm_name(a);
                line.push(count(&mut holed.iter().filter(|x| of(x) && x.arm == name)));
            }
            line.push(count(&mut holed.iter().filter(of)));
            t.push(line);
        }
        let mut total = vec!["all".to_string()];
        for &a in &lay.arms {
            let name = super::super::grid::arm_name(a);
            total.push(count(&mut holed.iter().filter(|x| x.arm == name)));
        }
        total.push(count(&mut holed.iter()));
        t.push(total);
        md_table(md, &header, &t);
    }

    // Every run.
    let _ = writeln!(md, "### Every run\n");
    let t: Vec<Vec<String>> = lay
        .records
        .iter()
        .map(|r| {
            let g = r.geometry.clone().unwrap_or_default();
            vec![
                r.id.clone(),
                fmt_opt(r.chamfer_sum, 3),
                fmt_opt(g.floor_mm, 3),
                fmt_opt(g.ratio_to_floor, 2),
                format!(
                    "{} ({}){}",
                    g.genus.map_or("—".into(), |x| x.to_string()),
                    g.gt_genus.map_or("?".into(), |x| x.to_string()),
                    match g.genus_matches {
                        Some(true) => " =",
                        Some(false) => " ≠",
                        None => "",
                    }
                ),
                format!(
                    "{} → {}",
                    g.components_raw.map_or("—".into(), |c| c.to_string()),
                    g.components.map_or("—".into(), |c| c.to_string())
                ),
                fmt_opt(g.normal_error_deg, 1),
                fmt_opt(r.psnr, 2),
                fmt_opt(g.chamfer_closed, 3),
                g.depth_prior.clone().unwrap_or_else(|| "—".into()),
                fmt_opt(g.floor_seen, 3),
                fmt_opt(g.ratio_to_floor_seen, 2),
            ]
        })
        .collect();
    md_table(
        md,
        &[
            "run",
            "Chamfer",
            "floor",
            "ratio",
            "genus (truth)",
            "components",
            "normal error (°)",
            "PSNR",
            "Chamfer, closed mesh",
            "depth prior",
            "seen floor",
            "× seen",
        ]
        .map(String::from),
        &t,
    );
}

fn arm_of(name: &str) -> AugMode {
    match name {
        "sia" => AugMode::Sia,
        "dia" => AugMode::Dia,
        _ => AugMode::None,
    }
}

/// The `hard` grid's `report.md`: the intro, the geometry tables, the paired differences of the
/// augmented arms where they ran, and what is missing. Returns the differences it shows.
pub(super) fn report_md(lay: &Layout<'_>, missing: &[String]) -> (String, Vec<DiffSummary>) {
    let mut md = String::new();
    intro(&mut md, lay, missing);
    let _ = writeln!(
        md,
        "Distances are the DTU protocol in mm (Chamfer = accuracy + completeness as in the \
         paper); lower is better. The Chamfer scores the surface the training cameras see \
         (`mesh.ply`, rule 4 of `mesh::clean`); the last column of the every-run table scores \
         the closed surface it was cut from (`mesh_closed.ply`). Genus and components are the \
         closed surface's.\n"
    );
    geometry_section(&mut md, lay);
    // Paired differences only on the scenes where another arm ran, and pooled over them.
    let with_arms: Vec<&String> = lay
        .scenes
        .iter()
        .filter(|s| {
            lay.plan
                .runs
                .iter()
                .any(|r| &r.scene_label() == *s && r.arm != AugMode::None)
        })
        .collect();
    let mut rows: Vec<Row> = Vec::new();
    for c in &lay.conditions {
        for s in &with_arms {
            rows.push(Row {
                label: (*s).clone(),
                condition: c.clone(),
                scene: Some((*s).clone()),
            });
        }
        if with_arms.len() > 1 {
            // Pairs exist only where the arms ran, so the mean row is over those scenes.
            rows.push(Row {
                label: "mean".into(),
                condition: c.clone(),
                scene: None,
            });
        }
    }
    let diffs = if rows.is_empty() {
        Vec::new()
    } else {
        paired_section(&mut md, lay, &rows)
    };
    if !missing.is_empty() {
        let _ = writeln!(md, "Missing (not finished yet): {}.\n", missing.join(", "));
    }
    let _ = writeln!(
        md,
        "Files: `runs.csv` and `runs.json` (every run, geometry columns included), \
         `summary.json` (every aggregate, `geometry` for the tables above), `chamfer.png`."
    );
    (md, diffs)
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn median_of_odd_and_even_counts_ignores_non_finite_values() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(median(&[f64::NAN, 5.0]), Some(5.0));
        assert_eq!(median(&[]), None);
    }
}
