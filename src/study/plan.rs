//! The plan of a study (`study.toml`): its options and every run with the hashes of its resolved
//! configuration, and the checks that keep a study folder from mixing configurations.
//!
//! Each run's configuration is what `neus-aug reconstruct` resolves from the same inputs, in the
//! same order as its command line: preset → `base.toml` → scene, `--aug`, `--seed`,
//! `--views-fraction`, `--degrade`, `--out` → the study's `--set` → the run's own settings.

pub use super::confighash::{config_diff, config_hash, config_hash_of_toml};
use super::grid::{self, Grid, RunDraft, StudyOptions};
use super::store;
use super::{io_err, write_atomic, StudyError};
use crate::augment::AugMode;
use crate::reconstruct::{parse_set, resolve, Preset, RunConfig};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Version of the `study.toml` layout. Format 2 hashes each run's configuration as the program
/// reads it ([`config_hash_of_toml`]); format 1 hashed the text, which depended on the keys a
/// build left out. A format-1 plan is read, its hashes ignored and the plan rewritten.
pub const PLAN_FORMAT: u32 = 2;

/// File names inside a study folder.
pub const PLAN_FILE: &str = "study.toml";
pub const BASE_CONFIG_FILE: &str = "base.toml";
pub const RUNS_DIR: &str = "runs";

/// One planned run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunSpec {
    /// Folder name under `runs/`.
    pub id: String,
    /// The scene as `reconstruct` takes it.
    pub scene: String,
    /// Table row group (`full`, `views 10%`, `gaussian:0.1`, a pareto variant).
    pub condition: String,
    /// `none` (the baseline), `sia` or `dia`.
    pub arm: AugMode,
    pub seed: u64,
    pub preset: Preset,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub views_fraction: Option<f64>,
    /// `KIND:q`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub degrade: Option<String>,
    /// Run-specific `key=value` settings.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sets: Vec<String>,
    /// A run of the same training whose final checkpoint this one may start from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reuse_training_of: Option<String>,
    /// FNV-1a 64 of the resolved `config.toml` without its `out` key ([`config_hash`]).
    pub config_hash: String,
    /// `RunConfig::training_hash` (what `metrics.json` calls `config_hash`).
    pub training_hash: String,
}

impl RunSpec {
    /// The run's scene label.
    pub fn scene_label(&self) -> String {
        grid::scene_label(&self.scene)
    }
}

/// `study.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudyPlan {
    pub format: u32,
    pub options: StudyOptions,
    pub runs: Vec<RunSpec>,
}

/// The overrides `neus-aug reconstruct` would apply for `spec`'s command line (see
/// [`super::jobs::command_line`]), in the same order: scene, `--aug`, `--seed`,
/// `--views-fraction`, `--degrade`, `--out`, then the study's `--set` and the run's own.
pub fn overrides(
    spec: &RunSpec,
    out: &Path,
    study_sets: &[String],
) -> Result<Vec<(String, toml::Value)>, StudyError> {
    let s = |v: &str| toml::Value::String(v.to_string());
    let mut v = vec![
        ("scene".to_string(), s(&spec.scene)),
        ("augment.mode".to_string(), s(spec.arm.name())),
        ("seed".to_string(), toml::Value::Integer(spec.seed as i64)),
    ];
    if let Some(f) = spec.views_fraction {
        v.push(("data.views_fraction".into(), toml::Value::Float(f)));
    }
    if let Some(d) = &spec.degrade {
        v.push(("data.degrade".into(), s(d)));
    }
    v.push(("out".into(), s(&out.display().to_string())));
    for spec in study_sets.iter().chain(&spec.sets) {
        v.push(parse_set(spec)?);
    }
    Ok(v)
}

/// A study folder's run folder for `id`.
pub fn run_dir(dir: &Path, id: &str) -> PathBuf {
    dir.join(RUNS_DIR).join(id)
}

/// Resolves one run's configuration with its output in `dir/runs/<id>`.
pub fn resolve_run(
    spec: &RunSpec,
    opts: &StudyOptions,
    base_config: Option<&Path>,
    dir: &Path,
) -> Result<RunConfig, StudyError> {
    let ov = overrides(spec, &run_dir(dir, &spec.id), &opts.sets)?;
    Ok(resolve(Some(spec.preset), base_config, &ov)?)
}

/// The configuration the study's runs start from (preset → base config → `--set`), used to
/// size the pareto and smoke variants.
pub fn base_run_config(
    opts: &StudyOptions,
    base_config: Option<&Path>,
) -> Result<RunConfig, StudyError> {
    let mut ov = Vec::new();
    for s in &opts.sets {
        ov.push(parse_set(s)?);
    }
    Ok(resolve(Some(opts.preset), base_config, &ov)?)
}

/// Builds the plan: expands the grid and resolves every run (errors in `--set` or the base
/// config surface here, before anything runs). `base_config` is the file to read (the user's
/// `--config` when planning, the folder's `base.toml` afterwards); `dir` is the study folder.
/// Returns the plan and each run's resolved configuration, in plan order.
pub fn make_plan(
    opts: &StudyOptions,
    base_config: Option<&Path>,
    dir: &Path,
) -> Result<(StudyPlan, Vec<RunConfig>), StudyError> {
    opts.validate()?;
    if opts.base_config != base_config.is_some() {
        return Err(StudyError::Folder {
            dir: dir.into(),
            problem: format!(
                "the plan says base_config = {} but {} given",
                opts.base_config,
                if base_config.is_some() {
                    "a config file was"
                } else {
                    "no config file was"
                }
            ),
        });
    }
    let base = base_run_config(opts, base_config)?;
    let drafts = grid::expand(opts, &base);
    let mut runs = Vec::with_capacity(drafts.len());
    let mut cfgs = Vec::with_capacity(drafts.len());
    for d in drafts {
        let RunDraft {
            id,
            scene,
            condition,
            arm,
            seed,
            preset,
            views_fraction,
            degrade,
            sets,
            reuse_training_of,
        } = d;
        let mut spec = RunSpec {
            id,
            scene,
            condition,
            arm,
            seed,
            preset,
            views_fraction,
            degrade: degrade.map(|d| d.to_string()),
            sets,
            reuse_training_of,
            config_hash: String::new(),
            training_hash: String::new(),
        };
        let cfg = resolve_run(&spec, opts, base_config, dir)?;
        spec.config_hash = config_hash(&cfg);
        spec.training_hash = cfg.training_hash();
        runs.push(spec);
        cfgs.push(cfg);
    }
    // A reused training must really be the same training.
    for r in &runs {
        if let Some(src) = &r.reuse_training_of {
            let s = runs.iter().find(|x| &x.id == src);
            if s.map(|s| &s.training_hash) != Some(&r.training_hash) {
                return Err(StudyError::Folder {
                    dir: dir.into(),
                    problem: format!("run {} cannot reuse the training of {src}", r.id),
                });
            }
        }
    }
    Ok((
        StudyPlan {
            format: PLAN_FORMAT,
            options: opts.clone(),
            runs,
        },
        cfgs,
    ))
}

impl StudyPlan {
    /// Reads `dir/study.toml`.
    pub fn load(dir: &Path) -> Result<Self, StudyError> {
        let path = dir.join(PLAN_FILE);
        if !path.is_file() {
            return Err(StudyError::Folder {
                dir: dir.into(),
                problem: format!(
                    "no {PLAN_FILE}: not a study folder (make one with `neus-aug study GRID --out {}`)",
                    dir.display()
                ),
            });
        }
        let text = std::fs::read_to_string(&path).map_err(io_err(&path))?;
        let plan: StudyPlan = toml::from_str(&text).map_err(|e| StudyError::Parse {
            path: path.clone(),
            message: e.to_string(),
        })?;
        if !(1..=PLAN_FORMAT).contains(&plan.format) {
            return Err(StudyError::Folder {
                dir: dir.into(),
                problem: format!(
                    "{PLAN_FILE} has format {}, this program reads format {PLAN_FORMAT}",
                    plan.format
                ),
            });
        }
        Ok(plan)
    }

    /// The TOML of `study.toml`.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("plans serialise")
    }

    /// The run ids, in plan order.
    pub fn ids(&self) -> Vec<&str> {
        self.runs.iter().map(|r| r.id.as_str()).collect()
    }

    /// The run called `id`.
    pub fn run(&self, id: &str) -> Option<&RunSpec> {
        self.runs.iter().find(|r| r.id == id)
    }

    /// Differences from `other` (this = stored, other = requested), one line each, at most
    /// `limit`; empty when they are the same plan.
    pub fn differences(&self, other: &StudyPlan, limit: usize) -> Vec<String> {
        let mut d = Vec::new();
        let (a, b) = (&self.options, &other.options);
        let mut opt = |name: &str, x: String, y: String| {
            if x != y {
                d.push(format!("{name}: {x} → {y}"));
            }
        };
        opt("grid", a.grid.to_string(), b.grid.to_string());
        opt("scenes", a.scenes.join(","), b.scenes.join(","));
        opt("seeds", a.seeds.to_string(), b.seeds.to_string());
        opt("preset", a.preset.name().into(), b.preset.name().into());
        if a.grid.uses_ia() || b.grid.uses_ia() {
            opt("ia", a.ia.name().into(), b.ia.name().into());
        }
        opt(
            "--config",
            a.base_config.to_string(),
            b.base_config.to_string(),
        );
        opt("--set", a.sets.join(" "), b.sets.join(" "));
        // The same runs (in whatever order an older build listed them).
        let ids_a: std::collections::BTreeSet<&str> =
            self.runs.iter().map(|r| r.id.as_str()).collect();
        let ids_b: std::collections::BTreeSet<&str> =
            other.runs.iter().map(|r| r.id.as_str()).collect();
        if ids_a != ids_b {
            d.push(format!(
                "runs: {} planned → {} requested",
                ids_a.len(),
                ids_b.len()
            ));
        }
        // A format-1 plan's hashes were of the text, which this program writes otherwise.
        let comparable = self.format == other.format;
        for y in &other.runs {
            let Some(x) = self.run(&y.id) else { continue };
            if comparable && x.config_hash != y.config_hash {
                d.push(format!(
                    "run {}: resolved configuration {} → {} (a different base config or program version)",
                    x.id, x.config_hash, y.config_hash
                ));
            }
        }
        d.truncate(limit);
        d
    }
}

/// What a run folder holds.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RunState {
    /// Nothing yet.
    Empty,
    /// The planned configuration, unfinished (maybe with a checkpoint).
    Partial,
    /// The planned configuration, finished (`metrics.json`).
    Done,
}

/// Checks a run folder against the plan: its `config.toml` (when present) must be the planned
/// configuration, and a `metrics.json` must come with one. `planned_toml` (the resolved
/// configuration's TOML, when known) names the differing keys in the error.
pub fn run_state(
    dir: &Path,
    spec: &RunSpec,
    planned_toml: Option<&str>,
    records: &BTreeMap<String, store::StoredRun>,
) -> Result<RunState, StudyError> {
    let rd = run_dir(dir, &spec.id);
    let cfg_path = rd.join("config.toml");
    let metrics = rd.join("metrics.json").is_file();
    if !cfg_path.is_file() && !metrics {
        // A run finished elsewhere (or whose folder was cleared) that left its record.
        if store::planned_record(records, dir, &spec.id, &spec.config_hash)?.is_some() {
            return Ok(RunState::Done);
        }
    }
    if !cfg_path.is_file() {
        if metrics || rd.join("checkpoint.safetensors").is_file() {
            return Err(StudyError::RunMismatch {
                path: rd,
                problem: "it holds results but no config.toml to check them against".into(),
            });
        }
        return Ok(RunState::Empty);
    }
    let text = std::fs::read_to_string(&cfg_path).map_err(io_err(&cfg_path))?;
    let found = config_hash_of_toml(&text, &cfg_path)?;
    if found != spec.config_hash {
        let keys = planned_toml
            .map(|p| config_diff(&text, p, 8))
            .filter(|d| !d.is_empty())
            .map(|d| format!("; differing keys (found → planned): {}", d.join("; ")))
            .unwrap_or_default();
        return Err(StudyError::RunMismatch {
            path: rd,
            problem: format!(
                "its config.toml hashes to {found}, the plan to {}{keys}",
                spec.config_hash
            ),
        });
    }
    Ok(if metrics {
        RunState::Done
    } else {
        RunState::Partial
    })
}

/// Opens a study folder for `plan`: a new (or empty) folder gets `study.toml` (and `base.toml`
/// copied from `base_src`); an existing study must have been planned identically, else
/// [`StudyError::PlanMismatch`] lists the differences. Then every run folder is checked
/// ([`run_state`]); any mismatch is an error before anything runs. Returns each run's state.
pub fn open_folder(
    dir: &Path,
    plan: &StudyPlan,
    cfgs: &[RunConfig],
    base_src: Option<&Path>,
) -> Result<Vec<RunState>, StudyError> {
    let plan_path = dir.join(PLAN_FILE);
    if plan_path.is_file() {
        let stored = StudyPlan::load(dir)?;
        let diff = stored.differences(plan, 12);
        if diff.is_empty() && (stored.format != plan.format || stored.ids() != plan.ids()) {
            write_atomic(&plan_path, plan.to_toml().as_bytes())?;
        }
        if !diff.is_empty() {
            return Err(StudyError::PlanMismatch {
                dir: dir.into(),
                differences: diff
                    .iter()
                    .map(|l| format!("  {l}"))
                    .collect::<Vec<_>>()
                    .join("\n"),
            });
        }
    } else {
        if dir.join(RUNS_DIR).is_dir() {
            return Err(StudyError::Folder {
                dir: dir.into(),
                problem: format!(
                    "it has a {RUNS_DIR}/ folder but no {PLAN_FILE}; refusing to mix with unknown runs"
                ),
            });
        }
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
        if let Some(src) = base_src {
            let text = std::fs::read(src).map_err(io_err(src))?;
            write_atomic(&dir.join(BASE_CONFIG_FILE), &text)?;
        }
        write_atomic(&plan_path, plan.to_toml().as_bytes())?;
    }
    sync_records(dir, plan)?;
    let records = store::read(dir)?;
    let mut states = Vec::with_capacity(plan.runs.len());
    let mut errors = Vec::new();
    for (spec, cfg) in plan.runs.iter().zip(cfgs) {
        match run_state(dir, spec, Some(&cfg.to_toml()), &records) {
            Ok(s) => states.push(s),
            Err(e) => errors.push(e),
        }
    }
    match errors.len() {
        0 => Ok(states),
        1 => Err(errors.remove(0)),
        n => {
            let first = errors.remove(0);
            match first {
                StudyError::RunMismatch { path, problem } => Err(StudyError::RunMismatch {
                    path,
                    problem: format!("{problem} (and {} more run folders)", n - 1),
                }),
                e => Err(e),
            }
        }
    }
}

/// Whether this grid's rows are conditions other than a single `full`.
pub fn is_single_condition(plan: &StudyPlan) -> bool {
    let first = plan.runs.first().map(|r| r.condition.as_str());
    plan.runs
        .iter()
        .all(|r| Some(r.condition.as_str()) == first)
}

/// Whether the plan is a pareto sweep.
pub fn is_pareto(plan: &StudyPlan) -> bool {
    plan.options.grid == Grid::Pareto
}

/// Adds (or replaces) the record of every planned run whose folder holds a finished run, then
/// writes the file in the plan's order. Returns how many records the file holds.
pub fn sync_records(dir: &Path, plan: &StudyPlan) -> Result<usize, StudyError> {
    let mut records = store::read(dir)?;
    let before = records.clone();
    for spec in &plan.runs {
        let rd = run_dir(dir, &spec.id);
        let (c, m) = (rd.join("config.toml"), rd.join("metrics.json"));
        if !(c.is_file() && m.is_file()) {
            continue;
        }
        let config = std::fs::read_to_string(&c).map_err(io_err(&c))?;
        let text = std::fs::read_to_string(&m).map_err(io_err(&m))?;
        let metrics: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| StudyError::Parse {
                path: m.clone(),
                message: e.to_string(),
            })?;
        let id = spec.id.clone();
        records.insert(
            id.clone(),
            store::StoredRun {
                id,
                config,
                metrics,
            },
        );
    }
    if records == before {
        return Ok(records.len());
    }
    store::write(dir, &plan.ids(), &records)?;
    Ok(records.len())
}

/// Copies into `dir`'s records the record of every planned run that has neither a folder nor
/// a record there but whose configuration another study already ran: a record in one of
/// `sources` (study folders, or their `records.jsonl`) of the same configuration (the same
/// [`config_hash`]), under this plan's run id. The reduced grid's 100 % cells are Table 2's runs
/// of the same scene, seed and arm, for example. Returns how many it copied.
pub fn import_records(
    dir: &Path,
    plan: &StudyPlan,
    sources: &[PathBuf],
) -> Result<usize, StudyError> {
    let mut have = store::read(dir)?;
    let mut by_hash: BTreeMap<String, store::StoredRun> = BTreeMap::new();
    for src in sources {
        let folder = if src.is_file() {
            src.parent().unwrap_or(Path::new(".")).to_path_buf()
        } else {
            src.clone()
        };
        if !folder.join(store::RECORDS_FILE).is_file() {
            return Err(StudyError::Folder {
                dir: folder,
                problem: format!("no {} to reuse records from", store::RECORDS_FILE),
            });
        }
        for (id, r) in store::read(&folder)? {
            let origin = folder.join(store::RECORDS_FILE).join(&id);
            by_hash
                .entry(config_hash_of_toml(&r.config, &origin)?)
                .or_insert(r);
        }
    }
    let mut copied = 0;
    for spec in &plan.runs {
        if have.contains_key(&spec.id) || run_dir(dir, &spec.id).join("config.toml").is_file() {
            continue;
        }
        if let Some(r) = by_hash.get(&spec.config_hash) {
            let mut r = r.clone();
            r.id = spec.id.clone();
            have.insert(spec.id.clone(), r);
            copied += 1;
        }
    }
    if copied > 0 {
        store::write(dir, &plan.ids(), &have)?;
    }
    Ok(copied)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_hash_ignores_out_and_key_order_but_not_values() {
        let mut a = Preset::Fast.config();
        a.out = Some("x/y".into());
        let mut b = a.clone();
        b.out = Some("elsewhere".into());
        assert_eq!(config_hash(&a), config_hash(&b));
        b.mesh.fine_res += 1;
        assert_ne!(config_hash(&a), config_hash(&b));
        let d = config_diff(&a.to_toml(), &b.to_toml(), 10);
        assert_eq!(d, vec!["mesh.fine_res: 256 → 257".to_string()]);
    }

    #[test]
    fn plans_are_deterministic_and_round_trip() {
        let tmp = tempfile::tempdir().unwrap();
        let o = StudyOptions::new(Grid::Reduced);
        let (p1, cfgs) = make_plan(&o, None, tmp.path()).unwrap();
        let (p2, _) = make_plan(&o, None, tmp.path()).unwrap();
        assert_eq!(p1, p2);
        assert_eq!(cfgs[0].data.views_fraction, 0.1);
        assert_eq!(cfgs[1].augment.mode, AugMode::Sia);
        let back: StudyPlan = toml::from_str(&p1.to_toml()).unwrap();
        assert_eq!(back, p1);
        let mut o2 = o.clone();
        o2.seeds = 2;
        let (p3, _) = make_plan(&o2, None, tmp.path()).unwrap();
        let d = p1.differences(&p3, 10);
        assert!(d.iter().any(|l| l.contains("seeds: 3 → 2")), "{d:?}");
        let mut o3 = o.clone();
        o3.sets = vec!["train.iterations=7".into()];
        let (p4, _) = make_plan(&o3, None, tmp.path()).unwrap();
        let d = p1.differences(&p4, 10);
        assert!(d.iter().any(|l| l.contains("--set")), "{d:?}");
        assert!(
            d.iter().any(|l| l.contains("resolved configuration")),
            "{d:?}"
        );
    }

    #[test]
    fn a_bad_set_is_named_at_planning() {
        let tmp = tempfile::tempdir().unwrap();
        let mut o = StudyOptions::new(Grid::Smoke);
        o.sets = vec!["train.iterationz=3".into()];
        let e = make_plan(&o, None, tmp.path()).unwrap_err().to_string();
        assert!(e.contains("iterationz"), "{e}");
    }
}
