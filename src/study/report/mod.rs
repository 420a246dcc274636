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
//! `chamfer_by_degradation.png` (degraded: one group per degradation, scene means),
//! `pareto.csv` + `pareto.png` (pareto).
//!
//! One file per concern: `records` reads the run folders, `layout` arranges runs by
//! condition, scene, arm and seed and aggregates them, `markdown` writes `report.md` (with
//! `paper`, the comparison with the paper's figures, and `pareto`, accuracy against time),
//! `csv` the CSV files; this module writes the files and the plots.

mod csv;
mod format;
mod hard;
mod layout;
mod markdown;
mod paper;
mod pareto;
mod records;

pub use pareto::{pareto_front, read_reference_front};
pub use records::{load_records, GeometryRecord, RunRecord};

use super::grid::{arm_name, arm_title, Grid};
use super::plot;
use super::stats::{self, Ci};
use super::{io_err, plan, write_atomic, StudyError};
use layout::{all_values, m_acc, m_chamfer, m_comp, m_mesh_time, m_psnr, m_train, Layout, Row};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Default output folder inside a study folder.
pub const REPORT_DIR: &str = "report";

/// What [`collect`] found and wrote.
#[derive(Clone, Debug)]
pub struct CollectSummary {
    pub planned: usize,
    pub collected: usize,
    /// Runs without `metrics.json` yet.
    pub missing: Vec<String>,
    pub files: Vec<PathBuf>,
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
    /// The geometry against the ground truth (`hard`, or runs that recorded it).
    #[serde(skip_serializing_if = "Option::is_none")]
    geometry: Option<hard::GeometrySummary>,
}

/// Part of a study to report (`study collect DIR --scenes A,B --seeds N`): the runs of these
/// scenes (by name, as the report names them) and of seeds `0..N`. The report then reads as
/// the report of a study planned with those options, which would hold exactly these runs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Subset {
    /// Scene names; `None` keeps every scene.
    pub scenes: Option<Vec<String>>,
    /// Keep seeds `0..n`; `None` keeps every seed.
    pub seeds: Option<u32>,
}

impl Subset {
    /// Restricts `plan` and `records` to the subset. An unknown scene, or a seed count of 0
    /// or above the plan's, is refused by option.
    pub fn restrict(
        &self,
        plan: &mut plan::StudyPlan,
        records: &mut Vec<RunRecord>,
    ) -> Result<(), StudyError> {
        let o = &mut plan.options;
        if let Some(names) = &self.scenes {
            let labels: Vec<String> = o
                .scenes
                .iter()
                .map(|s| super::grid::scene_label(s))
                .collect();
            if let Some(bad) = names.iter().find(|n| !labels.contains(n)) {
                return Err(StudyError::Option {
                    option: "--scenes".into(),
                    value: bad.clone(),
                    why: format!("the study holds the scenes {}", labels.join(", ")),
                });
            }
            o.scenes
                .retain(|s| names.contains(&super::grid::scene_label(s)));
            plan.runs.retain(|r| names.contains(&r.scene_label()));
        }
        if let Some(n) = self.seeds {
            if n == 0 || n > o.seeds {
                return Err(StudyError::Option {
                    option: "--seeds".into(),
                    value: n.to_string(),
                    why: format!("the study has seeds 0..{}; give 1 to {}", o.seeds, o.seeds),
                });
            }
            o.seeds = n;
            plan.runs.retain(|r| r.seed < u64::from(n));
        }
        records.retain(|r| plan.runs.iter().any(|s| s.id == r.id));
        Ok(())
    }
}

/// What `study collect` may add to [`collect`]: a reference front, a subset.
#[derive(Clone, Debug, Default)]
pub struct CollectOptions<'a> {
    /// Another pareto study's front, drawn beside this one's in `pareto.png`
    /// (`--reference-front`). Refused for a study of another grid (there is no
    /// accuracy-against-time plot to draw it in).
    pub reference: Option<&'a plot::ReferenceFront>,
    /// Report only part of the study.
    pub subset: Subset,
}

/// Collects the study in `dir` and writes the report files into `to` (created).
pub fn collect(dir: &Path, to: &Path) -> Result<CollectSummary, StudyError> {
    collect_with(dir, to, &CollectOptions::default())
}

/// [`collect`] with the options of [`CollectOptions`].
pub fn collect_with(
    dir: &Path,
    to: &Path,
    opts: &CollectOptions<'_>,
) -> Result<CollectSummary, StudyError> {
    let reference = opts.reference;
    super::plan::sync_records(dir, &super::plan::StudyPlan::load(dir)?)?;
    let (mut plan, mut records) = load_records(dir)?;
    opts.subset.restrict(&mut plan, &mut records)?;
    if let (Some(r), false) = (reference, plan::is_pareto(&plan)) {
        return Err(StudyError::Option {
            option: "--reference-front".into(),
            value: r.label.clone(),
            why: format!(
                "{} holds a `{}` study; only a `pareto` study has a front to draw it beside",
                dir.display(),
                plan.options.grid.name()
            ),
        });
    }
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
    let pareto = plan::is_pareto(&plan).then(|| pareto::pareto_points(&lay));
    let hard_report = matches!(o.grid, Grid::Hard | Grid::Outside);
    let with_geometry = hard_report || records.iter().any(|r| r.geometry.is_some());
    let (md, diffs) = if hard_report {
        hard::report_md(&lay, &missing)
    } else {
        markdown::report_md(&lay, &rows, &missing, pareto.as_deref())
    };
    put("report.md", md.as_bytes())?;

    // Per-run data.
    put("runs.csv", csv::runs_csv(&records).as_bytes())?;
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
        geometry: with_geometry.then(|| hard::summarise(&lay)),
    };
    let json = serde_json::to_string_pretty(&summary).expect("summary serialises");
    put("summary.json", format!("{json}\n").as_bytes())?;

    // Plots.
    // Bars of the Chamfer of `pick`, one group per row (named by `name`), one bar per arm:
    // the row's mean with its std over seeds.
    let chamfer_bars = |title: String, pick: &[&Row], name: &dyn Fn(&Row) -> String| plot::Bars {
        title,
        y_label: "Chamfer acc + comp (mm)".into(),
        groups: pick.iter().map(|r| name(r)).collect(),
        series: lay.arms.iter().map(|a| arm_title(*a).to_string()).collect(),
        values: pick
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
    if pareto.is_none() {
        let all: Vec<&Row> = rows.iter().collect();
        let title = format!("{}: Chamfer distance (mean ± 1 std over seeds)", o.grid);
        let bars = chamfer_bars(title, &all, &|r| r.label.clone());
        put("chamfer.png", &plot::bar_chart("chamfer.png", &bars)?)?;
    }
    if o.grid == Grid::Degraded {
        // One group per degradation: the scene mean (or the one scene), both arms.
        let pick: Vec<&Row> = rows
            .iter()
            .filter(|r| r.scene.is_none() || lay.scenes.len() == 1)
            .collect();
        let title = "degraded images: Chamfer per degradation \
                     (mean over scenes, ± pooled std over seeds)";
        let bars = chamfer_bars(title.into(), &pick, &|r| r.condition.clone());
        put(
            "chamfer_by_degradation.png",
            &plot::bar_chart("chamfer_by_degradation.png", &bars)?,
        )?;
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
    if let Some(pareto_rows) = &pareto {
        put("pareto.csv", csv::pareto_csv(pareto_rows).as_bytes())?;
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
        put("pareto.png", &plot::pareto_chart(&title, &pts, reference)?)?;
    }

    Ok(CollectSummary {
        planned: plan.runs.len(),
        collected: records.len(),
        missing,
        files,
    })
}
