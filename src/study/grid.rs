//! The grids: which runs each experiment consists of.
//!
//! A grid expands [`StudyOptions`] into [`RunDraft`]s, one per (condition, scene, arm, seed), in
//! a fixed order (seed, condition, scene, arm) that the tables and the job list keep.

use super::StudyError;
use crate::augment::{AugMode, Degradation, DegradationKind};
use crate::reconstruct::{scale_run_length, Preset, RunConfig};
use crate::render::Scheduled;
use crate::sim;
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::str::FromStr;

/// An experiment grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Grid {
    /// Baseline, DIA and SIA on every scene (the paper's Table 2, NeuS rows).
    Table2,
    /// IA off / on with 10, 25, 50 and 75 % of the training views (Table 4, reduced data).
    Reduced,
    /// IA off / on under each of the five degradations at the main strength (Table 4, right).
    Degraded,
    /// IA off / on under each degradation at the milder strength (the paper's appendix).
    DegradedMild,
    /// Accuracy against time: iterations, image scale, samples per ray and marching-cubes
    /// resolution, one at a time around the preset, plus the presets.
    Pareto,
    /// Baseline and SIA for a tenth of the preset's steps with a coarse mesh: a check of the
    /// whole machinery in minutes.
    Smoke,
    /// Geometry against the ground truth on every built-in scene: the baseline on
    /// each scene, plus DIA and SIA on the scenes with holes ([`HARD_IA_SCENES`]); the report
    /// adds the Chamfer floor, the ratio to it, genus against the truth, components before and
    /// after clean-up and the held-out normal error.
    Hard,
    /// The `hard` report on meshes from outside the project: every mesh of a folder (by default
    /// the set `scripts/fetch_outside.py` downloads) rendered with `synth --mesh` into a scene of
    /// the study folder, then reconstructed at the baseline; the report adds the median and
    /// worst ratio to the floor and the share of runs with the true genus.
    Outside,
}

/// Scenes on which the `hard` grid also runs DIA and SIA: the ones whose holes must open (the
/// genus should match the truth in 9 of 9 runs, 3 seeds × baseline / SIA / DIA, on each).
pub const HARD_IA_SCENES: [&str; 2] = ["torus", "double-torus"];

impl Grid {
    /// Every grid, in the order `--help` lists them.
    pub const ALL: [Grid; 8] = [
        Grid::Table2,
        Grid::Reduced,
        Grid::Degraded,
        Grid::DegradedMild,
        Grid::Pareto,
        Grid::Smoke,
        Grid::Hard,
        Grid::Outside,
    ];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Grid::Table2 => "table2",
            Grid::Reduced => "reduced",
            Grid::Degraded => "degraded",
            Grid::DegradedMild => "degraded-mild",
            Grid::Pareto => "pareto",
            Grid::Smoke => "smoke",
            Grid::Hard => "hard",
            Grid::Outside => "outside",
        }
    }

    /// One line for listings.
    pub fn summary(self) -> &'static str {
        match self {
            Grid::Table2 => "baseline / DIA / SIA on every scene (paper Table 2)",
            Grid::Reduced => "IA off/on × 10, 25, 50, 75, 100 % of the views (paper Table 4)",
            Grid::Degraded => "IA off/on × five degradations, main strength (paper Table 4)",
            Grid::DegradedMild => "IA off/on × five degradations, milder strength (appendix)",
            Grid::Pareto => "Chamfer against wall time: one factor at a time + presets",
            Grid::Smoke => "baseline and SIA, a tenth of the steps: a quick end-to-end check",
            Grid::Hard => {
                "geometry against the truth on every scene (floor, genus, components, normals); \
                 DIA/SIA on torus and double-torus"
            }
            Grid::Outside => {
                "the hard grid's report on outside meshes (--meshes DIR, default target/outside, \
                 from scripts/fetch_outside.py), rendered with synth --mesh; baseline only"
            }
        }
    }

    /// Scenes when `--scenes` is not given: every built-in scene for `table2` and `hard`, none
    /// for `outside` (its scenes are made from `--meshes`), the default scene otherwise (the
    /// reduced and degraded grids are 8–10 runs per scene and seed; `--scenes all` widens them).
    pub fn default_scenes(self) -> Vec<String> {
        match self {
            Grid::Table2 | Grid::Hard => sim::CATALOG.iter().map(|e| e.name.to_string()).collect(),
            Grid::Outside => Vec::new(),
            _ => vec![sim::DEFAULT_SCENE.to_string()],
        }
    }

    /// Seeds when `--seeds` is not given: 3 for the paper's grids, 1 for
    /// `pareto` (twelve configurations; timings matter more than seeds there), 2 for `smoke` and
    /// `outside` (twenty meshes; the set's breadth matters more than seeds there).
    pub fn default_seeds(self) -> u32 {
        match self {
            Grid::Pareto => 1,
            Grid::Smoke | Grid::Outside => 2,
            _ => 3,
        }
    }

    /// Whether the grid has an IA-off / IA-on pair (the `--ia` option applies).
    pub fn uses_ia(self) -> bool {
        matches!(self, Grid::Reduced | Grid::Degraded | Grid::DegradedMild)
    }

    fn known() -> String {
        Self::ALL.map(|g| g.name()).join(", ")
    }
}

impl std::fmt::Display for Grid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Grid {
    type Err = StudyError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let n = s.trim().to_ascii_lowercase().replace('_', "-");
        Self::ALL
            .into_iter()
            .find(|g| g.name() == n)
            .ok_or_else(|| StudyError::UnknownGrid {
                name: s.to_string(),
                known: Self::known(),
            })
    }
}

/// Everything that decides which runs a study holds. Stored in `study.toml`; a folder planned
/// with other options is refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudyOptions {
    /// The grid.
    pub grid: Grid,
    /// Scenes as `neus-aug reconstruct` takes them: built-in names, or absolute folder paths.
    pub scenes: Vec<String>,
    /// Seeds `0..seeds` per cell.
    pub seeds: u32,
    /// The preset every run starts from (pareto adds the other presets as points).
    pub preset: Preset,
    /// The augmentation of the "IA on" arm of `reduced`, `degraded` and `degraded-mild`.
    pub ia: AugMode,
    /// Whether `base.toml` (a copy of `--config FILE`) is applied after the preset.
    pub base_config: bool,
    /// `--set key=value` applied to every run, in order, after the grid's own settings.
    pub sets: Vec<String>,
}

impl StudyOptions {
    /// Options with the grid's defaults.
    pub fn new(grid: Grid) -> Self {
        Self {
            grid,
            scenes: grid.default_scenes(),
            seeds: grid.default_seeds(),
            preset: Preset::Fast,
            ia: AugMode::Sia,
            base_config: false,
            sets: Vec::new(),
        }
    }

    /// Checks what can be checked without resolving configurations.
    pub fn validate(&self) -> Result<(), StudyError> {
        let bad = |option: &str, value: String, why: &str| StudyError::Option {
            option: option.into(),
            value,
            why: why.into(),
        };
        if self.seeds == 0 {
            return Err(bad("--seeds", "0".into(), "at least one seed is needed"));
        }
        if self.scenes.is_empty() {
            return Err(bad("--scenes", String::new(), "no scene given"));
        }
        if self.grid.uses_ia() && self.ia == AugMode::None {
            return Err(bad(
                "--ia",
                "none".into(),
                "the IA-on arm needs an augmentation (sia or dia)",
            ));
        }
        // Keys the grid sets per run may not be overridden for all runs at once.
        const OWNED: [&str; 6] = [
            "scene",
            "seed",
            "out",
            "augment.mode",
            "data.views_fraction",
            "data.degrade",
        ];
        for s in &self.sets {
            let key = s.split_once('=').map_or(s.as_str(), |(k, _)| k).trim();
            if OWNED.contains(&key) {
                return Err(bad(
                    "--set",
                    s.clone(),
                    "the grid sets this key per run (use --scenes, --seeds, --ia or another grid)",
                ));
            }
        }
        Ok(())
    }
}

/// Expands `--scenes a,b` (or `all`): built-in names are kept, `default` becomes the default
/// scene's name, folders become absolute paths (job lines run from the study folder).
pub fn parse_scenes(list: &str, data_root: &Path) -> Result<Vec<String>, StudyError> {
    let mut out = Vec::new();
    for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        if item == "all" {
            out.extend(sim::CATALOG.iter().map(|e| e.name.to_string()));
            continue;
        }
        let p = Path::new(item);
        if p.is_dir() {
            let abs = std::fs::canonicalize(p).map_err(super::io_err(p))?;
            out.push(abs.display().to_string());
        } else if sim::builtin(item).is_ok() {
            out.push(if item == "default" {
                sim::DEFAULT_SCENE.to_string()
            } else {
                item.to_string()
            });
        } else if data_root.join(item).is_dir() || data_root.join(format!("dtu_{item}")).is_dir() {
            out.push(item.to_string());
        } else {
            return Err(StudyError::Option {
                option: "--scenes".into(),
                value: item.into(),
                why: format!(
                    "not a folder, not a DTU scan under {}, not a built-in scene (known: {}, all)",
                    data_root.display(),
                    sim::CATALOG.map(|e| e.name).join(", ")
                ),
            });
        }
    }
    if out.is_empty() {
        return Err(StudyError::Option {
            option: "--scenes".into(),
            value: list.into(),
            why: "no scene given".into(),
        });
    }
    let mut seen = std::collections::BTreeSet::new();
    for s in &out {
        if !seen.insert(scene_label(s)) {
            return Err(StudyError::Option {
                option: "--scenes".into(),
                value: list.into(),
                why: format!("two scenes are both called '{}'", scene_label(s)),
            });
        }
    }
    Ok(out)
}

/// The short name of a scene in tables and run ids (a folder's last component).
pub fn scene_label(scene: &str) -> String {
    Path::new(scene)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| scene.to_string())
}

/// One run before its configuration is resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct RunDraft {
    /// Folder name under `runs/`.
    pub id: String,
    pub scene: String,
    /// Row group of the tables: `full`, `views 10%`, `gaussian:0.1`, a pareto variant.
    pub condition: String,
    pub arm: AugMode,
    pub seed: u64,
    pub preset: Preset,
    pub views_fraction: Option<f64>,
    pub degrade: Option<Degradation>,
    /// Run-specific `key=value` settings, applied after the study's `--set`.
    pub sets: Vec<String>,
    /// Another run of the same training whose final checkpoint this run may start from (it then
    /// only extracts, scores and renders).
    pub reuse_training_of: Option<String>,
}

/// Filename-safe slug: letters, digits, `.` and `-`.
fn slug(s: &str) -> String {
    s.chars()
        .filter(|c| c.is_ascii_alphanumeric() || *c == '.' || *c == '-')
        .collect()
}

/// A run setting as `key=value` (TOML value syntax).
fn set(key: &str, value: impl std::fmt::Display) -> String {
    format!("{key}={value}")
}

/// The `--set`s that turn a run of `base` into one of `iterations` steps with every step-indexed
/// schedule at the same fraction of the run ([`scale_run_length`]: cos-anneal end, learning-rate
/// phases, coarse-to-fine hash levels, ramped loss weights, occupancy decay). Without them a
/// shortened run would end before its finest levels and its curvature turn on.
fn run_length_sets(base: &RunConfig, iterations: u64) -> Vec<String> {
    let s = scale_run_length(base, iterations);
    let mut v = vec![
        set("train.iterations", s.train.iterations),
        set("model.render.cos_anneal_end", s.model.render.cos_anneal_end),
        set("train.lr.constant_steps", s.train.lr.constant_steps),
        set("train.lr.warmup_steps", s.train.lr.warmup_steps),
        set(
            "model.render.occupancy.ema_decay",
            s.model.render.occupancy.ema_decay,
        ),
    ];
    if let Some(p) = &s.model.field.hash_grid.progressive {
        let prefix = "model.field.hash_grid.progressive";
        v.push(set(&format!("{prefix}.start_step"), p.start_step));
        v.push(set(&format!("{prefix}.update_steps"), p.update_steps));
    }
    for (name, w) in s.model.loss.weights() {
        if let Scheduled::Linear(..) = w {
            v.push(set(&format!("model.loss.{name}"), w));
        }
    }
    v
}

/// The pareto variants around `base` (the study's preset + base config + `--set`), in plot
/// order: `(condition, preset, sets, reuses_centre)`. Iterations scale the schedule with them
/// (cos-anneal end and the constant learning-rate phase keep their fraction of the run).
pub fn pareto_variants(base: &RunConfig) -> Vec<(String, Preset, Vec<String>, bool)> {
    let mut v = vec![("centre".to_string(), base.preset, vec![], false)];
    let it = base.train.iterations;
    for k in [0.125, 0.25, 0.5, 2.0] {
        let n = ((it as f64 * k).round() as u64).max(1);
        v.push((
            format!("iterations={n}"),
            base.preset,
            run_length_sets(base, n),
            false,
        ));
    }
    let ds = base.data.downscale * 2;
    v.push((
        format!("downscale={ds}"),
        base.preset,
        vec![set("data.downscale", ds)],
        false,
    ));
    let s = base.model.render.num_samples_per_ray;
    for n in [s / 2, s * 2] {
        v.push((
            format!("samples={n}"),
            base.preset,
            vec![set("model.render.num_samples_per_ray", n.max(1))],
            false,
        ));
    }
    let r = base.mesh.fine_res;
    for n in [r / 2, r * 2] {
        v.push((
            format!("mc={n}"),
            base.preset,
            vec![set("mesh.fine_res", n.max(2))],
            true,
        ));
    }
    for p in [Preset::Quick, Preset::Fast, Preset::Default] {
        if p != base.preset {
            v.push((format!("preset={}", p.name()), p, vec![], false));
        }
    }
    v
}

/// The runs of a grid, in table order. `base` is the study's preset resolved with the base
/// config and `--set` (pareto scales around it).
pub fn expand(opts: &StudyOptions, base: &RunConfig) -> Vec<RunDraft> {
    let seeds = 0..opts.seeds as u64;
    let ia = opts.ia;
    // (condition, preset, views fraction, degradation, sets, reuse centre, arms)
    type Cond = (
        String,
        Preset,
        Option<f64>,
        Option<Degradation>,
        Vec<String>,
        bool,
        Vec<AugMode>,
    );
    let p = opts.preset;
    let conds: Vec<Cond> = match opts.grid {
        Grid::Table2 | Grid::Hard => vec![(
            "full".into(),
            p,
            None,
            None,
            vec![],
            false,
            vec![AugMode::None, AugMode::Dia, AugMode::Sia],
        )],
        Grid::Outside => vec![(
            "full".into(),
            p,
            None,
            None,
            vec![],
            false,
            vec![AugMode::None],
        )],
        Grid::Reduced => [0.10, 0.25, 0.50, 0.75, 1.0]
            .into_iter()
            .map(|f| {
                (
                    format!("views {:.0}%", f * 100.0),
                    p,
                    Some(f),
                    None,
                    vec![],
                    false,
                    vec![AugMode::None, ia],
                )
            })
            .collect(),
        Grid::Degraded | Grid::DegradedMild => DegradationKind::ALL
            .into_iter()
            .map(|k| {
                let q = if opts.grid == Grid::Degraded {
                    k.default_q()
                } else {
                    k.mild_q()
                };
                let d = Degradation::new(k, q).expect("the paper's strengths are in range");
                (
                    d.to_string(),
                    p,
                    None,
                    Some(d),
                    vec![],
                    false,
                    vec![AugMode::None, ia],
                )
            })
            .collect(),
        Grid::Pareto => pareto_variants(base)
            .into_iter()
            .map(|(c, preset, sets, reuse)| {
                (c, preset, None, None, sets, reuse, vec![AugMode::None])
            })
            .collect(),
        Grid::Smoke => {
            let it = ((base.train.iterations as f64 * 0.1).round() as u64).max(1);
            let mut sets = run_length_sets(base, it);
            sets.push(set("mesh.fine_res", (base.mesh.fine_res / 2).max(2)));
            vec![(
                format!("iterations={it}"),
                p,
                None,
                None,
                sets,
                false,
                vec![AugMode::None, AugMode::Sia],
            )]
        }
    };
    let mut out = Vec::new();
    for (cond, preset, vf, deg, sets, reuse, arms) in &conds {
        for scene in &opts.scenes {
            let label = scene_label(scene);
            // `hard` runs the augmentations only where the holes are.
            let arms: Vec<AugMode> = match opts.grid {
                Grid::Hard if !HARD_IA_SCENES.contains(&label.as_str()) => vec![AugMode::None],
                _ => arms.clone(),
            };
            for seed in seeds.clone() {
                for &arm in &arms {
                    let arm_part = match opts.grid {
                        Grid::Pareto => String::new(),
                        _ => format!("-{}", arm_name(arm)),
                    };
                    let cond_part = match opts.grid {
                        Grid::Table2 | Grid::Hard | Grid::Outside => String::new(),
                        _ => format!("-{}", slug(cond)),
                    };
                    let id = format!("{}{cond_part}{arm_part}-s{seed}", slug(&label));
                    let centre_id = format!("{}-centre-s{seed}", slug(&label));
                    out.push(RunDraft {
                        id,
                        scene: scene.clone(),
                        condition: cond.clone(),
                        arm,
                        seed,
                        preset: *preset,
                        views_fraction: *vf,
                        degrade: *deg,
                        sets: sets.clone(),
                        reuse_training_of: reuse.then_some(centre_id),
                    });
                }
            }
        }
    }
    // Seed-major: every cell's first seed before any cell's second, so a study stopped early
    // (or run a slice at a time, `--runs`) has every cell at the same count of seeds.
    out.sort_by_key(|d| d.seed);
    out
}

/// The arm's name in run ids and tables: `baseline`, `sia`, `dia`.
pub fn arm_name(a: AugMode) -> &'static str {
    match a {
        AugMode::None => "baseline",
        AugMode::Sia => "sia",
        AugMode::Dia => "dia",
    }
}

/// The arm's column title: `baseline`, `SIA`, `DIA`.
pub fn arm_title(a: AugMode) -> &'static str {
    match a {
        AugMode::None => "baseline",
        AugMode::Sia => "SIA",
        AugMode::Dia => "DIA",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_names_round_trip_and_unknown_names_list_the_grids() {
        for g in Grid::ALL {
            assert_eq!(g.name().parse::<Grid>().unwrap(), g);
        }
        assert_eq!("Degraded_Mild".parse::<Grid>().unwrap(), Grid::DegradedMild);
        let e = "table3".parse::<Grid>().unwrap_err().to_string();
        for g in Grid::ALL {
            assert!(e.contains(g.name()), "{e}");
        }
        assert!(e.contains("table3"), "{e}");
    }

    #[test]
    fn the_outside_grid_runs_the_baseline_on_every_given_scene() {
        let mut o = StudyOptions::new(Grid::Outside);
        assert!(o.scenes.is_empty(), "its scenes come from --meshes");
        assert_eq!(o.seeds, 2);
        o.scenes = vec!["/s/bunny".into(), "/s/anchor".into()];
        let runs = expand(&o, &Preset::Fast.config());
        let ids: Vec<&str> = runs.iter().map(|r| r.id.as_str()).collect();
        assert_eq!(
            ids,
            [
                "bunny-baseline-s0",
                "anchor-baseline-s0",
                "bunny-baseline-s1",
                "anchor-baseline-s1"
            ]
        );
        assert!(runs
            .iter()
            .all(|r| r.arm == AugMode::None && r.condition == "full"));
    }

    #[test]
    fn grids_have_the_papers_cells() {
        let base = Preset::Fast.config();
        let count = |g: Grid, seeds: u32| {
            let mut o = StudyOptions::new(g);
            o.seeds = seeds;
            expand(&o, &base)
        };
        let hard = count(Grid::Hard, 3);
        let n = sim::CATALOG.len();
        assert_eq!(hard.len(), n * 3 + HARD_IA_SCENES.len() * 3 * 2);
        for r in &hard {
            assert_eq!(r.preset, Preset::Fast);
            assert!(r.arm == AugMode::None || HARD_IA_SCENES.contains(&r.scene.as_str()));
        }
        let torus: Vec<&str> = hard
            .iter()
            .filter(|r| r.scene == "torus")
            .map(|r| r.id.as_str())
            .collect();
        assert_eq!(
            torus[..3],
            ["torus-baseline-s0", "torus-dia-s0", "torus-sia-s0"]
        );
        assert_eq!(torus.len(), 9);
        assert_eq!(hard[0].id, "blob-baseline-s0");
        // Seed-major: every seed-0 run comes before any seed-1 run.
        let first_s1 = hard.iter().position(|r| r.seed == 1).unwrap();
        assert!(hard[..first_s1].iter().all(|r| r.seed == 0));
        assert!(hard[first_s1..].iter().all(|r| r.seed >= 1));
        assert_eq!(first_s1, hard.len() / 3);
        let t2 = count(Grid::Table2, 3);
        assert_eq!(t2.len(), sim::CATALOG.len() * 3 * 3);
        assert_eq!(t2[0].id, "blob-baseline-s0");
        assert_eq!(t2[1].id, "blob-dia-s0");
        assert_eq!(t2[2].id, "blob-sia-s0");
        let red = count(Grid::Reduced, 3);
        // 10 / 25 / 50 / 75 % and the 100 % cells (the latter reuse Table 2's runs).
        assert_eq!(red.len(), 5 * 2 * 3);
        assert_eq!(red.last().unwrap().views_fraction, Some(1.0));
        assert_eq!(red[0].views_fraction, Some(0.1));
        assert_eq!(red[1].arm, AugMode::Sia);
        assert_eq!(red[0].id, "blob-views10-baseline-s0");
        let deg = count(Grid::Degraded, 3);
        assert_eq!(deg.len(), 5 * 2 * 3);
        let mild = count(Grid::DegradedMild, 3);
        for (d, m) in deg.iter().zip(&mild) {
            let (d, m) = (d.degrade.unwrap(), m.degrade.unwrap());
            assert_eq!(d.kind(), m.kind());
            assert_eq!(d.q(), d.kind().default_q());
            assert_eq!(m.q(), m.kind().mild_q());
        }
        let par = count(Grid::Pareto, 1);
        let conds: Vec<&str> = par.iter().map(|r| r.condition.as_str()).collect();
        assert_eq!(
            conds,
            [
                "centre",
                "iterations=250",
                "iterations=500",
                "iterations=1000",
                "iterations=4000",
                "downscale=2",
                "samples=128",
                "samples=512",
                "mc=128",
                "mc=512",
                "preset=quick",
                "preset=default"
            ]
        );
        assert_eq!(
            par[8].reuse_training_of.as_deref(),
            Some("blob-centre-s0"),
            "mesh-only variants reuse the centre's training"
        );
        let ids: std::collections::BTreeSet<_> = t2
            .iter()
            .chain(&red)
            .chain(&deg)
            .chain(&mild)
            .chain(&par)
            .map(|r| &r.id)
            .collect();
        assert_eq!(
            ids.len(),
            t2.len() + red.len() + deg.len() + mild.len() + par.len()
        );
    }

    #[test]
    fn shortened_pareto_runs_keep_every_schedule_at_its_fraction_of_the_run() {
        let base = Preset::Fast.config();
        let n = base.train.iterations;
        for (cond, preset, sets, _) in pareto_variants(&base) {
            let Some(it) = cond.strip_prefix("iterations=") else {
                continue;
            };
            let it: u64 = it.parse().unwrap();
            let parsed: Vec<_> = sets
                .iter()
                .map(|s| crate::reconstruct::parse_set(s).unwrap())
                .collect();
            let c = crate::reconstruct::resolve(Some(preset), None, &parsed).unwrap();
            assert_eq!(c.train.iterations, it);
            let k = it as f64 / n as f64;
            // Every hash level is on at the same fraction of the run as in the base.
            let all_on = |c: &RunConfig| {
                let p = c.model.field.hash_grid.progressive.clone().unwrap();
                p.start_step
                    + (c.model.field.hash_grid.n_levels - p.start_level) as u64 * p.update_steps
            };
            let (f0, f1) = (
                all_on(&base) as f64 / n as f64,
                all_on(&c) as f64 / it as f64,
            );
            assert!(
                (f0 - f1).abs() < 0.1,
                "{cond}: levels all on at {f1} of the run, base {f0}"
            );
            // The curvature ramp is where the base has it, scaled.
            let (Scheduled::Linear(a0, _, w0, b0), Scheduled::Linear(a1, _, w1, b1)) =
                (base.model.loss.curvature, c.model.loss.curvature)
            else {
                panic!("{cond}: the fast preset ramps its curvature");
            };
            assert_eq!(w0, w1, "{cond}");
            assert_eq!(a1, (a0 as f64 * k).round() as u64, "{cond}");
            assert_eq!(b1, ((b0 as f64 * k).round() as u64).min(it), "{cond}");
            // The occupancy grid has decayed by the same factor at the end of both runs.
            // (Logarithms: 0.6^2000 underflows.)
            let log_forget = |c: &RunConfig| {
                c.train.iterations as f64 * (c.model.render.occupancy.ema_decay as f64).ln()
            };
            let (d0, d1) = (log_forget(&base), log_forget(&c));
            assert!(
                (d1 / d0 - 1.0).abs() < 1e-5,
                "{cond}: log decay over the run {d1}, base {d0}"
            );
        }
    }

    #[test]
    fn options_are_checked() {
        let mut o = StudyOptions::new(Grid::Reduced);
        o.ia = AugMode::None;
        assert!(o.validate().unwrap_err().to_string().contains("--ia"));
        let mut o = StudyOptions::new(Grid::Table2);
        o.sets = vec!["augment.mode=sia".into()];
        let e = o.validate().unwrap_err().to_string();
        assert!(e.contains("augment.mode"), "{e}");
        o.sets = vec!["train.iterations=10".into()];
        o.validate().unwrap();
        o.seeds = 0;
        assert!(o.validate().unwrap_err().to_string().contains("--seeds"));
        let e = parse_scenes("blob,nonesuch", Path::new("/nonexistent"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("nonesuch") && e.contains("torus"), "{e}");
        assert_eq!(
            parse_scenes("default, torus", Path::new("/x")).unwrap(),
            ["blob", "torus"]
        );
        assert_eq!(
            parse_scenes("all", Path::new("/x")).unwrap().len(),
            sim::CATALOG.len()
        );
        assert!(parse_scenes("blob,blob", Path::new("/x")).is_err());
    }
}
