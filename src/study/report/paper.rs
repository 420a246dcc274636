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

/// The smallest paired difference these runs could detect (mm): 80 % power at a two-sided 5 %
/// level is `(1.96 + 0.84)` standard errors of the paired mean, the standard error taken from
/// the 95 % bootstrap interval's width (`(hi − lo) / (2 · 1.96)`).
pub(super) fn detectable(ci: &Ci) -> f64 {
    2.8 * (ci.hi - ci.lo) / (2.0 * 1.96)
}

/// The verdict on one claim: does our pooled paired interval (arm − baseline) agree with the
/// paper's difference `paper_diff`? `agrees` / `disagrees` when the interval excludes 0 (or, for
/// a claim of no difference, contains it), else `inconclusive`, with the smallest difference
/// these runs could detect ([`detectable`]).
///
/// While a stratum (a scene, or a condition–scene cell) holds a single pair, the stratified
/// bootstrap cannot see how that stratum's difference varies from seed to seed, and the interval
/// is too narrow to judge by: the verdict is then `provisional`, whatever the interval says.
pub(super) fn verdict(paper_diff: f64, ci: &Ci) -> String {
    let excludes_zero = ci.lo > 0.0 || ci.hi < 0.0;
    let mde = detectable(ci);
    let could = format!("could detect ≥ {mde:.3} mm");
    if ci.min_stratum < 2 {
        let direction = if paper_diff == 0.0 {
            "the paper saw no change"
        } else if (ci.mean < 0.0) == (paper_diff < 0.0) {
            "same direction as the paper so far"
        } else {
            "opposite direction to the paper so far"
        };
        return format!(
            "provisional: a scene has a single seed, so the interval understates the spread \
             ({direction})"
        );
    }
    if paper_diff == 0.0 {
        match (excludes_zero, ci.mean < 0.0) {
            (false, _) => format!("agrees: no difference either way ({could})"),
            (true, true) => "disagrees: here the arm is better, the paper saw no change".into(),
            (true, false) => "disagrees: here the arm is worse, the paper saw no change".into(),
        }
    } else {
        let same_sign = (ci.mean < 0.0) == (paper_diff < 0.0);
        match (excludes_zero, same_sign) {
            (true, true) => "agrees: same direction, and the interval excludes 0".into(),
            (true, false) => "disagrees: opposite direction, and the interval excludes 0".into(),
            (false, true) => format!("inconclusive ({could}; same direction)"),
            (false, false) => format!("inconclusive ({could}; opposite direction)"),
        }
    }
}

/// The paper's robustness table (NeuS, DTU; baseline and with image augmentation): Chamfer
/// sum at 10 / 25 / 50 / 75 % of the training views, and under Gaussian noise, motion blur,
/// Poisson noise, salt & pepper and speckle at their main strength (the appendix's order).
const PAPER_REDUCED: [(&str, f64, f64); 4] = [
    ("views 10%", 5.72, 4.77),
    ("views 25%", 2.91, 2.65),
    ("views 50%", 2.28, 2.12),
    ("views 75%", 2.15, 2.02),
];
const PAPER_DEGRADED: [(&str, f64, f64); 5] = [
    ("gaussian", 2.36, 2.18),
    ("motion-blur", 2.01, 1.90),
    ("poisson", 3.34, 2.85),
    ("salt-pepper", 2.68, 2.39),
    ("speckle", 4.54, 3.91),
];

/// The key of `cond` in the paper's tables: a degradation's kind in its canonical spelling
/// (`motion-blur:5` → `motion-blur`, whatever spelling the plan used), else the condition.
fn paper_key(cond: &str) -> &str {
    let kind = cond.split(':').next().unwrap_or(cond);
    match kind.parse::<crate::augment::DegradationKind>() {
        Ok(k) => k.name(),
        Err(_) => cond,
    }
}

/// "Against the paper" for the reduced and degraded grids: per condition, the paper's baseline
/// and augmented figures and difference beside our pooled paired difference (IA − baseline over
/// scenes and seeds), its interval, power and verdict; then the claim over all conditions
/// ("improves across all reduction percentages", "consistently improves against all types of
/// noise"): agrees when every condition agrees, disagrees when one disagrees, else inconclusive.
pub(super) fn robustness_section(md: &mut String, lay: &Layout<'_>, degraded: bool) {
    let Some(&ia) = lay.arms.iter().find(|a| **a != AugMode::None) else {
        return;
    };
    let table: &[(&str, f64, f64)] = if degraded {
        &PAPER_DEGRADED
    } else {
        &PAPER_REDUCED
    };
    let _ = writeln!(
        md,
        "## Against the paper\n\n\
         The paper's robustness table (NeuS on DTU): Chamfer sum without and with image \
         augmentation. Here: the pooled paired difference {} − baseline over the scenes and \
         seeds of each condition, with its 95 % bootstrap interval; \"could detect\" is the \
         smallest difference these runs detect with 80 % power.\n",
        arm_title(ia)
    );
    let mut t = Vec::new();
    let mut verdicts = Vec::new();
    for cond in &lay.conditions {
        let Some(&(_, pb, pa)) = table.iter().find(|(k, _, _)| paper_key(cond) == *k) else {
            continue;
        };
        let row = Row {
            label: String::new(),
            condition: cond.clone(),
            scene: (lay.scenes.len() == 1).then(|| lay.scenes[0].clone()),
        };
        let label = format!("{cond}|*|{}", arm_name(ia));
        let ci = stats::paired_ci(&label, &lay.paired(&row, ia, m_chamfer));
        let v = ci.as_ref().map(|c| verdict(pa - pb, c));
        verdicts.push(v.clone());
        t.push(vec![
            cond.clone(),
            format!("{pb:.2} / {pa:.2} ({})", fmt_signed(pa - pb, 2)),
            fmt_ci(&ci),
            v.unwrap_or_else(|| "no pairs yet".into()),
        ]);
    }
    md_table(
        md,
        &[
            "condition",
            "paper: baseline / IA (difference)",
            "here: IA − baseline (mm)",
            "verdict",
        ]
        .map(String::from),
        &t,
    );
    let all = verdicts.len();
    let agree = verdicts
        .iter()
        .flatten()
        .filter(|v| v.starts_with("agrees"))
        .count();
    let disagree = verdicts
        .iter()
        .flatten()
        .filter(|v| v.starts_with("disagrees"))
        .count();
    let provisional = verdicts
        .iter()
        .flatten()
        .any(|v| v.starts_with("provisional"));
    let claim = if all == 0 {
        "no condition yet".to_string()
    } else if provisional {
        format!("provisional: some conditions have a scene with a single seed ({agree} of {all} agree so far)")
    } else if verdicts.iter().any(|v| v.is_none()) {
        format!("not all conditions have runs yet ({agree} of {all} agree so far)")
    } else if agree == all {
        format!("**agrees**: every one of the {all} conditions agrees")
    } else if disagree > 0 {
        format!("**disagrees**: {disagree} of {all} conditions disagree, {agree} agree")
    } else {
        format!("**inconclusive**: {agree} of {all} conditions agree, none disagrees")
    };
    let _ = writeln!(
        md,
        "Claim ({}): {claim}.\n",
        if degraded {
            "\"consistently improves against all types of noise\""
        } else {
            "\"IA improves performance across all reduction percentages\""
        }
    );
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
                .map_or("no pairs yet".to_string(), |c| verdict(pd, c)),
            format!(
                "{:.0}× / {ratio}",
                paper(a, &PAPER_TIME_RATIO).unwrap_or(f64::NAN)
            ),
        ]);
    }
    // The paper: "the baseline is the worst in 9 of 15 scenes".
    let mut worst = 0;
    let mut scored = 0;
    for sc in &lay.scenes {
        let row = Row {
            label: String::new(),
            condition: cond.clone(),
            scene: Some(sc.clone()),
        };
        let means: Vec<Option<f64>> = lay
            .arms
            .iter()
            .map(|&a| lay.row_mean(&row, a, m_chamfer))
            .collect();
        if means.iter().all(|m| m.is_some()) {
            scored += 1;
            let b = lay.arms.iter().position(|a| *a == AugMode::None);
            let base = b.and_then(|i| means[i]).unwrap_or(f64::NAN);
            worst += usize::from(means.iter().flatten().all(|&m| m <= base));
        }
    }
    let _ = writeln!(
        md,
        "The baseline is the worst arm (highest mean Chamfer) in **{worst} of {scored}** scenes \
         here; in the paper, in 9 of 15.\n"
    );
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

    /// Every degradation a plan can hold finds its row of the paper's table, in any spelling
    /// the command line accepts; a degradation left out would drop from the claim's verdict.
    #[test]
    fn every_degradation_finds_its_paper_row() {
        use crate::augment::DegradationKind;
        for k in DegradationKind::ALL {
            for cond in [
                format!("{}:{}", k.name(), k.default_q()),
                format!("{}:1", k.name().replace('-', "_")),
                k.name().to_uppercase(),
            ] {
                assert!(
                    PAPER_DEGRADED
                        .iter()
                        .any(|(key, _, _)| paper_key(&cond) == *key),
                    "{cond} has no row in the paper's table"
                );
            }
        }
        for (key, _, _) in PAPER_REDUCED {
            assert_eq!(paper_key(key), key);
        }
    }

    #[test]
    fn verdicts_follow_the_interval() {
        let ci = |lo: f64, hi: f64| Ci {
            mean: 0.5 * (lo + hi),
            lo,
            hi,
            n: 3,
            min_stratum: 3,
        };
        assert!(verdict(-0.12, &ci(-0.3, -0.1)).starts_with("agrees"));
        assert!(verdict(-0.12, &ci(-0.3, 0.1)).contains("inconclusive"));
        // The smallest detectable difference: 2.8 standard errors, the interval ±1.96 of them.
        assert!((detectable(&ci(-0.3, 0.1)) - 2.8 * 0.4 / 3.92).abs() < 1e-12);
        assert!(verdict(-0.12, &ci(-0.3, 0.1)).contains("could detect ≥ 0.286 mm"));
        assert!(verdict(-0.12, &ci(0.1, 0.3)).starts_with("disagrees"));
        assert!(verdict(0.0, &ci(-0.1, 0.1)).starts_with("agrees"));
        assert!(verdict(0.0, &ci(0.1, 0.2)).contains("worse"));
        assert!(verdict(0.0, &ci(-0.2, -0.1)).contains("better"));
    }

    /// One pair per scene: the stratified bootstrap has no within-scene spread to resample, so
    /// an interval that excludes 0 must not become "agrees" or "disagrees".
    #[test]
    fn one_pair_per_scene_gives_a_provisional_verdict() {
        let one_each: Vec<Vec<f64>> = [0.010, 0.006, 0.009].iter().map(|&d| vec![d]).collect();
        let ci = stats::paired_ci("x", &one_each).unwrap();
        assert_eq!(ci.min_stratum, 1);
        // The interval is narrow and excludes 0 …
        assert!(ci.lo > 0.0, "{ci:?}");
        // … yet the verdict waits for a second seed.
        let v = verdict(-0.12, &ci);
        assert!(v.starts_with("provisional"), "{v}");
        assert!(v.contains("opposite direction"), "{v}");
        assert!(verdict(0.0, &ci).starts_with("provisional"));
        // With two pairs in every scene the same differences are judged.
        let two_each: Vec<Vec<f64>> = one_each.iter().map(|s| vec![s[0], s[0] + 0.002]).collect();
        let ci2 = stats::paired_ci("x", &two_each).unwrap();
        assert_eq!(ci2.min_stratum, 2);
        assert!(verdict(-0.12, &ci2).starts_with("disagrees"));
    }
}
