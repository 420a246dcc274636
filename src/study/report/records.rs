//! Reading the run folders: each finished run's `metrics.json`, checked against the plan, as a
//! [`RunRecord`].

use super::super::grid::{arm_name, scene_label, Grid};
use super::super::plan::{
    self, run_dir, run_state, RunSpec, RunState, StudyPlan, BASE_CONFIG_FILE,
};
use super::super::store::{planned_record, StoredRun, RECORDS_FILE};
use super::super::{io_err, StudyError};
use crate::reconstruct::Metrics;
use serde::Serialize;
use std::path::Path;

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
    /// The geometry against the ground truth, for the `hard` grid and for any run
    /// whose `metrics.json` knows the truth (a floor or a ground-truth genus). Absent otherwise,
    /// so the files of studies collected before it existed regenerate unchanged.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub geometry: Option<GeometryRecord>,
}

/// A run's geometry against the ground truth: `metrics.json`'s floor, ratio and genus fields
/// (`None` where the record does not have them, e.g. one written before they existed).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct GeometryRecord {
    /// The scene's Chamfer floor (mm).
    pub floor_mm: Option<f64>,
    /// Chamfer sum / floor.
    pub ratio_to_floor: Option<f64>,
    /// Genus of the closed cleaned mesh's largest component (`metrics.json` `mesh.largest_genus`).
    pub genus: Option<i64>,
    /// Genus of the true mesh's largest component.
    pub gt_genus: Option<i64>,
    pub genus_matches: Option<bool>,
    /// Components of the marching-cubes mesh, before clean-up.
    pub components_raw: Option<usize>,
    /// Components of the closed cleaned mesh (after rules 1–3 of `mesh::clean`; the floater
    /// count). Records older than rule 4: the written mesh's.
    pub components: Option<usize>,
    /// Chamfer sum of the closed cleaned mesh (mm), when rule 4 cut its unseen side away.
    pub chamfer_closed: Option<f64>,
    /// Mean angle between rendered and true normals on the held-out views (degrees).
    pub normal_error_deg: Option<f64>,
    /// The seen floor (mm, `metrics.json` `floor_seen`): the true mesh cut by rule 4 of the
    /// clean-up with the run's training cameras, scored by the same protocol.
    pub floor_seen: Option<f64>,
    /// Chamfer sum / seen floor.
    pub ratio_to_floor_seen: Option<f64>,
    /// The depth prior (`train.depth`): `"asked"` (weight > 0 in the config), `"switched on"`
    /// (its automatic switch fired, `train.depth_auto`) or `"off"`; unknown for a record
    /// without a floor.
    pub depth_prior: Option<String>,
}

impl GeometryRecord {
    fn of(m: &Metrics) -> Self {
        // A record without a mesh summary reads as 0 faces (serde default), and one older than
        // the clean-up has no raw counts: unknown, not zero. (An empty mesh reads as unknown
        // too; its record says so in `eval_note`.)
        let raw_known = m.mesh.raw_faces > 0;
        let known = raw_known || m.mesh.faces > 0;
        Self {
            floor_mm: m.floor_mm,
            ratio_to_floor: m.ratio_to_floor,
            floor_seen: m.floor_seen.as_ref().map(|f| f.chamfer_sum),
            ratio_to_floor_seen: m.ratio_to_floor_seen,
            genus: m.mesh.largest_genus,
            gt_genus: m.gt_genus,
            genus_matches: m.genus_matches,
            components_raw: raw_known.then_some(m.mesh.raw_components),
            components: known.then_some(
                m.mesh
                    .clean
                    .as_ref()
                    .map_or(m.mesh.components, |c| c.components_after),
            ),
            chamfer_closed: m.chamfer_closed.as_ref().map(|c| c.chamfer_sum),
            normal_error_deg: m.normal_error_deg,
            // A record older than the floor (the first geometry fields) is older than
            // the depth prior too, but says nothing about it either way: unknown.
            depth_prior: m.floor_mm.is_some().then(|| {
                match (&m.train.depth_auto, &m.train.depth_maps) {
                    (Some(a), _) if a.triggered => "switched on",
                    (None, Some(_)) => "asked",
                    _ => "off",
                }
                .to_string()
            }),
        }
    }
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
    let stored = super::super::store::read(dir)?;
    let mut records: Vec<RunRecord> = Vec::new();
    for spec in &plan.runs {
        let state = match run_state(dir, spec, None, &stored) {
            Ok(s) => s,
            Err(StudyError::RunMismatch { .. }) => {
                // Name the differing keys when the planned configuration can be rebuilt.
                let planned = plan::resolve_run(spec, &plan.options, base, dir)
                    .ok()
                    .filter(|c| plan::config_hash(c) == spec.config_hash)
                    .map(|c| c.to_toml());
                run_state(dir, spec, planned.as_deref(), &stored)?
            }
            Err(e) => return Err(e),
        };
        if state != RunState::Done {
            continue;
        }
        records.push(read_record(dir, spec, plan.options.grid, &stored)?);
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

/// The run's record: its folder's `metrics.json`, else its stored record (`records.jsonl`).
fn read_record(
    dir: &Path,
    spec: &RunSpec,
    grid: Grid,
    stored: &std::collections::BTreeMap<String, StoredRun>,
) -> Result<RunRecord, StudyError> {
    let rd = run_dir(dir, &spec.id);
    let path = rd.join("metrics.json");
    let (m, config): (Metrics, String) = if path.is_file() {
        let text = std::fs::read_to_string(&path).map_err(io_err(&path))?;
        let m = serde_json::from_str(&text).map_err(|e| StudyError::Parse {
            path: path.clone(),
            message: e.to_string(),
        })?;
        let c = rd.join("config.toml");
        (m, std::fs::read_to_string(&c).map_err(io_err(&c))?)
    } else {
        let r = planned_record(stored, dir, &spec.id, &spec.config_hash)?.ok_or_else(|| {
            StudyError::Folder {
                dir: dir.into(),
                problem: format!("run {} has neither a folder nor a record", spec.id),
            }
        })?;
        let m = serde_json::from_value(r.metrics.clone()).map_err(|e| StudyError::Parse {
            path: dir.join(RECORDS_FILE),
            message: format!("{}: {e}", spec.id),
        })?;
        (m, r.config.clone())
    };
    // A configuration written before the schema key hashed its training otherwise; its
    // configuration was checked against the plan above, key by key.
    let legacy = !config.lines().any(|l| l.starts_with("schema ="));
    if m.config_hash != spec.training_hash && !legacy {
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
        geometry: (matches!(grid, Grid::Hard | Grid::Outside)
            || m.floor_mm.is_some()
            || m.gt_genus.is_some())
        .then(|| GeometryRecord::of(&m)),
    })
}
