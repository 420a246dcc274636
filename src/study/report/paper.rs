//! "Against the paper" (Table 2 only): our pooled paired differences and time ratios beside the
//! paper's figures.

use super::super::grid::{arm_name, arm_title};
use super::super::stats::{self, Ci};
use super::format::{fmt_ci, fmt_signed, md_table};
use super::layout::{all_values, m_chamfer, m_train, Layout, Row};
use crate::augment::AugMode;
use std::fmt::Write as _;

/// The paper's NeuS figures on DTU (Pérez et al., "Enhancing Neural Rendering Methods with Image
/// Augmentations", Table 2: mean Chamfer sum over the 15 scans, 5 runs; training time on an A100).
const PAPER_CHAMFER: [(AugMode, f64); 3] = [
    (AugMode::None, 2.03),
    (AugMode::Dia, 2.03),
    (AugMode::Sia, 1.91),
];
const PAPER_TIME_RATIO: [(AugMode, f64); 3] = [
    (AugMode::None, 1.0),
    (AugMode::Dia, 3.0),
    (AugMode::Sia, 1.0),
];

/// The verdict on one arm: does our pooled paired interval agree with the paper's difference?
pub(super) fn verdict(paper_diff: f64, ci: &Ci) -> &'static str {
    let excludes_zero = ci.lo > 0.0 || ci.hi < 0.0;
    if paper_diff == 0.0 {
        match (excludes_zero, ci.mean < 0.0) {
            (false, _) => "agrees: no difference either way (the interval contains 0)",
            (true, true) => "disagrees: here the arm is better, the paper saw no change",
            (true, false) => "disagrees: here the arm is worse, the paper saw no change",
        }
    } else {
        let same_sign = (ci.mean < 0.0) == (paper_diff < 0.0);
        match (excludes_zero, same_sign) {
            (true, true) => "agrees: same direction, and the interval excludes 0",
            (false, true) => "same direction, but inconclusive: the interval contains 0",
            (false, false) => "inconclusive, opposite direction: the interval contains 0",
            (true, false) => "disagrees: opposite direction, and the interval excludes 0",
        }
    }
}

/// "Against the paper": each arm's pooled paired difference and time ratio beside the paper's.
pub(super) fn paper_section(md: &mut String, lay: &Layout<'_>) {
    let cond = &lay.conditions[0];
    let pooled = Row {
        label: String::new(),
        condition: cond.clone(),
        scene: (lay.scenes.len() == 1).then(|| lay.scenes[0].clone()),
    };
    let paper = |a: AugMode, t: &[(AugMode, f64); 3]| t.iter().find(|x| x.0 == a).map(|x| x.1);
    let Some(base_mean) = lay.row_mean(&pooled, AugMode::None, m_chamfer) else {
        return;
    };
    let base_time = stats::mean(&all_values(lay, &pooled, AugMode::None, m_train));
    let _ = writeln!(
        md,
        "## Against the paper\n\n\
         The paper (NeuS on DTU, Table 2; 5 runs, A100): Chamfer baseline 2.03, DIA 2.03, SIA \
         1.91 mm; training time SIA ≈ 1×, DIA ≈ 3× the baseline. Here: the pooled paired \
         difference arm − baseline with its 95 % bootstrap interval, as a share of the \
         baseline's mean ({base_mean:.3} mm), and the training-time ratio.\n"
    );
    let mut t = Vec::new();
    for &a in lay.arms.iter().filter(|a| **a != AugMode::None) {
        let (Some(pc), Some(pb)) = (
            paper(a, &PAPER_CHAMFER),
            paper(AugMode::None, &PAPER_CHAMFER),
        ) else {
            continue;
        };
        let pd = pc - pb;
        let label = format!(
            "{}|{}|{}",
            pooled.condition,
            pooled.scene.as_deref().unwrap_or("*"),
            arm_name(a)
        );
        let ci = stats::paired_ci(&label, &lay.paired(&pooled, a, m_chamfer));
        let time = stats::mean(&all_values(lay, &pooled, a, m_train));
        let ratio = match (time, base_time) {
            (Some(x), Some(b)) if b > 0.0 => format!("{:.2}×", x / b),
            _ => "—".into(),
        };
        t.push(vec![
            arm_title(a).to_string(),
            format!("{} ({:+.1} %)", fmt_signed(pd, 2), 100.0 * pd / pb).replace('-', "−"),
            ci.as_ref().map_or("—".into(), |c| {
                format!(
                    "{} ({:+.1} %)",
                    fmt_ci(&Some(*c)),
                    100.0 * c.mean / base_mean
                )
                .replace("(+-", "(−")
                .replace("(-", "(−")
            }),
            ci.as_ref()
                .map_or("no pairs yet", |c| verdict(pd, c))
                .to_string(),
            format!(
                "{:.0}× / {ratio}",
                paper(a, &PAPER_TIME_RATIO).unwrap_or(f64::NAN)
            ),
        ]);
    }
    md_table(
        md,
        &[
            "arm",
            "paper: arm − baseline (mm)",
            "here: arm − baseline (mm)",
            "verdict",
            "time ratio paper / here",
        ]
        .map(String::from),
        &t,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn verdicts_follow_the_interval() {
        let ci = |lo: f64, hi: f64| Ci {
            mean: 0.5 * (lo + hi),
            lo,
            hi,
            n: 3,
        };
        assert!(verdict(-0.12, &ci(-0.3, -0.1)).starts_with("agrees"));
        assert!(verdict(-0.12, &ci(-0.3, 0.1)).contains("inconclusive"));
        assert!(verdict(-0.12, &ci(0.1, 0.3)).starts_with("disagrees"));
        assert!(verdict(0.0, &ci(-0.1, 0.1)).starts_with("agrees"));
        assert!(verdict(0.0, &ci(0.1, 0.2)).contains("worse"));
        assert!(verdict(0.0, &ci(-0.2, -0.1)).contains("better"));
    }
}
