//! The pieces every report page is made of: number formats, Markdown tables, the introduction
//! and the paired-difference section.

use super::super::grid::{arm_name, arm_title};
use super::super::plan::{StudyPlan, BASE_CONFIG_FILE};
use super::super::stats::{self, Ci};
use super::layout::{m_chamfer, Layout, Row};
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
