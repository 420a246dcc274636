//! How a `reconstruct` configuration is resolved: the preset's defaults, then `--config FILE`,
//! then command-line flags, then `--set key=value` (TOML syntax, dotted keys), each merged into
//! one TOML tree that is deserialised and validated once; and the check that `--resume` changes
//! nothing.

use super::config::Preset;
use super::config::{invalid, ConfigError, RunConfig};

/// Deep-merges `over` into `base` (tables merge key by key; other values replace).
fn merge(base: &mut toml::Value, over: toml::Value) {
    match (base, over) {
        (toml::Value::Table(b), toml::Value::Table(o)) => {
            for (k, v) in o {
                match b.get_mut(&k) {
                    Some(slot) => merge(slot, v),
                    None => {
                        b.insert(k, v);
                    }
                }
            }
        }
        (slot, v) => *slot = v,
    }
}

/// Sets a dotted key (`model.render.num_samples_per_ray`) in a TOML tree.
fn set_dotted(root: &mut toml::Value, key: &str, value: toml::Value) -> Result<(), ConfigError> {
    let parts: Vec<&str> = key.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(invalid(
            key,
            "",
            "is not a dotted key like train.iterations",
        ));
    }
    let mut node = root;
    for p in &parts[..parts.len() - 1] {
        let table = node
            .as_table_mut()
            .ok_or_else(|| invalid(key, "", "goes through a value that is not a table"))?;
        node = table
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(Default::default()));
    }
    node.as_table_mut()
        .ok_or_else(|| invalid(key, "", "goes through a value that is not a table"))?
        .insert(parts[parts.len() - 1].to_string(), value);
    Ok(())
}

/// Parses the value of a `--set key=value` (TOML syntax; a bare word is taken as a string).
pub fn parse_set(spec: &str) -> Result<(String, toml::Value), ConfigError> {
    let (k, v) = spec
        .split_once('=')
        .ok_or_else(|| invalid("--set", spec, "must look like key=value"))?;
    let k = k.trim();
    let wrapped = format!("v = {}", v.trim());
    let value = match toml::from_str::<toml::Table>(&wrapped) {
        Ok(mut t) => t.remove("v").expect("parsed key"),
        Err(_) => toml::Value::String(v.trim().to_string()),
    };
    Ok((k.to_string(), value))
}

/// Reads a TOML configuration file into a tree; errors name the file.
fn read_toml(path: &std::path::Path) -> Result<toml::Value, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
        path: path.into(),
        source,
    })?;
    let table: toml::Table = toml::from_str(&text).map_err(|e| ConfigError::Parse {
        origin: path.display().to_string(),
        message: e.to_string(),
    })?;
    Ok(toml::Value::Table(table))
}

/// The `preset` key of a configuration tree, if it has one.
fn preset_of(tree: Option<&toml::Value>) -> Result<Option<Preset>, ConfigError> {
    match tree.and_then(|v| v.get("preset")) {
        Some(p) => Ok(Some(p.clone().try_into::<Preset>().map_err(|e| {
            ConfigError::Parse {
                origin: "config key `preset`".into(),
                message: e.to_string(),
            }
        })?)),
        None => Ok(None),
    }
}

/// Builds the configuration: `preset` (if `None`, the file's `preset` key or `default`), then
/// the file, then `overrides` (dotted key → value, in order). `preset` cannot be an override: it
/// picks the defaults every other key starts from (`--preset NAME` or the file's `preset` key).
pub fn resolve(
    preset: Option<Preset>,
    file: Option<&std::path::Path>,
    overrides: &[(String, toml::Value)],
) -> Result<RunConfig, ConfigError> {
    let file_value = file.map(read_toml).transpose()?;
    let preset = preset
        .or(preset_of(file_value.as_ref())?)
        .unwrap_or_default();
    let tree = toml::Value::try_from(preset.config()).expect("presets serialise");
    finish(tree, preset, file, file_value, overrides)
}

/// Merges the file and the overrides into `tree`, then deserialises and validates.
fn finish(
    mut tree: toml::Value,
    preset: Preset,
    file: Option<&std::path::Path>,
    file_value: Option<toml::Value>,
    overrides: &[(String, toml::Value)],
) -> Result<RunConfig, ConfigError> {
    if let Some(v) = file_value {
        merge(&mut tree, v);
    }
    for (k, v) in overrides {
        if k == "preset" {
            return Err(invalid(
                "preset",
                v,
                "cannot be set with --set: a preset picks the defaults every other key starts \
                 from; use --preset NAME (or `preset` in the --config file)",
            ));
        }
        set_dotted(&mut tree, k, v.clone())?;
    }
    set_dotted(
        &mut tree,
        "preset",
        toml::Value::String(preset.name().into()),
    )?;
    let origin = match file {
        Some(p) => format!("configuration ({} and command line)", p.display()),
        None => "configuration (command line)".to_string(),
    };
    let mut cfg: RunConfig = tree
        .try_into()
        .map_err(|e: toml::de::Error| ConfigError::Parse {
            origin,
            message: e.to_string(),
        })?;
    cfg.apply_augment_to_model();
    cfg.validate()?;
    Ok(cfg)
}

/// The configuration of `reconstruct --resume`: the run's own `config.toml` (`saved`), with the
/// options given now applied on top only to check that they agree with it. A preset, file or
/// override that changes any value (the output folder aside) is refused with every differing key
/// named, so `--resume` needs no options and never silently trains another configuration.
pub fn resolve_resume(
    saved: &std::path::Path,
    preset: Option<Preset>,
    file: Option<&std::path::Path>,
    overrides: &[(String, toml::Value)],
) -> Result<RunConfig, ConfigError> {
    let dir = saved.parent().map(|p| p.to_path_buf()).unwrap_or_default();
    let text = std::fs::read_to_string(saved).map_err(|source| ConfigError::Io {
        path: saved.into(),
        source,
    })?;
    let saved_cfg = RunConfig::from_saved_toml(&text, &saved.display().to_string())?;
    let file_value = file.map(read_toml).transpose()?;
    for p in [preset, preset_of(file_value.as_ref())?]
        .into_iter()
        .flatten()
    {
        if p != saved_cfg.preset {
            return Err(ConfigError::ResumeMismatch {
                dir,
                differences: format!(
                    "preset: the run has {}, given {}",
                    saved_cfg.preset.name(),
                    p.name()
                ),
            });
        }
    }
    let base = toml::Value::try_from(&saved_cfg).expect("configurations serialise");
    let cfg = finish(base, saved_cfg.preset, file, file_value, overrides)?;
    let mut diffs = Vec::new();
    let (mut a, mut b) = (saved_cfg.clone(), cfg.clone());
    a.out = None;
    b.out = None;
    diff_trees(
        "",
        &toml::Value::try_from(&a).expect("serialises"),
        &toml::Value::try_from(&b).expect("serialises"),
        &mut diffs,
    );
    if !diffs.is_empty() {
        return Err(ConfigError::ResumeMismatch {
            dir,
            differences: diffs.join("; "),
        });
    }
    Ok(cfg)
}

/// Appends `key: the run has A, given B` for every leaf where `a` and `b` differ.
fn diff_trees(prefix: &str, a: &toml::Value, b: &toml::Value, out: &mut Vec<String>) {
    let key = |k: &str| {
        if prefix.is_empty() {
            k.to_string()
        } else {
            format!("{prefix}.{k}")
        }
    };
    match (a, b) {
        (toml::Value::Table(ta), toml::Value::Table(tb)) => {
            let mut keys: Vec<&String> = ta.keys().chain(tb.keys()).collect();
            keys.sort();
            keys.dedup();
            for k in keys {
                match (ta.get(k), tb.get(k)) {
                    (Some(x), Some(y)) => diff_trees(&key(k), x, y, out),
                    (x, y) => out.push(format!(
                        "{}: the run has {}, given {}",
                        key(k),
                        x.map_or("nothing".into(), |v| v.to_string()),
                        y.map_or("nothing".into(), |v| v.to_string())
                    )),
                }
            }
        }
        _ if a != b => out.push(format!("{prefix}: the run has {a}, given {b}")),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::augment::AugMode;
    use std::path::PathBuf;

    #[test]
    fn file_then_flags_then_set_override_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("c.toml");
        std::fs::write(
            &f,
            "preset = \"fast\"\nseed = 3\n[train]\niterations = 77\n",
        )
        .unwrap();
        let c = resolve(None, Some(&f), &[]).unwrap();
        assert_eq!(
            (c.preset, c.seed, c.train.iterations),
            (Preset::Fast, 3, 77)
        );
        // Other fast-preset values survive the partial [train] table.
        assert_eq!(
            c.train.lr.constant_steps,
            Preset::Fast.config().train.lr.constant_steps
        );
        let sets = vec![
            parse_set("train.iterations=5").unwrap(),
            parse_set("data.degrade=gaussian:0.05").unwrap(),
            parse_set("augment.mode=dia").unwrap(),
        ];
        let c = resolve(Some(Preset::Default), Some(&f), &sets).unwrap();
        assert_eq!((c.preset, c.train.iterations), (Preset::Default, 5));
        assert_eq!(c.augment.mode, AugMode::Dia);
        assert_eq!(c.data.degrade.unwrap().to_string(), "gaussian:0.05");
    }

    #[test]
    fn unknown_keys_and_bad_values_are_named() {
        let e = resolve(None, None, &[parse_set("train.iterationz=5").unwrap()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("iterationz"), "{e}");
        let e = resolve(
            None,
            None,
            &[parse_set("train.optimizer.lr=-0.01").unwrap()],
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("train.optimizer.lr") && e.contains("-0.01"),
            "{e}"
        );
        let e = resolve(None, None, &[parse_set("data.views_fraction=0").unwrap()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("views_fraction"), "{e}");
        for bad in ["-1", "nan"] {
            let set = format!("mesh.clean_visible_margin_mm={bad}");
            let e = resolve(None, None, &[parse_set(&set).unwrap()])
                .unwrap_err()
                .to_string();
            assert!(e.contains("mesh.clean_visible_margin_mm"), "{e}");
        }
        for (bad, why) in [("9", "0..=8"), ("-1", "-1")] {
            let e = resolve(
                None,
                None,
                &[parse_set(&format!("mesh.close_radius={bad}")).unwrap()],
            )
            .unwrap_err()
            .to_string();
            assert!(e.contains("mesh.close_radius"), "{e}");
            assert!(e.contains(why), "{e}");
        }
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("bad.toml");
        std::fs::write(&f, "[train\niterations = 1").unwrap();
        let e = resolve(None, Some(&f), &[]).unwrap_err().to_string();
        assert!(e.contains("bad.toml"), "{e}");
        let e = resolve(None, Some(&dir.path().join("none.toml")), &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.toml"), "{e}");
    }

    #[test]
    fn loss_weights_follow_the_reference_schedule_helper() {
        let sets = vec![
            parse_set("model.loss.eikonal=[0, 0.1, 0.0, 10]").unwrap(),
            parse_set("model.loss.mask=0.25").unwrap(),
        ];
        let c = resolve(Some(Preset::Fast), None, &sets).unwrap();
        let at = |step| c.model.schedule(step).loss;
        assert!((at(0).eikonal - 0.1).abs() < 1e-7);
        assert!((at(5).eikonal - 0.05).abs() < 1e-7);
        assert_eq!(at(50).eikonal, 0.0);
        assert_eq!((at(0).mask, at(50).mask), (0.25, 0.25));
        // The written configuration keeps the quadruple.
        let back = RunConfig::from_saved_toml(&c.to_toml(), "test").unwrap();
        assert_eq!(back.model.loss, c.model.loss);
        let bad = resolve(
            None,
            None,
            &[parse_set("model.loss.mask=[0, 0.1, -1.0, 10]").unwrap()],
        );
        assert!(bad.unwrap_err().to_string().contains("model.loss.mask"));
        let bad = resolve(
            None,
            None,
            &[parse_set("model.loss.curvature=-0.5").unwrap()],
        );
        assert!(bad
            .unwrap_err()
            .to_string()
            .contains("model.loss.curvature"));
    }

    #[test]
    fn resume_keeps_the_saved_configuration_and_names_every_difference() {
        let dir = tempfile::tempdir().unwrap();
        let saved = dir.path().join("config.toml");
        let sets = vec![
            parse_set("seed=7").unwrap(),
            parse_set("scene=torus").unwrap(),
            parse_set("train.iterations=33").unwrap(),
        ];
        let c = resolve(Some(Preset::Fast), None, &sets).unwrap();
        std::fs::write(&saved, c.to_toml()).unwrap();
        // No options: the saved configuration, whatever the default preset says.
        assert_eq!(resolve_resume(&saved, None, None, &[]).unwrap(), c);
        // Agreeing options (and another spelling of the output folder) are accepted.
        let same = vec![
            parse_set("seed=7").unwrap(),
            parse_set("out=\"elsewhere\"").unwrap(),
        ];
        let r = resolve_resume(&saved, Some(Preset::Fast), None, &same).unwrap();
        assert_eq!(r.out, Some(PathBuf::from("elsewhere")));
        // Two changed values: both named, with the saved and the given value.
        let e = resolve_resume(
            &saved,
            None,
            None,
            &[
                parse_set("seed=8").unwrap(),
                parse_set("mesh.fine_res=64").unwrap(),
            ],
        )
        .unwrap_err()
        .to_string();
        for want in [
            "seed: the run has 7, given 8",
            "mesh.fine_res: the run has 256, given 64",
        ] {
            assert!(e.contains(want), "{e}");
        }
        let e = resolve_resume(&saved, Some(Preset::Paper), None, &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("preset: the run has fast, given paper"), "{e}");
        // The saved file is never rewritten by resolution.
        assert_eq!(std::fs::read_to_string(&saved).unwrap(), c.to_toml());
    }

    #[test]
    fn nan_is_refused_in_any_float_key_by_name() {
        for key in [
            "mesh.pad_fraction",
            "model.render.occupancy.ema_decay",
            "model.render.variance_init",
            "train.lr.warmup_start",
            "model.field.sdf.softplus_beta",
        ] {
            let e = resolve(None, None, &[parse_set(&format!("{key}=nan")).unwrap()])
                .unwrap_err()
                .to_string();
            assert!(e.contains(key) && e.contains("NaN"), "{key}: {e}");
        }
    }
}
