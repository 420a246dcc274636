//! `records.jsonl`: the compact record of every finished run of a study, one JSON object a line
//! (`{"id", "config", "metrics"}`: the run's `config.toml` text and its `metrics.json`), in the
//! plan's order. It is what a study commits to version control instead of its run folders
//! (checkpoints and meshes stay out), so that a study can be continued on another machine (a
//! run with a record is finished) and its report rebuilt from the plan and the records alone.

use super::confighash::config_hash_of_toml;
use super::{io_err, write_atomic, StudyError};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// The records file of a study folder.
pub const RECORDS_FILE: &str = "records.jsonl";

/// One finished run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StoredRun {
    /// The run's id in the plan.
    pub id: String,
    /// Its `config.toml`, as written.
    pub config: String,
    /// Its `metrics.json`.
    pub metrics: serde_json::Value,
}

/// The records of `dir` by run id (none without a records file).
pub fn read(dir: &Path) -> Result<BTreeMap<String, StoredRun>, StudyError> {
    let path = dir.join(RECORDS_FILE);
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(BTreeMap::new()),
        Err(e) => return Err(io_err(&path)(e)),
    };
    let mut out = BTreeMap::new();
    for (i, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
    {
        let r: StoredRun = serde_json::from_str(line).map_err(|e| StudyError::Parse {
            path: path.clone(),
            message: format!("line {}: {e}", i + 1),
        })?;
        out.insert(r.id.clone(), r);
    }
    Ok(out)
}

/// The record of run `id` if it is stored and holds the plan's configuration (`Err` when it
/// holds another: a study never mixes configurations).
pub fn planned_record<'a>(
    records: &'a BTreeMap<String, StoredRun>,
    dir: &Path,
    id: &str,
    config_hash: &str,
) -> Result<Option<&'a StoredRun>, StudyError> {
    let Some(r) = records.get(id) else {
        return Ok(None);
    };
    let origin = dir.join(RECORDS_FILE).join(id);
    let found = config_hash_of_toml(&r.config, &origin)?;
    if found != config_hash {
        return Err(StudyError::RunMismatch {
            path: origin,
            problem: format!("its configuration hashes to {found}, the plan's to {config_hash}"),
        });
    }
    Ok(Some(r))
}

/// Writes `records` to `dir/records.jsonl` in the order of `ids` (a plan's run ids), records of
/// other ids after them, by id.
pub fn write(
    dir: &Path,
    ids: &[&str],
    records: &BTreeMap<String, StoredRun>,
) -> Result<(), StudyError> {
    let mut text = String::new();
    let others = records
        .keys()
        .map(String::as_str)
        .filter(|k| !ids.contains(k));
    for id in ids.iter().copied().chain(others) {
        if let Some(r) = records.get(id) {
            text.push_str(&serde_json::to_string(r).expect("records serialise"));
            text.push('\n');
        }
    }
    write_atomic(&dir.join(RECORDS_FILE), text.as_bytes())
}
