//! `report.md`: the tables, in plan order, floats with fixed precision.

use super::super::grid::{arm_name, arm_title, Grid};
use super::super::plan::{StudyPlan, BASE_CONFIG_FILE};
use super::super::stats::{self, Ci};
use super::layout::{all_values, m_acc, m_chamfer, m_comp, m_psnr, m_train, Layout, Row};
use super::pareto::ParetoRow;
use super::DiffSummary;
use crate::augment::AugMode;
use std::fmt::Write as _;

pub(super) fn fmt_opt(v: Option<f64>, prec: usize) -> String {
    v.map_or("—".into(), |x| format!("{x:.prec$}"))
}

/// Seconds: one decimal below 10 s, whole seconds above.
pub(super) fn fmt_time(v: Option<f64>) -> String {
    match v {
        Some(x) if x < 10.0 => format!("{x:.1}"),
        v => fmt_opt(v, 0),
    }
}

pub(super) fn fmt_signed(x: f64, prec: usize) -> String {
    let s = format!("{x:+.prec$}");
    s.replace('-', "−")
}

pub(super) fn fmt_ci(ci: &Option<Ci>) -> String {
    match ci {
        None => "—".into(),
        Some(c) => format!(
            "{} [{}, {}] (n={})",
            fmt_signed(c.mean, 3),
            fmt_signed(c.lo, 3),
            fmt_signed(c.hi, 3),
            c.n
        ),
    }
}

/// Marks the lowest value of a row bold and the runner-up italic (when at least three values).
pub(super) fn rank_marks(vals: &[Option<f64>], prec: usize) -> Vec<String> {
    let mut order: Vec<(usize, f64)> = vals
        .iter()
        .enumerate()
        .filter_map(|(i, v)| v.map(|x| (i, x)))
        .collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    vals.iter()
        .enumerate()
        .map(|(i, v)| {
            let s = fmt_opt(*v, prec);
            if order.len() >= 2 && order[0].0 == i {
                format!("**{s}**")
            } else if order.len() >= 3 && order[1].0 == i {
                format!("*{s}*")
            } else {
                s
            }
        })
        .collect()
}

/// One table line per row: its label, then `cell(row, arm)` for every arm.
pub(super) fn arm_rows(
    rows: &[Row],
    arms: &[AugMode],
    cell: impl Fn(&Row, AugMode) -> String,
) -> Vec<Vec<String>> {
    rows.iter()
        .map(|r| {
            let mut line = vec![r.label.clone()];
            line.extend(arms.iter().map(|&a| cell(r, a)));
            line
        })
        .collect()
}

pub(super) fn md_table(out: &mut String, header: &[String], rows: &[Vec<String>]) {
    let _ = writeln!(out, "| {} |", header.join(" | "));
    let _ = writeln!(
        out,
        "|{}|",
        header
            .iter()
            .enumerate()
            .map(|(i, _)| if i == 0 { "---" } else { "---:" })
            .collect::<Vec<_>>()
            .join("|")
    );
    for r in rows {
        let _ = writeln!(out, "| {} |", r.join(" | "));
    }
    out.push('\n');
}

/// The command that (re)creates this study, with `STUDY_DIR` for the folder.
pub(super) fn study_command(plan: &StudyPlan) -> String {
    let o = &plan.options;
    let mut c = format!(
        "neus-aug study {} --preset {} --seeds {} --scenes {}",
        o.grid,
        o.preset.name(),
        o.seeds,
        super::super::jobs::shell_quote(&o.scenes.join(","))
    );
    if o.grid.uses_ia() {
        let _ = write!(c, " --ia {}", o.ia.name());
    }
    if o.base_config {
        let _ = write!(c, " --config STUDY_DIR/{BASE_CONFIG_FILE}");
    }
    for s in &o.sets {
        let _ = write!(c, " --set {}", super::super::jobs::shell_quote(s));
    }
    c.push_str(" --out STUDY_DIR");
    c
}

/// The title, what ran, and the command that made it.
pub(super) fn intro(md: &mut String, lay: &Layout<'_>, missing: &[String]) {
    let plan = lay.plan;
    let records = lay.records;
    let o = &plan.options;
    let _ = writeln!(md, "# Study `{}`: {}\n", o.grid, o.grid.summary());
    let _ = writeln!(
        md,
        "Preset `{}`, {} seed(s) per cell (0–{}), scenes: {}.{}",
        o.preset.name(),
        o.seeds,
        o.seeds.saturating_sub(1),
        lay.scenes.join(", "),
        if o.grid.uses_ia() {
            format!(" IA = {}.", arm_title(o.ia))
        } else {
            String::new()
        }
    );
    let _ = writeln!(
        md,
        "Runs: {} planned, {} collected{}.\n",
        plan.runs.len(),
        records.len(),
        if missing.is_empty() {
            String::new()
        } else {
            format!(", {} missing (listed at the end)", missing.len())
        }
    );
    let _ = writeln!(
        md,
        "Made with:\n\n```\n{}\nneus-aug study collect STUDY_DIR\n```\n",
        study_command(plan)
    );
}

/// The column title of a table's first column: `condition` when there are several, else `scene`.
pub(super) fn first_column(lay: &Layout<'_>) -> &'static str {
    if lay.conditions.len() > 1 {
        "condition"
    } else {
        "scene"
    }
}

/// The header `first`, then one column per arm.
pub(super) fn arm_header(lay: &Layout<'_>, first: &str) -> Vec<String> {
    let mut h = vec![first.to_string()];
    h.extend(lay.arms.iter().map(|a| arm_title(*a).to_string()));
    h
}

/// The whole `report.md` of a study, and the paired differences it shows (for `summary.json`).
/// `pareto`: the variants of a pareto study, `None` for other grids. The `hard` grid has its
/// own ([`super::hard::report_md`]).
pub(super) fn report_md(
    lay: &Layout<'_>,
    rows: &[Row],
    missing: &[String],
    pareto: Option<&[ParetoRow]>,
) -> (String, Vec<DiffSummary>) {
    let plan = lay.plan;
    let records = lay.records;
    let o = &plan.options;
    let mut md = String::new();
    intro(&mut md, lay, missing);
    let _ = writeln!(
        md,
        "Distances are the DTU protocol in mm (accuracy = mesh → ground truth, completeness = \
         ground truth → mesh, Chamfer = accuracy + completeness as in the paper); lower is \
         better. Means are over seeds; a `mean` row averages the scenes where every arm has \
         results.\n"
    );

    let arm_header = |first: &str| arm_header(lay, first);
    let first_col = first_column(lay);

    // Chamfer means, best bold, runner-up italic; time beside it.
    let _ = writeln!(
        md,
        "## Chamfer distance (mm, mean over seeds; best **bold**, runner-up *italic*)\n"
    );
    let mut t = Vec::new();
    for r in rows {
        let vals: Vec<Option<f64>> = lay
            .arms
            .iter()
            .map(|&a| lay.row_mean(r, a, m_chamfer))
            .collect();
        let mut line = vec![r.label.clone()];
        line.extend(rank_marks(&vals, 3));
        t.push(line);
    }
    if lay.conditions.len() == 1 {
        let cond = &lay.conditions[0];
        let all = Row {
            label: String::new(),
            condition: cond.clone(),
            scene: None,
        };
        let times: Vec<Option<f64>> = lay
            .arms
            .iter()
            .map(|&a| stats::mean(&all_values(lay, &all, a, m_train)))
            .collect();
        let mut line = vec!["train time (s)".to_string()];
        line.extend(times.iter().map(|v| fmt_time(*v)));
        t.push(line);
        if let Some(Some(b)) = lay
            .arms
            .iter()
            .position(|a| *a == AugMode::None)
            .map(|i| times[i])
        {
            let mut line = vec!["train time / baseline".to_string()];
            line.extend(
                times
                    .iter()
                    .map(|v| v.map_or("—".into(), |x| format!("{:.2}×", x / b))),
            );
            t.push(line);
        }
    }
    md_table(&mut md, &arm_header(first_col), &t);

    // Standard deviations.
    let _ = writeln!(md, "## Standard deviation over seeds (mm)\n");
    let t = arm_rows(rows, &lay.arms, |r, a| {
        fmt_opt(lay.row_std(r, a, m_chamfer), 3)
    });
    md_table(&mut md, &arm_header(first_col), &t);
    let _ = writeln!(
        md,
        "A `mean` row gives √(mean of the per-scene variances).\n"
    );

    // Accuracy / completeness.
    let _ = writeln!(md, "## Accuracy / completeness (mm)\n");
    let t = arm_rows(rows, &lay.arms, |r, a| {
        format!(
            "{} / {}",
            fmt_opt(lay.row_mean(r, a, m_acc), 3),
            fmt_opt(lay.row_mean(r, a, m_comp), 3)
        )
    });
    md_table(&mut md, &arm_header(first_col), &t);

    // Geometry against the ground truth, when the runs recorded it (issue 13).
    if records.iter().any(|r| r.geometry.is_some()) {
        super::hard::geometry_section(&mut md, lay);
    }

    // Paired differences.
    let diffs = paired_section(&mut md, lay, rows);

    // Against the paper (Table 2 only: the figures of DESIGN §8).
    if o.grid == Grid::Table2 && lay.has_baseline_and_others() {
        super::paper::paper_section(&mut md, lay);
    }

    // Held-out PSNR.
    let _ = writeln!(md, "## Held-out views: PSNR (dB, higher is better)\n");
    let t = arm_rows(rows, &lay.arms, |r, a| {
        fmt_opt(lay.row_mean(r, a, m_psnr), 2)
    });
    md_table(&mut md, &arm_header(first_col), &t);

    // Time per arm and condition.
    let _ = writeln!(
        md,
        "## Training time per arm (s, mean over runs; ratio to the baseline)\n\n\
         The paper measured SIA at about 1× and DIA at about 3× the baseline's time (A100, 50k \
         iterations). Runs resumed after an interruption count only the time after the resume; \
         runs that reused another run's training are left out.\n"
    );
    let mut t = Vec::new();
    for c in &lay.conditions {
        let row = Row {
            label: c.clone(),
            condition: c.clone(),
            scene: None,
        };
        let times: Vec<Option<f64>> = lay
            .arms
            .iter()
            .map(|&a| stats::mean(&all_values(lay, &row, a, m_train)))
            .collect();
        let base = lay
            .arms
            .iter()
            .position(|a| *a == AugMode::None)
            .and_then(|i| times[i]);
        let mut line = vec![c.clone()];
        line.extend(times.iter().map(|v| match (v, base) {
            (Some(x), Some(b)) if b > 0.0 => format!("{} ({:.2}×)", fmt_time(Some(*x)), x / b),
            (v, _) => fmt_time(*v),
        }));
        t.push(line);
    }
    md_table(&mut md, &arm_header("condition"), &t);

    // Pareto.
    if let Some(pareto_rows) = pareto {
        let _ = writeln!(
            md,
            "## Accuracy against time\n\nOne factor at a time around the `{}` preset (`centre`), \
             plus the other preset. Time to mesh = load + prepare + train + mesh extraction (s, \
             mean over seeds; a mesh-only variant counts its source run's training). Points on \
             the Pareto front (no other point is both faster and more accurate) are marked ◆.\n",
            o.preset.name()
        );
        let t: Vec<Vec<String>> = pareto_rows
            .iter()
            .map(|p| {
                vec![
                    format!("{}{}", p.condition, if p.on_front { " ◆" } else { "" }),
                    fmt_opt(p.chamfer_mean, 3),
                    fmt_opt(p.chamfer_std, 3),
                    fmt_time(p.time_to_mesh_mean),
                    fmt_time(p.train_mean),
                    fmt_time(p.mesh_mean),
                    p.n.to_string(),
                ]
            })
            .collect();
        md_table(
            &mut md,
            &[
                "variant",
                "Chamfer",
                "std",
                "time to mesh (s)",
                "train (s)",
                "mesh (s)",
                "n",
            ]
            .map(String::from),
            &t,
        );
    }

    // Counts and missing runs.
    let _ = writeln!(md, "## Runs collected / planned\n");
    let t = arm_rows(rows, &lay.arms, |r, a| {
        format!("{}/{}", lay.row_n(r, a, m_chamfer), lay.planned_n(r, a))
    });
    md_table(&mut md, &arm_header(first_col), &t);
    let resumed: Vec<&str> = records
        .iter()
        .filter(|r| r.resumed_from.is_some() && !r.reused_training)
        .map(|r| r.id.as_str())
        .collect();
    if !resumed.is_empty() {
        let _ = writeln!(
            md,
            "Resumed after an interruption (their training time is partial): {}.\n",
            resumed.join(", ")
        );
    }
    if !missing.is_empty() {
        let _ = writeln!(md, "Missing (not finished yet): {}.\n", missing.join(", "));
    }
    let _ = writeln!(
        md,
        "Files: `runs.csv` and `runs.json` (every run), `summary.json` (every aggregate and \
         interval){}{}{}.",
        if pareto.is_some() {
            ""
        } else {
            ", `chamfer.png`"
        },
        if o.grid == Grid::Reduced {
            ", `chamfer_vs_views.png`"
        } else {
            ""
        },
        if pareto.is_some() {
            ", `pareto.csv`, `pareto.png`"
        } else {
            ""
        }
    );
    (md, diffs)
}

/// The paired differences `arm − baseline` of `rows` (with an "all conditions" row when there
/// are several), when the study has a baseline and another arm; what it shows, for
/// `summary.json`.
pub(super) fn paired_section(md: &mut String, lay: &Layout<'_>, rows: &[Row]) -> Vec<DiffSummary> {
    let mut diffs = Vec::new();
    let first_col = first_column(lay);
    if lay.has_baseline_and_others() {
        let others: Vec<AugMode> = lay
            .arms
            .iter()
            .copied()
            .filter(|a| *a != AugMode::None)
            .collect();
        let _ = writeln!(
            md,
            "## Paired differences arm − baseline (Chamfer, mm; negative: the arm is better)\n\n\
             Mean difference over pairs of runs with the same condition, scene and seed, with a \
             95 % percentile bootstrap interval ({} resamples, seed {:#x}; `mean` rows resample \
             within scenes). An interval that excludes 0 marks a difference the seeds support.\n",
            stats::RESAMPLES,
            stats::BOOTSTRAP_SEED
        );
        let mut t = Vec::new();
        let mut all_rows = rows.to_vec();
        if lay.conditions.len() > 1 {
            all_rows.push(Row {
                label: "all conditions".into(),
                condition: String::new(),
                scene: None,
            });
        }
        for r in &all_rows {
            let mut line = vec![r.label.clone()];
            for &a in &others {
                let strata = if r.condition.is_empty() {
                    lay.conditions
                        .iter()
                        .flat_map(|c| {
                            let row = Row {
                                label: String::new(),
                                condition: c.clone(),
                                scene: None,
                            };
                            lay.paired(&row, a, m_chamfer)
                        })
                        .collect()
                } else {
                    lay.paired(r, a, m_chamfer)
                };
                let label = format!(
                    "{}|{}|{}",
                    r.condition,
                    r.scene.as_deref().unwrap_or("*"),
                    arm_name(a)
                );
                let ci = stats::paired_ci(&label, &strata);
                line.push(fmt_ci(&ci));
                diffs.push(DiffSummary {
                    row: r.label.clone(),
                    arm: arm_name(a).into(),
                    chamfer_diff: ci,
                });
            }
            t.push(line);
        }
        let mut h = vec![first_col.to_string()];
        h.extend(
            others
                .iter()
                .map(|a| format!("{} − baseline", arm_title(*a))),
        );
        md_table(md, &h, &t);
    }
    diffs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranks_mark_best_and_runner_up() {
        let v = rank_marks(&[Some(2.0), Some(1.0), None, Some(3.0)], 2);
        assert_eq!(v, ["*2.00*", "**1.00**", "—", "3.00"]);
        assert_eq!(rank_marks(&[Some(2.0), Some(1.0)], 1), ["2.0", "**1.0**"]);
        assert_eq!(rank_marks(&[Some(2.0)], 1), ["2.0"]);
    }

    #[test]
    fn signed_format_uses_a_true_minus() {
        assert_eq!(fmt_signed(-0.0123, 3), "−0.012");
        assert_eq!(fmt_signed(0.5, 2), "+0.50");
    }
}
