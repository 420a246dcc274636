//! `report.md`: the tables, in plan order, floats with fixed precision.

use super::super::grid::Grid;
use super::super::stats;
use super::format::{
    arm_header, arm_rows, first_column, fmt_opt, fmt_time, intro, md_table, paired_section,
    rank_marks,
};
use super::layout::{all_values, m_acc, m_chamfer, m_comp, m_psnr, m_ssim, m_train, Layout, Row};
use super::pareto::ParetoRow;
use super::DiffSummary;
use crate::augment::AugMode;
use std::fmt::Write as _;

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

    // Geometry against the ground truth, when the runs recorded it.
    if records.iter().any(|r| r.geometry.is_some()) {
        super::hard::geometry_section(&mut md, lay);
    }

    // Paired differences.
    let diffs = paired_section(&mut md, lay, rows);

    // Against the paper (Table 2 only: the paper's NeuS figures, `paper::PAPER_CHAMFER`).
    if o.grid == Grid::Table2 && lay.has_baseline_and_others() {
        super::paper::paper_section(&mut md, lay);
    }
    // Against the paper's robustness table (reduced data, degradations).
    if matches!(o.grid, Grid::Reduced | Grid::Degraded) && lay.has_baseline_and_others() {
        super::paper::robustness_section(&mut md, lay, o.grid == Grid::Degraded);
    }

    // Held-out PSNR and SSIM.
    let _ = writeln!(
        md,
        "## Held-out views: PSNR (dB) / SSIM (higher is better)\n"
    );
    let t = arm_rows(rows, &lay.arms, |r, a| {
        format!(
            "{} / {}",
            fmt_opt(lay.row_mean(r, a, m_psnr), 2),
            fmt_opt(lay.row_mean(r, a, m_ssim), 4)
        )
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
        match o.grid {
            Grid::Reduced => ", `chamfer_vs_views.png`",
            Grid::Degraded => ", `chamfer_by_degradation.png`",
            _ => "",
        },
        if pareto.is_some() {
            ", `pareto.csv`, `pareto.png`"
        } else {
            ""
        }
    );
    (md, diffs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::report::format::fmt_signed;

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
