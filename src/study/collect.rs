//! `neus-aug study collect DIR`: aggregates what a study folder holds into tables, data files
//! and plots.
//!
//! Reads only `study.toml` (and `base.toml`, to name differing keys when a run folder does not
//! match), each run's `config.toml` (checked against the plan) and `metrics.json`. Everything
//! is ordered by the plan, floats are printed with fixed precision in the Markdown and with
//! Rust's shortest round-trip form in CSV/JSON, and the bootstrap is seeded, so the outputs are
//! the same bytes every time for the same run folders.
//!
//! Outputs (in `DIR/report/` unless `--to`): `report.md` (the tables), `runs.csv` and
//! `runs.json` (one row per collected run), `summary.json` (every aggregate and interval),
//! `chamfer.png` (bars with ±1 std error bars), `chamfer_vs_views.png` (reduced),
//! `pareto.csv` + `pareto.png` (pareto).

use super::grid::{arm_name, arm_title, scene_label, Grid};
use super::plan::{self, run_dir, run_state, RunSpec, RunState, StudyPlan, BASE_CONFIG_FILE};
use super::plot;
use super::stats::{self, Ci};
use super::{io_err, write_atomic, StudyError};
use crate::augment::AugMode;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Default output folder inside a study folder.
pub const REPORT_DIR: &str = "report";

/// The part of `metrics.json` a study reads (see `reconstruct::Metrics`).
#[derive(Deserialize)]
struct MetricsIn {
    config_hash: String,
    chamfer: Option<ChamferIn>,
    psnr_heldout: Option<f64>,
    ssim_heldout: Option<f64>,
    train: TrainIn,
    timings_s: TimingsIn,
}

#[derive(Deserialize)]
struct ChamferIn {
    mean_d2s: f64,
    mean_s2d: f64,
    overall: f64,
    chamfer_sum: f64,
}

#[derive(Deserialize)]
struct TrainIn {
    iterations: u64,
    resumed_from: Option<u64>,
}

#[derive(Deserialize)]
struct TimingsIn {
    load: f64,
    prepare: f64,
    train: f64,
    mesh: f64,
    eval: f64,
    render: f64,
    total: f64,
}

/// One collected run: the plan's description and what its `metrics.json` says. Distances in
/// world mm, times in seconds.
#[derive(Clone, Debug, Serialize)]
pub struct RunRecord {
    pub id: String,
    pub scene: String,
    pub condition: String,
    /// `baseline`, `sia` or `dia`.
    pub arm: String,
    pub seed: u64,
    pub preset: String,
    pub views_fraction: Option<f64>,
    pub degrade: Option<String>,
    /// Accuracy + completeness (the paper's figure).
    pub chamfer_sum: Option<f64>,
    /// Accuracy: mean mesh → GT distance.
    pub accuracy: Option<f64>,
    /// Completeness: mean GT → mesh distance.
    pub completeness: Option<f64>,
    /// `(acc + comp) / 2` (DTUeval-python's "overall").
    pub overall: Option<f64>,
    pub psnr: Option<f64>,
    pub ssim: Option<f64>,
    pub iterations: u64,
    /// The step training resumed from (an interrupted run, or a reused training).
    pub resumed_from: Option<u64>,
    /// The run started from another run's final checkpoint (mesh-only variant).
    pub reused_training: bool,
    pub time_load: f64,
    pub time_prepare: f64,
    /// Training time of this process (0 when the training was reused).
    pub time_train: f64,
    pub time_mesh: f64,
    pub time_eval: f64,
    pub time_render: f64,
    pub time_total: f64,
    /// Load + prepare + train + mesh, with the source run's training time for a reused training:
    /// what producing this mesh costs, without scoring and held-out renders.
    pub time_to_mesh: f64,
}

/// What [`collect`] found and wrote.
#[derive(Clone, Debug)]
pub struct CollectSummary {
    pub planned: usize,
    pub collected: usize,
    /// Runs without `metrics.json` yet.
    pub missing: Vec<String>,
    pub files: Vec<PathBuf>,
}

/// Reads every finished run of the study in `dir`, checking each against the plan.
pub fn load_records(dir: &Path) -> Result<(StudyPlan, Vec<RunRecord>), StudyError> {
    let plan = StudyPlan::load(dir)?;
    let base = dir.join(BASE_CONFIG_FILE);
    let base = plan.options.base_config.then_some(base.as_path());
    if let Some(b) = base {
        if !b.is_file() {
            return Err(StudyError::Folder {
                dir: dir.into(),
                problem: format!("the plan uses {BASE_CONFIG_FILE}, which is missing"),
            });
        }
    }
    let mut records: Vec<RunRecord> = Vec::new();
    for spec in &plan.runs {
        let state = match run_state(dir, spec, None) {
            Ok(s) => s,
            Err(StudyError::RunMismatch { .. }) => {
                // Name the differing keys when the planned configuration can be rebuilt.
                let planned = plan::resolve_run(spec, &plan.options, base, dir)
                    .ok()
                    .filter(|c| plan::config_hash(c) == spec.config_hash)
                    .map(|c| c.to_toml());
                run_state(dir, spec, planned.as_deref())?
            }
            Err(e) => return Err(e),
        };
        if state != RunState::Done {
            continue;
        }
        records.push(read_record(dir, spec)?);
    }
    // A reused training costs the source run's training time.
    let train_of: std::collections::BTreeMap<String, f64> = records
        .iter()
        .map(|r| (r.id.clone(), r.time_train))
        .collect();
    for (r, spec) in records.iter_mut().filter_map(|r| {
        let s = plan.run(&r.id).cloned();
        s.map(|s| (r, s))
    }) {
        if let Some(src) = &spec.reuse_training_of {
            if r.resumed_from == Some(r.iterations) {
                r.reused_training = true;
                if let Some(t) = train_of.get(src) {
                    r.time_to_mesh += t;
                }
            }
        }
    }
    Ok((plan, records))
}

fn read_record(dir: &Path, spec: &RunSpec) -> Result<RunRecord, StudyError> {
    let path = run_dir(dir, &spec.id).join("metrics.json");
    let text = std::fs::read_to_string(&path).map_err(io_err(&path))?;
    let m: MetricsIn = serde_json::from_str(&text).map_err(|e| StudyError::Parse {
        path: path.clone(),
        message: e.to_string(),
    })?;
    if m.config_hash != spec.training_hash {
        return Err(StudyError::RunMismatch {
            path: run_dir(dir, &spec.id),
            problem: format!(
                "its metrics.json was trained under configuration hash {}, the plan's is {}",
                m.config_hash, spec.training_hash
            ),
        });
    }
    let t = &m.timings_s;
    let c = m.chamfer.as_ref();
    Ok(RunRecord {
        id: spec.id.clone(),
        scene: scene_label(&spec.scene),
        condition: spec.condition.clone(),
        arm: arm_name(spec.arm).into(),
        seed: spec.seed,
        preset: spec.preset.name().into(),
        views_fraction: spec.views_fraction,
        degrade: spec.degrade.clone(),
        chamfer_sum: c.map(|c| c.chamfer_sum),
        accuracy: c.map(|c| c.mean_d2s),
        completeness: c.map(|c| c.mean_s2d),
        overall: c.map(|c| c.overall),
        psnr: m.psnr_heldout,
        ssim: m.ssim_heldout,
        iterations: m.train.iterations,
        resumed_from: m.train.resumed_from,
        reused_training: false,
        time_load: t.load,
        time_prepare: t.prepare,
        time_train: t.train,
        time_mesh: t.mesh,
        time_eval: t.eval,
        time_render: t.render,
        time_total: t.total,
        time_to_mesh: t.load + t.prepare + t.train + t.mesh,
    })
}

/// A row of the tables: one scene of one condition, or (`scene: None`) the mean over scenes.
#[derive(Clone, Debug, Serialize)]
struct Row {
    label: String,
    condition: String,
    scene: Option<String>,
}

/// The collected runs arranged by condition, scene, arm and seed.
struct Layout<'a> {
    plan: &'a StudyPlan,
    records: &'a [RunRecord],
    conditions: Vec<String>,
    scenes: Vec<String>,
    arms: Vec<AugMode>,
}

fn push_unique<T: PartialEq + Clone>(v: &mut Vec<T>, x: &T) {
    if !v.contains(x) {
        v.push(x.clone());
    }
}

type Metric = fn(&RunRecord) -> Option<f64>;

fn m_chamfer(r: &RunRecord) -> Option<f64> {
    r.chamfer_sum
}
fn m_acc(r: &RunRecord) -> Option<f64> {
    r.accuracy
}
fn m_comp(r: &RunRecord) -> Option<f64> {
    r.completeness
}
fn m_psnr(r: &RunRecord) -> Option<f64> {
    r.psnr
}
fn m_train(r: &RunRecord) -> Option<f64> {
    Some(r.time_train).filter(|_| !r.reused_training)
}
fn m_mesh_time(r: &RunRecord) -> Option<f64> {
    Some(r.time_to_mesh)
}

impl<'a> Layout<'a> {
    fn new(plan: &'a StudyPlan, records: &'a [RunRecord]) -> Self {
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

    fn rows(&self) -> Vec<Row> {
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
    fn cell(&self, cond: &str, scene: &str, arm: AugMode, f: Metric) -> Vec<(u64, f64)> {
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

    fn values(&self, cond: &str, scene: &str, arm: AugMode, f: Metric) -> Vec<f64> {
        self.cell(cond, scene, arm, f)
            .into_iter()
            .map(|p| p.1)
            .collect()
    }

    /// Scenes of `cond` where every arm has at least one value: the mean rows compare like with
    /// like.
    fn complete_scenes(&self, cond: &str, f: Metric) -> Vec<&String> {
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
    fn row_mean(&self, row: &Row, arm: AugMode, f: Metric) -> Option<f64> {
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
    fn row_std(&self, row: &Row, arm: AugMode, f: Metric) -> Option<f64> {
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

    fn row_n(&self, row: &Row, arm: AugMode, f: Metric) -> usize {
        match &row.scene {
            Some(s) => self.values(&row.condition, s, arm, f).len(),
            None => self
                .scenes
                .iter()
                .map(|s| self.values(&row.condition, s, arm, f).len())
                .sum(),
        }
    }

    fn planned_n(&self, row: &Row, arm: AugMode) -> usize {
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
    fn paired(&self, row: &Row, arm: AugMode, f: Metric) -> Vec<Vec<f64>> {
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

    fn has_baseline_and_others(&self) -> bool {
        self.arms.contains(&AugMode::None) && self.arms.len() > 1
    }
}

/// Differences `a − b` of the seeds both have.
fn pairs(a: &[(u64, f64)], b: &[(u64, f64)]) -> Vec<f64> {
    a.iter()
        .filter_map(|(s, x)| b.iter().find(|(t, _)| t == s).map(|(_, y)| x - y))
        .collect()
}

fn fmt_opt(v: Option<f64>, prec: usize) -> String {
    v.map_or("—".into(), |x| format!("{x:.prec$}"))
}

/// Seconds: one decimal below 10 s, whole seconds above.
fn fmt_time(v: Option<f64>) -> String {
    match v {
        Some(x) if x < 10.0 => format!("{x:.1}"),
        v => fmt_opt(v, 0),
    }
}

fn fmt_signed(x: f64, prec: usize) -> String {
    let s = format!("{x:+.prec$}");
    s.replace('-', "−")
}

fn fmt_ci(ci: &Option<Ci>) -> String {
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
fn rank_marks(vals: &[Option<f64>], prec: usize) -> Vec<String> {
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
fn arm_rows(
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

fn md_table(out: &mut String, header: &[String], rows: &[Vec<String>]) {
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

/// Aggregates of one row and arm (for `summary.json`).
#[derive(Serialize)]
struct CellSummary {
    row: String,
    condition: String,
    scene: Option<String>,
    arm: String,
    n: usize,
    planned: usize,
    chamfer_mean: Option<f64>,
    chamfer_std: Option<f64>,
    accuracy_mean: Option<f64>,
    completeness_mean: Option<f64>,
    psnr_mean: Option<f64>,
    train_time_mean: Option<f64>,
    time_to_mesh_mean: Option<f64>,
}

#[derive(Serialize)]
struct DiffSummary {
    row: String,
    arm: String,
    /// `arm − baseline` Chamfer sum, mm, with its 95 % bootstrap interval.
    chamfer_diff: Option<Ci>,
}

#[derive(Serialize)]
struct Summary {
    grid: String,
    preset: String,
    seeds: u32,
    scenes: Vec<String>,
    planned: usize,
    collected: usize,
    bootstrap_resamples: usize,
    bootstrap_seed: u64,
    cells: Vec<CellSummary>,
    paired_differences: Vec<DiffSummary>,
}

/// The command that (re)creates this study, with `STUDY_DIR` for the folder.
fn study_command(plan: &StudyPlan) -> String {
    let o = &plan.options;
    let mut c = format!(
        "neus-aug study {} --preset {} --seeds {} --scenes {}",
        o.grid,
        o.preset.name(),
        o.seeds,
        super::jobs::shell_quote(&o.scenes.join(","))
    );
    if o.grid.uses_ia() {
        let _ = write!(c, " --ia {}", o.ia.name());
    }
    if o.base_config {
        let _ = write!(c, " --config STUDY_DIR/{BASE_CONFIG_FILE}");
    }
    for s in &o.sets {
        let _ = write!(c, " --set {}", super::jobs::shell_quote(s));
    }
    c.push_str(" --out STUDY_DIR");
    c
}

/// Collects the study in `dir` and writes the report files into `to` (created).
pub fn collect(dir: &Path, to: &Path) -> Result<CollectSummary, StudyError> {
    let (plan, records) = load_records(dir)?;
    std::fs::create_dir_all(to).map_err(io_err(to))?;
    let lay = Layout::new(&plan, &records);
    let rows = lay.rows();
    let mut files = Vec::new();
    let mut put = |name: &str, bytes: &[u8]| -> Result<(), StudyError> {
        let p = to.join(name);
        write_atomic(&p, bytes)?;
        files.push(p);
        Ok(())
    };
    let o = &plan.options;
    let missing: Vec<String> = plan
        .runs
        .iter()
        .filter(|r| !records.iter().any(|x| x.id == r.id))
        .map(|r| r.id.clone())
        .collect();

    let mut md = String::new();
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
        study_command(&plan)
    );
    let _ = writeln!(
        md,
        "Distances are the DTU protocol in mm (accuracy = mesh → ground truth, completeness = \
         ground truth → mesh, Chamfer = accuracy + completeness as in the paper); lower is \
         better. Means are over seeds; a `mean` row averages the scenes where every arm has \
         results.\n"
    );

    let arm_header = |first: &str| {
        let mut h = vec![first.to_string()];
        h.extend(lay.arms.iter().map(|a| arm_title(*a).to_string()));
        h
    };
    let first_col = if lay.conditions.len() > 1 {
        "condition"
    } else {
        "scene"
    };

    // Chamfer means, best bold, runner-up italic; time beside it.
    let _ = writeln!(
        md,
        "## Chamfer distance (mm, mean over seeds; best **bold**, runner-up *italic*)\n"
    );
    let mut t = Vec::new();
    for r in &rows {
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
            .map(|&a| stats::mean(&all_values(&lay, &all, a, m_train)))
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
    let t = arm_rows(&rows, &lay.arms, |r, a| {
        fmt_opt(lay.row_std(r, a, m_chamfer), 3)
    });
    md_table(&mut md, &arm_header(first_col), &t);
    let _ = writeln!(
        md,
        "A `mean` row gives √(mean of the per-scene variances).\n"
    );

    // Accuracy / completeness.
    let _ = writeln!(md, "## Accuracy / completeness (mm)\n");
    let t = arm_rows(&rows, &lay.arms, |r, a| {
        format!(
            "{} / {}",
            fmt_opt(lay.row_mean(r, a, m_acc), 3),
            fmt_opt(lay.row_mean(r, a, m_comp), 3)
        )
    });
    md_table(&mut md, &arm_header(first_col), &t);

    // Paired differences.
    let mut diffs = Vec::new();
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
        let mut all_rows = rows.clone();
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
        md_table(&mut md, &h, &t);
    }

    // Against the paper (Table 2 only: the figures of DESIGN §8).
    if o.grid == Grid::Table2 && lay.has_baseline_and_others() {
        paper_section(&mut md, &lay);
    }

    // Held-out PSNR.
    let _ = writeln!(md, "## Held-out views: PSNR (dB, higher is better)\n");
    let t = arm_rows(&rows, &lay.arms, |r, a| {
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
            .map(|&a| stats::mean(&all_values(&lay, &row, a, m_train)))
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
    let pareto = plan::is_pareto(&plan);
    let mut pareto_rows = Vec::new();
    if pareto {
        pareto_rows = pareto_points(&lay);
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
    let t = arm_rows(&rows, &lay.arms, |r, a| {
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
        if pareto { "" } else { ", `chamfer.png`" },
        if o.grid == Grid::Reduced {
            ", `chamfer_vs_views.png`"
        } else {
            ""
        },
        if pareto {
            ", `pareto.csv`, `pareto.png`"
        } else {
            ""
        }
    );
    put("report.md", md.as_bytes())?;

    // Per-run data.
    put("runs.csv", runs_csv(&records).as_bytes())?;
    let json = serde_json::to_string_pretty(&records).expect("records serialise");
    put("runs.json", format!("{json}\n").as_bytes())?;
    let mut cells = Vec::new();
    for r in &rows {
        for &a in &lay.arms {
            cells.push(CellSummary {
                row: r.label.clone(),
                condition: r.condition.clone(),
                scene: r.scene.clone(),
                arm: arm_name(a).into(),
                n: lay.row_n(r, a, m_chamfer),
                planned: lay.planned_n(r, a),
                chamfer_mean: lay.row_mean(r, a, m_chamfer),
                chamfer_std: lay.row_std(r, a, m_chamfer),
                accuracy_mean: lay.row_mean(r, a, m_acc),
                completeness_mean: lay.row_mean(r, a, m_comp),
                psnr_mean: lay.row_mean(r, a, m_psnr),
                train_time_mean: stats::mean(&all_values(&lay, r, a, m_train)),
                time_to_mesh_mean: stats::mean(&all_values(&lay, r, a, m_mesh_time)),
            });
        }
    }
    let summary = Summary {
        grid: o.grid.to_string(),
        preset: o.preset.name().into(),
        seeds: o.seeds,
        scenes: lay.scenes.clone(),
        planned: plan.runs.len(),
        collected: records.len(),
        bootstrap_resamples: stats::RESAMPLES,
        bootstrap_seed: stats::BOOTSTRAP_SEED,
        cells,
        paired_differences: diffs,
    };
    let json = serde_json::to_string_pretty(&summary).expect("summary serialises");
    put("summary.json", format!("{json}\n").as_bytes())?;

    // Plots.
    if !pareto {
        let bars = plot::Bars {
            title: format!("{}: Chamfer distance (mean ± 1 std over seeds)", o.grid),
            y_label: "Chamfer acc + comp (mm)".into(),
            groups: rows.iter().map(|r| r.label.clone()).collect(),
            series: lay.arms.iter().map(|a| arm_title(*a).to_string()).collect(),
            values: rows
                .iter()
                .map(|r| {
                    lay.arms
                        .iter()
                        .map(|&a| {
                            lay.row_mean(r, a, m_chamfer)
                                .map(|m| (m, lay.row_std(r, a, m_chamfer).unwrap_or(0.0)))
                        })
                        .collect()
                })
                .collect(),
        };
        put("chamfer.png", &plot::bar_chart("chamfer.png", &bars)?)?;
    }
    if o.grid == Grid::Reduced {
        let series = lay
            .arms
            .iter()
            .map(|&a| {
                let pts = lay
                    .conditions
                    .iter()
                    .filter_map(|c| {
                        let x = plan
                            .runs
                            .iter()
                            .find(|r| &r.condition == c)?
                            .views_fraction?;
                        let row = Row {
                            label: String::new(),
                            condition: c.clone(),
                            scene: if lay.scenes.len() == 1 {
                                Some(lay.scenes[0].clone())
                            } else {
                                None
                            },
                        };
                        let m = lay.row_mean(&row, a, m_chamfer)?;
                        Some((x * 100.0, m, lay.row_std(&row, a, m_chamfer).unwrap_or(0.0)))
                    })
                    .collect();
                (arm_title(a).to_string(), pts)
            })
            .collect();
        let lines = plot::Lines {
            title: "reduced data: Chamfer against the share of training views".into(),
            x_label: "training views kept (%)".into(),
            y_label: "Chamfer acc + comp (mm)".into(),
            series,
        };
        put(
            "chamfer_vs_views.png",
            &plot::line_chart("chamfer_vs_views.png", &lines)?,
        )?;
    }
    if pareto {
        put("pareto.csv", pareto_csv(&pareto_rows).as_bytes())?;
        let centre = o.preset.name();
        let pts: Vec<plot::ParetoPoint> = pareto_rows
            .iter()
            .filter_map(|p| {
                Some(plot::ParetoPoint {
                    time: p.time_to_mesh_mean?,
                    chamfer: p.chamfer_mean?,
                    label: if p.condition == "centre" {
                        format!("{centre} (preset)")
                    } else if let Some(pr) = p.condition.strip_prefix("preset=") {
                        format!("{pr} (preset)")
                    } else {
                        p.condition.clone()
                    },
                    preset: p.condition == "centre" || p.condition.starts_with("preset="),
                    on_front: p.on_front,
                })
            })
            .collect();
        let title = format!("accuracy against time ({})", lay.scenes.join(", "));
        put("pareto.png", &plot::pareto_chart(&title, &pts)?)?;
    }

    Ok(CollectSummary {
        planned: plan.runs.len(),
        collected: records.len(),
        missing,
        files,
    })
}

/// The paper's NeuS figures on DTU (mean Chamfer sum over the 15 scans, 5 runs; training time
/// on an A100): ../shared/DESIGN.md §8.
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
fn verdict(paper_diff: f64, ci: &Ci) -> &'static str {
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
fn paper_section(md: &mut String, lay: &Layout<'_>) {
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

/// Every value of a row (all its scenes when `scene` is `None`), in plan order.
fn all_values(lay: &Layout<'_>, row: &Row, arm: AugMode, f: Metric) -> Vec<f64> {
    match &row.scene {
        Some(s) => lay.values(&row.condition, s, arm, f),
        None => lay
            .scenes
            .iter()
            .flat_map(|s| lay.values(&row.condition, s, arm, f))
            .collect(),
    }
}

/// One pareto variant, averaged over seeds (and scenes).
#[derive(Clone, Debug, Serialize)]
struct ParetoRow {
    condition: String,
    n: usize,
    chamfer_mean: Option<f64>,
    chamfer_std: Option<f64>,
    time_to_mesh_mean: Option<f64>,
    train_mean: Option<f64>,
    mesh_mean: Option<f64>,
    on_front: bool,
}

fn pareto_points(lay: &Layout<'_>) -> Vec<ParetoRow> {
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

fn csv_opt(v: Option<f64>) -> String {
    v.map_or(String::new(), |x| x.to_string())
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn runs_csv(records: &[RunRecord]) -> String {
    let mut s = String::from(
        "id,scene,condition,arm,seed,preset,views_fraction,degrade,chamfer_sum,accuracy,\
         completeness,overall,psnr,ssim,iterations,resumed_from,reused_training,time_load,\
         time_prepare,time_train,time_mesh,time_eval,time_render,time_total,time_to_mesh\n",
    );
    for r in records {
        let f = [
            csv_field(&r.id),
            csv_field(&r.scene),
            csv_field(&r.condition),
            r.arm.clone(),
            r.seed.to_string(),
            r.preset.clone(),
            csv_opt(r.views_fraction),
            csv_field(r.degrade.as_deref().unwrap_or("")),
            csv_opt(r.chamfer_sum),
            csv_opt(r.accuracy),
            csv_opt(r.completeness),
            csv_opt(r.overall),
            csv_opt(r.psnr),
            csv_opt(r.ssim),
            r.iterations.to_string(),
            r.resumed_from.map_or(String::new(), |x| x.to_string()),
            r.reused_training.to_string(),
            r.time_load.to_string(),
            r.time_prepare.to_string(),
            r.time_train.to_string(),
            r.time_mesh.to_string(),
            r.time_eval.to_string(),
            r.time_render.to_string(),
            r.time_total.to_string(),
            r.time_to_mesh.to_string(),
        ];
        s.push_str(&f.join(","));
        s.push('\n');
    }
    s
}

fn pareto_csv(rows: &[ParetoRow]) -> String {
    let mut s = String::from(
        "variant,factor,value,n,chamfer_mean,chamfer_std,time_to_mesh_mean,train_mean,mesh_mean,on_front\n",
    );
    for r in rows {
        let (factor, value) = r
            .condition
            .split_once('=')
            .map_or((r.condition.as_str(), ""), |(f, v)| (f, v));
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{}",
            csv_field(&r.condition),
            csv_field(factor),
            csv_field(value),
            r.n,
            csv_opt(r.chamfer_mean),
            csv_opt(r.chamfer_std),
            csv_opt(r.time_to_mesh_mean),
            csv_opt(r.train_mean),
            csv_opt(r.mesh_mean),
            r.on_front
        );
    }
    s
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

    #[test]
    fn ranks_mark_best_and_runner_up() {
        let v = rank_marks(&[Some(2.0), Some(1.0), None, Some(3.0)], 2);
        assert_eq!(v, ["*2.00*", "**1.00**", "—", "3.00"]);
        assert_eq!(rank_marks(&[Some(2.0), Some(1.0)], 1), ["2.0", "**1.0**"]);
        assert_eq!(rank_marks(&[Some(2.0)], 1), ["2.0"]);
    }

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

    #[test]
    fn pairs_match_seeds() {
        let a = [(0, 1.0), (1, 2.0), (3, 5.0)];
        let b = [(1, 1.5), (0, 0.5), (2, 9.0)];
        assert_eq!(pairs(&a, &b), vec![0.5, 0.5]);
    }

    #[test]
    fn signed_format_uses_a_true_minus() {
        assert_eq!(fmt_signed(-0.0123, 3), "−0.012");
        assert_eq!(fmt_signed(0.5, 2), "+0.50");
    }
}
