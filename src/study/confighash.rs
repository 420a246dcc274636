//! The hash that says whether two `config.toml` texts are one run's configuration, and the keys
//! by which they differ.

use super::StudyError;
use crate::reconstruct::RunConfig;
use crate::util::fnv1a64_hex;
use std::collections::BTreeMap;
use std::path::Path;

/// The configuration file's hash used to compare runs: `config.toml` read as the program reads
/// it (so texts of two schemas that mean one configuration hash alike), `out` removed (a run
/// folder may be reached by different paths), serialised with sorted keys.
pub fn config_hash_of_toml(text: &str, origin: &Path) -> Result<String, StudyError> {
    let t = normalised_table(text, origin)?;
    Ok(fnv1a64_hex(
        toml::to_string(&t).expect("tables serialise").as_bytes(),
    ))
}

/// The configuration `text` as the program reads it (`RunConfig::from_saved_toml`, whatever
/// schema wrote it), written back with every key, `out` removed.
fn normalised_table(text: &str, origin: &Path) -> Result<toml::Table, StudyError> {
    let mut cfg = RunConfig::from_saved_toml(text, &origin.display().to_string()).map_err(|e| {
        StudyError::Parse {
            path: origin.into(),
            message: e.to_string(),
        }
    })?;
    cfg.out = None;
    match toml::Value::try_from(&cfg).expect("configurations serialise") {
        toml::Value::Table(t) => Ok(t),
        _ => unreachable!("a configuration is a table"),
    }
}

/// [`config_hash_of_toml`] of a resolved configuration.
pub fn config_hash(cfg: &RunConfig) -> String {
    config_hash_of_toml(&cfg.to_toml(), Path::new("<resolved>")).expect("own TOML parses")
}

/// The dotted keys whose values differ between two `config.toml` texts (`out` ignored), as
/// `key: a → b` lines, at most `limit`.
pub fn config_diff(a: &str, b: &str, limit: usize) -> Vec<String> {
    fn flatten(prefix: &str, v: &toml::Value, out: &mut BTreeMap<String, String>) {
        match v {
            toml::Value::Table(t) => {
                for (k, v) in t {
                    let key = if prefix.is_empty() {
                        k.clone()
                    } else {
                        format!("{prefix}.{k}")
                    };
                    flatten(&key, v, out);
                }
            }
            other => {
                out.insert(prefix.to_string(), other.to_string());
            }
        }
    }
    let flat = |s: &str| {
        let mut m = BTreeMap::new();
        if let Ok(t) = normalised_table(s, Path::new("")) {
            flatten("", &toml::Value::Table(t), &mut m);
        }
        m
    };
    let (fa, fb) = (flat(a), flat(b));
    let keys: std::collections::BTreeSet<&String> = fa.keys().chain(fb.keys()).collect();
    let none = "(absent)".to_string();
    keys.into_iter()
        .filter(|k| fa.get(*k) != fb.get(*k))
        .take(limit)
        .map(|k| {
            format!(
                "{k}: {} → {}",
                fa.get(k).unwrap_or(&none),
                fb.get(k).unwrap_or(&none)
            )
        })
        .collect()
}
