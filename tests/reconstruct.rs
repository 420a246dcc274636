//! `neus-aug reconstruct` end to end on a tiny synthetic scene: determinism, kill and resume,
//! outputs, and a clear error (with no complete-looking output) for each kind of bad input.

mod common;

use common::tiny::{neus_aug, scene as tiny_scene};
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn write_config(dir: &Path, extra: &str) -> std::path::PathBuf {
    common::tiny::write_config(dir, 24, extra)
}

/// `neus-aug reconstruct <tiny scene> --config CONFIG --out OUT --quiet EXTRA...`, not yet run.
fn reconstruct_cmd(config: &Path, out: &Path, extra: &[&str]) -> Command {
    let mut c = neus_aug();
    c.arg("reconstruct")
        .arg(tiny_scene())
        .args([
            "--config",
            config.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ])
        .args(extra);
    c
}

fn reconstruct(config: &Path, out: &Path, extra: &[&str]) -> Output {
    reconstruct_cmd(config, out, extra).output().unwrap()
}

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "reconstruct failed:\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn same_seed_gives_the_same_mesh_and_all_outputs_exist() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path(), "");
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    ok(&reconstruct(&cfg, &a, &[]));
    ok(&reconstruct(&cfg, &b, &[]));
    let mesh_a = std::fs::read(a.join("mesh.ply")).unwrap();
    assert_eq!(
        mesh_a,
        std::fs::read(b.join("mesh.ply")).unwrap(),
        "same seed, same mesh bytes"
    );
    for f in [
        "config.toml",
        "checkpoint.safetensors",
        "metrics.json",
        "renders",
    ] {
        assert!(a.join(f).exists(), "{f} missing");
    }
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(a.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["train"]["iterations"], 24);
    // The tiny config's `auto` start on a scene with masks: the visual hull, fitted.
    let hull = &m["train"]["hull_init"];
    assert_eq!(hull["resolution"], 24, "{m}");
    let (first, last) = (
        hull["fit_error_first_mm"].as_f64().unwrap(),
        hull["fit_error_last_mm"].as_f64().unwrap(),
    );
    assert!(last.is_finite() && last < first, "{hull}");
    assert!(
        m["chamfer"]["chamfer_sum"].as_f64().unwrap().is_finite(),
        "{m}"
    );
    assert!(m["psnr_heldout"].as_f64().unwrap().is_finite());
    for phase in ["load", "train", "mesh", "eval", "render", "total"] {
        assert!(m["timings_s"][phase].as_f64().unwrap() >= 0.0, "{phase}");
    }
    // The figures against the truth: the scene's floor and true genus (its meta.json),
    // the ratio of the Chamfer sum to the floor, and whether the largest component's genus
    // matches.
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tiny_scene().join("meta.json")).unwrap())
            .unwrap();
    let floor = meta["floor"]["chamfer_sum"].as_f64().unwrap();
    assert_eq!(m["floor_mm"].as_f64(), Some(floor), "{m}");
    let chamfer = m["chamfer"]["chamfer_sum"].as_f64().unwrap();
    assert_eq!(m["ratio_to_floor"].as_f64(), Some(chamfer / floor), "{m}");
    assert_eq!(m["gt_genus"].as_i64(), Some(0), "{m}");
    let genus = m["mesh"]["largest_genus"].as_i64().unwrap();
    assert_eq!(m["genus_matches"].as_bool(), Some(genus == 0), "{m}");
    // The seen floor: the truth cut by rule 4 with the run's training cameras (the tiny rig looks
    // from above: the underside goes), scored by the same protocol, and the ratio to it.
    let seen = &m["floor_seen"];
    assert_eq!(seen["min_views"].as_u64(), Some(2), "{m}");
    let cut = seen["area_share_cut"].as_f64().unwrap();
    assert!(cut > 0.05 && cut < 0.9, "{seen}");
    let seen_floor = seen["chamfer_sum"].as_f64().unwrap();
    assert!(seen_floor.is_finite() && seen_floor > 0.0, "{seen}");
    assert_eq!(
        m["ratio_to_floor_seen"].as_f64(),
        Some(chamfer / seen_floor),
        "{m}"
    );
    // Rule 4 of the clean-up: `mesh.ply` is the part two training cameras see (the tiny rig is
    // DTU's, above the object: the underside goes), `mesh_closed.ply` the closed surface it was
    // cut from, and both are scored.
    let unseen = m["mesh"]["clean"]["faces_unseen"].as_u64().unwrap() as usize;
    let closed_faces = m["mesh"]["closed_faces"].as_u64().unwrap() as usize;
    let written = dtu_eval::ply::read_mesh(&a.join("mesh.ply")).unwrap();
    let closed = dtu_eval::ply::read_mesh(&a.join("mesh_closed.ply")).unwrap();
    // The cut's follow-ups: wholly unseen components leave the closed surface, and the cut's
    // specks leave `mesh.ply`; every face is accounted for.
    let clean = &m["mesh"]["clean"];
    let count = |k: &str| clean[k].as_u64().unwrap_or_else(|| panic!("{k}: {m}")) as usize;
    let (specks, gone) = (
        count("faces_in_cut_specks"),
        count("faces_in_unseen_components"),
    );
    assert!(unseen > 0, "{m}");
    assert_eq!(closed.faces.len(), closed_faces, "{m}");
    assert_eq!(
        written.faces.len() + unseen + specks,
        closed_faces + gone,
        "{m}"
    );
    assert_eq!(
        m["mesh"]["faces"].as_u64(),
        Some(written.faces.len() as u64)
    );
    assert!(m["mesh"]["boundary_edges"].as_u64().unwrap() > 0, "{m}");
    let closed_sum = m["chamfer_closed"]["chamfer_sum"].as_f64().unwrap();
    assert!(closed_sum.is_finite() && closed_sum > 0.0, "{m}");
    // The mesh is in world mm: its centre is near the scene's normalisation centre, not the origin.
    let mesh = dtu_eval::ply::read_mesh(&a.join("mesh.ply")).unwrap();
    let scene = neus_aug::scene::Scene::load(tiny_scene(), &Default::default()).unwrap();
    let (lo, hi) = mesh.bounds().unwrap();
    let c = scene.normalization.center;
    for k in 0..3 {
        let mid = 0.5 * (lo[k] + hi[k]) as f64;
        assert!(
            (mid - c[k]).abs() < scene.normalization.scale,
            "axis {k}: {mid} vs {}",
            c[k]
        );
    }
    // The checkpoint loads in Python (safetensors' numpy back end) and matches the config.
    let py = Command::new("python3").arg("--version").output();
    if py.is_ok_and(|o| o.status.success()) {
        let o = Command::new("python3")
            .arg(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/scripts/check_checkpoint.py"
            ))
            .arg(&a)
            .args(["--expect-step", "24"])
            .output()
            .unwrap();
        let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
        assert!(
            o.status.success() && text.contains("OK: checkpoint loads"),
            "{text}"
        );
    } else {
        eprintln!("SKIPPED the Python checkpoint check: python3 is not installed");
    }
    // A different seed trains differently.
    let d = tmp.path().join("d");
    ok(&reconstruct(&cfg, &d, &["--seed", "1"]));
    assert_ne!(mesh_a, std::fs::read(d.join("mesh.ply")).unwrap());
    // A finished run is never silently redone.
    let again = reconstruct(&cfg, &a, &[]);
    assert!(!again.status.success());
    assert!(
        stderr(&again).contains("already holds a finished run"),
        "{}",
        stderr(&again)
    );
}

#[test]
fn stop_then_resume_gives_the_same_mesh_as_an_uninterrupted_run() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path(), "");
    let full = tmp.path().join("full");
    ok(&reconstruct(&cfg, &full, &[]));
    for stop in ["5", "12"] {
        let out = tmp.path().join(format!("stopped{stop}"));
        let o = reconstruct(&cfg, &out, &["--stop-after", stop]);
        assert!(!o.status.success(), "--stop-after ends the run early");
        assert!(!out.join("metrics.json").exists() && !out.join("mesh.ply").exists());
        assert!(out.join("checkpoint.safetensors").exists());
        // Without --resume the unfinished run is protected.
        let o = reconstruct(&cfg, &out, &[]);
        assert!(stderr(&o).contains("--resume"), "{}", stderr(&o));
        ok(&reconstruct(&cfg, &out, &["--resume"]));
        assert_eq!(
            std::fs::read(full.join("mesh.ply")).unwrap(),
            std::fs::read(out.join("mesh.ply")).unwrap(),
            "resumed after step {stop}"
        );
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap())
                .unwrap();
        assert_eq!(m["train"]["resumed_from"], stop.parse::<u64>().unwrap());
    }
}

#[test]
fn killed_process_resumes_to_the_same_mesh() {
    let tmp = tempfile::tempdir().unwrap();
    // Long enough that the process is still training when the first checkpoint appears.
    let cfg = write_config(tmp.path(), "");
    let extra = ["--iterations", "160"];
    let full = tmp.path().join("full");
    ok(&reconstruct(&cfg, &full, &extra));
    let out = tmp.path().join("killed");
    let mut child = reconstruct_cmd(&cfg, &out, &extra)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while !out.join("checkpoint.safetensors").exists() {
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "no checkpoint appeared"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    assert!(
        !out.join("metrics.json").exists(),
        "the run finished before it could be killed; the test proves nothing"
    );
    ok(&reconstruct(
        &cfg,
        &out,
        &[&extra[..], &["--resume"]].concat(),
    ));
    assert_eq!(
        std::fs::read(full.join("mesh.ply")).unwrap(),
        std::fs::read(out.join("mesh.ply")).unwrap()
    );
}

/// Runs a failing reconstruct and checks its message and that nothing looks complete.
fn fails_with(extra_config: &str, args: &[&str], scene: Option<&Path>, expect: &[&str]) {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path(), extra_config);
    let out = tmp.path().join("out");
    let o = neus_aug()
        .arg("reconstruct")
        .arg(scene.unwrap_or(tiny_scene()))
        .args([
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ])
        .args(args)
        .output()
        .unwrap();
    let err = stderr(&o);
    assert!(!o.status.success(), "expected a failure for {expect:?}");
    for e in expect {
        assert!(err.contains(e), "message lacks {e:?}:\n{err}");
    }
    assert!(!err.contains("panicked"), "{err}");
    if out.is_dir() {
        assert!(!out.join("metrics.json").exists() && !out.join("mesh.ply").exists());
    }
}

#[test]
fn no_training_view_left_is_an_error() {
    fails_with(
        "",
        &["--set", "data.holdout=8"],
        None,
        &["data.holdout", "no training view"],
    );
}

#[test]
fn all_empty_masks_are_an_error() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("empty-masks");
    std::fs::create_dir_all(scene.join("image")).unwrap();
    std::fs::create_dir_all(scene.join("mask")).unwrap();
    for sub in ["image", "mask"] {
        for e in std::fs::read_dir(tiny_scene().join(sub)).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), scene.join(sub).join(e.file_name())).unwrap();
        }
    }
    std::fs::copy(
        tiny_scene().join("cameras_sphere.npz"),
        scene.join("cameras_sphere.npz"),
    )
    .unwrap();
    for e in std::fs::read_dir(scene.join("mask")).unwrap() {
        neus_aug::scene::GrayImage::new(48, 36)
            .save(&e.unwrap().path())
            .unwrap();
    }
    fails_with("", &[], Some(&scene), &["mask", "empty"]);
}

#[test]
fn unknown_config_key_is_named() {
    fails_with("[eval]\nvisualise = true\n", &[], None, &["visualise"]);
    fails_with("", &["--set", "model.render.samples=3"], None, &["samples"]);
}

#[test]
fn negative_learning_rate_is_named() {
    fails_with(
        "",
        &["--set", "train.optimizer.lr=-0.01"],
        None,
        &["train.optimizer.lr", "-0.01", "positive"],
    );
}

/// The visual-hull init carves masks: without them it is refused by name, and a
/// bad value of its section is named too.
#[test]
fn visual_hull_init_without_masks_or_with_bad_values_is_named() {
    let hull = "train.init.kind=\"visual_hull\"";
    fails_with(
        "",
        &["--set", hull, "--set", "data.masks=false"],
        None,
        &["train.init.kind", "data.masks"],
    );
    fails_with(
        "",
        &["--set", hull, "--set", "train.init.resolution=4"],
        None,
        &["train.init.resolution", "8..=512"],
    );
}

/// `train.init.kind = "sphere_or_hull"` measures how much of the init sphere the
/// masks' visual hull covers and starts from the hull only below the threshold: with the
/// threshold at 1 the tiny scene (whose object fills less than a 0.95 init sphere) takes the
/// hull, at 0 the sphere, and `metrics.json` says which, with the cover. The sphere choice trains exactly as
/// the plain sphere start (same mesh bytes); without masks the kind falls back to the sphere.
#[test]
fn sphere_or_hull_init_chooses_by_the_cover_and_reports_it() {
    let tmp = tempfile::tempdir().unwrap();
    // The map off: at 24 steps of the tiny network, the `fast` preset's error map leaves the
    // no-mask run's surface outside the observed voxels (no Chamfer); at full size it trains
    // (results/geometry/closing-2026-11-26). This test is about the start, not the rays.
    let cfg = write_config(
        tmp.path(),
        "[model.field.sdf]\nsphere_init_radius = 0.95\n[train.error_map]\nshare = 0.0\n",
    );
    let kind = "train.init.kind=\"sphere_or_hull\"";
    let run = |name: &str, extra: &[&str]| {
        let out = tmp.path().join(name);
        ok(&reconstruct(&cfg, &out, extra));
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap())
                .unwrap();
        (out, m)
    };
    let (_, hull) = run(
        "hull",
        &["--set", kind, "--set", "train.init.sphere_cover_min=1.0"],
    );
    let cover = hull["train"]["sphere_cover"].as_f64().unwrap();
    assert!(cover > 0.0 && cover < 1.0, "{}", hull["train"]);
    assert!(hull["train"]["hull_init"].is_object(), "{}", hull["train"]);
    let (sphere_out, sphere) = run(
        "sphere",
        &["--set", kind, "--set", "train.init.sphere_cover_min=0.0"],
    );
    assert_eq!(sphere["train"]["sphere_cover"].as_f64(), Some(cover));
    assert!(
        sphere["train"]["hull_init"].is_null(),
        "{}",
        sphere["train"]
    );
    let (plain_out, plain) = run("plain", &["--set", "train.init.kind=\"sphere\""]);
    assert!(
        plain["train"].get("sphere_cover").is_none(),
        "{}",
        plain["train"]
    );
    assert_eq!(
        std::fs::read(sphere_out.join("mesh.ply")).unwrap(),
        std::fs::read(plain_out.join("mesh.ply")).unwrap(),
        "the sphere choice is the sphere start"
    );
    let (_, nomask) = run(
        "nomask",
        &[
            "--set",
            kind,
            "--set",
            "data.masks=false",
            "--set",
            "train.init.sphere_cover_min=1.0",
            // A sphere the 24 steps without masks keep a surface of (an empty mesh is an error).
            "--set",
            "model.field.sdf.sphere_init_radius=0.5",
        ],
    );
    assert!(
        nomask["train"].get("sphere_cover").is_none() && nomask["train"]["hull_init"].is_null()
    );
    fails_with(
        "",
        &["--set", kind, "--set", "train.init.sphere_cover_min=1.5"],
        None,
        &["train.init.sphere_cover_min", "[0, 1]"],
    );
}

/// The tiny scene run without, then twice with, the config text `section` (an opt-in prior).
struct PriorRuns {
    tmp: tempfile::TempDir,
    /// The config with the section.
    cfg: std::path::PathBuf,
    /// The first run with it.
    with_dir: std::path::PathBuf,
    /// Its `metrics.json`.
    m: serde_json::Value,
    /// `metrics.json` of the run without it.
    plain: serde_json::Value,
}

/// [`PriorRuns`]: the two runs with the section give the same mesh bytes (same seed), and a
/// mesh other than the run without it (the prior's gradient reaches the field).
fn prior_runs(section: &str) -> PriorRuns {
    let tmp = tempfile::tempdir().unwrap();
    let plain = write_config(tmp.path(), "");
    let p = tmp.path().join("plain");
    ok(&reconstruct(&plain, &p, &[]));
    let cfg = write_config(tmp.path(), section);
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    ok(&reconstruct(&cfg, &a, &[]));
    ok(&reconstruct(&cfg, &b, &[]));
    let mesh = std::fs::read(a.join("mesh.ply")).unwrap();
    assert_eq!(
        mesh,
        std::fs::read(b.join("mesh.ply")).unwrap(),
        "same seed, same mesh bytes"
    );
    assert_ne!(mesh, std::fs::read(p.join("mesh.ply")).unwrap());
    let json = |d: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join("metrics.json")).unwrap()).unwrap()
    };
    PriorRuns {
        m: json(&a),
        plain: json(&p),
        tmp,
        cfg,
        with_dir: a,
    }
}

/// The depth prior's automatic switch (`train.depth.auto`). Its check runs after step
/// `round(0.1 · 24) = 2` of the tiny run. Switched on (a check that cannot fail to fire), the
/// run gives the mesh bytes of a run that asks for the prior at the switch's weight from step
/// 2; a check that cannot fire leaves the mesh of a run without the check; `metrics.json` and
/// `depth_auto.json` say what it found; a run stopped after the check and resumed makes the
/// same decision from the record and the same mesh; bad values are refused by name.
#[test]
fn depth_auto_switch_matches_the_prior_it_turns_on_and_resumes_the_same() {
    let tmp = tempfile::tempdir().unwrap();
    let mvs = "[train.depth]\nstart_step = 0\nrays = 64\n[train.depth.mvs]\nplanes = 32\n";
    // The check after step round(0.1 · 24) = 2: no `min_step` in so short a run.
    let json = |d: &Path, f: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join(f)).unwrap()).unwrap()
    };
    let mesh = |d: &Path| std::fs::read(d.join("mesh.ply")).unwrap();
    // Fires: any ray with solid 0.01 in front of its depth counts, one is enough.
    // Each configuration in its own folder (`write_config` writes `tiny.toml`).
    let dir = |n: &str| {
        let d = tmp.path().join(n);
        std::fs::create_dir_all(&d).unwrap();
        d
    };
    let fire = write_config(
        &dir("fire"),
        &format!(
            "{mvs}[train.depth.auto]\nmin_step = 0\nmargin = 0.01\nstep = 0.005\nshare = 1e-9\n\
             min_rays = 1\n"
        ),
    );
    let on = tmp.path().join("on");
    ok(&reconstruct(&fire, &on, &[]));
    let m = json(&on, "metrics.json");
    let a = &m["train"]["depth_auto"];
    assert_eq!(a["step"].as_u64(), Some(2), "{a}");
    assert_eq!(a["triggered"].as_bool(), Some(true), "{a}");
    let (rays, front) = (a["rays"].as_u64().unwrap(), a["in_front"].as_u64().unwrap());
    assert!(rays > 0 && front > 0 && front <= rays, "{a}");
    let share = a["share"].as_f64().unwrap();
    assert!((share - front as f64 / rays as f64).abs() < 1e-12, "{a}");
    assert!(
        m["train"]["depth_maps"]["with_depth"].as_u64().unwrap() > 0,
        "{m}"
    );
    assert!(
        m["train"]["depth_last"]["rays"].as_u64().unwrap() > 0,
        "{m}"
    );
    assert_eq!(
        &json(&on, "depth_auto.json"),
        a,
        "the record is what metrics.json says"
    );
    // The prior asked for, at the switch's weight, from the step after the check.
    let asked = tmp.path().join("asked");
    let cfg = write_config(&dir("asked_cfg"), mvs);
    ok(&reconstruct(
        &cfg,
        &asked,
        &[
            "--set",
            "train.depth.weight=10",
            "--set",
            "train.depth.start_step=2",
        ],
    ));
    assert_eq!(
        mesh(&on),
        mesh(&asked),
        "switched on = asked for from step 2"
    );
    assert!(json(&asked, "metrics.json")["train"]
        .get("depth_auto")
        .is_none());
    // Never fires (more rays needed than the tiny views have): the mesh of a run without it.
    let never = write_config(
        &dir("never"),
        &format!("{mvs}[train.depth.auto]\nmin_step = 0\nmin_rays = 100000000\n"),
    );
    let off_check = tmp.path().join("off_check");
    ok(&reconstruct(&never, &off_check, &[]));
    let a = &json(&off_check, "metrics.json")["train"]["depth_auto"];
    assert_eq!(a["triggered"].as_bool(), Some(false), "{a}");
    assert!(json(&off_check, "metrics.json")["train"]
        .get("depth_maps")
        .is_none());
    let off = tmp.path().join("off");
    ok(&reconstruct(
        &cfg,
        &off,
        &["--set", "train.depth.auto.enabled=false"],
    ));
    assert!(json(&off, "metrics.json")["train"]
        .get("depth_auto")
        .is_none());
    assert_eq!(
        mesh(&off_check),
        mesh(&off),
        "a check that does not fire changes nothing"
    );
    assert_ne!(mesh(&off), mesh(&on));
    // Stopped after the check, resumed: the decision comes from depth_auto.json.
    let resumed = tmp.path().join("resumed");
    assert!(!reconstruct(&fire, &resumed, &["--stop-after", "8"])
        .status
        .success());
    assert!(resumed.join("depth_auto.json").is_file());
    ok(&reconstruct(&fire, &resumed, &["--resume"]));
    assert_eq!(mesh(&resumed), mesh(&on), "resumed after the check");
    for (set, key) in [
        ("train.depth.auto.share=0", "train.depth.auto.share"),
        ("train.depth.auto.at=1.5", "train.depth.auto.at"),
        ("train.depth.auto.views=0", "train.depth.auto.views"),
    ] {
        fails_with("", &["--set", set], None, &[key]);
    }
}

/// Error-map sampling (`train.error_map`): it changes which pixels are trained (the
/// mesh differs from the uniform sampler's), the same seed gives the same mesh, a run stopped
/// between two rebuilds of the map (every 3 steps, stopped after 5 and 13) resumes to the mesh
/// of an uninterrupted run (the distribution in use is part of the checkpoint), `metrics.json`
/// reports the map, and a bad value is refused by name.
#[test]
fn error_map_sampling_is_deterministic_resumable_and_reported() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(
        tmp.path(),
        "[train.error_map]\nshare = 0.75\nrebuild_every = 3\ncell_px = 4\n",
    );
    let plain_dir = tmp.path().join("plain");
    std::fs::create_dir(&plain_dir).unwrap();
    // The `fast` preset has the map on: the uniform peer turns it off.
    let plain = write_config(&plain_dir, "[train.error_map]\nshare = 0.0\n");
    let (a, b, u) = (
        tmp.path().join("a"),
        tmp.path().join("b"),
        tmp.path().join("uniform"),
    );
    ok(&reconstruct(&cfg, &a, &[]));
    ok(&reconstruct(&cfg, &b, &[]));
    ok(&reconstruct(&plain, &u, &[]));
    let mesh = |d: &Path| std::fs::read(d.join("mesh.ply")).unwrap();
    assert_eq!(mesh(&a), mesh(&b), "same seed, same mesh bytes");
    assert_ne!(mesh(&a), mesh(&u), "the error map changed no ray");
    for stop in ["5", "13"] {
        let out = tmp.path().join(format!("stopped{stop}"));
        assert!(!reconstruct(&cfg, &out, &["--stop-after", stop])
            .status
            .success());
        ok(&reconstruct(&cfg, &out, &["--resume"]));
        assert_eq!(mesh(&a), mesh(&out), "resumed after step {stop}");
    }
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(a.join("metrics.json")).unwrap()).unwrap();
    let e = &m["train"]["error_map"];
    assert!(e["cells"].as_u64().unwrap() > 0, "{e}");
    let mean = e["mean_error"].as_f64().unwrap();
    assert!(mean.is_finite() && mean > 0.0 && mean < 1.0, "{e}");
    let top = e["top_decile_weight"].as_f64().unwrap();
    assert!((0.1..=1.0).contains(&top), "{e}");
    let mu: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(u.join("metrics.json")).unwrap()).unwrap();
    assert!(mu["train"].get("error_map").is_none(), "{}", mu["train"]);
    assert!(std::fs::read_to_string(a.join("config.toml"))
        .unwrap()
        .contains("[train.error_map]"));
    // Every key is written: the uniform sampler's map is there, off.
    assert!(std::fs::read_to_string(u.join("config.toml"))
        .unwrap()
        .contains("[train.error_map]\nshare = 0.0\n"));
    fails_with(
        "",
        &["--set", "train.error_map.share=1.5"],
        None,
        &["train.error_map.share", "[0, 1]"],
    );
    fails_with(
        "",
        &[
            "--set",
            "train.error_map.share=0.5",
            "--set",
            "train.error_map.cell_px=0",
        ],
        None,
        &["train.error_map.cell_px"],
    );
}

#[test]
fn output_folder_that_is_a_file_is_an_error() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path(), "");
    let out = tmp.path().join("a-file");
    std::fs::write(&out, b"not a folder").unwrap();
    let o = reconstruct(&cfg, &out, &[]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("exists and is not a folder"),
        "{}",
        stderr(&o)
    );
    assert_eq!(
        std::fs::read(&out).unwrap(),
        b"not a folder",
        "the file is untouched"
    );
}

#[test]
fn missing_scene_names_where_it_looked() {
    let tmp = tempfile::tempdir().unwrap();
    let o = neus_aug()
        .args(["reconstruct", "scan999", "--data-root"])
        .arg(tmp.path())
        .args(["--quiet", "--out"])
        .arg(tmp.path().join("o"))
        .output()
        .unwrap();
    let err = stderr(&o);
    assert!(!o.status.success());
    for e in ["scan999", "dtu_scan999", "built-in", "NEUS_AUG_DATA"] {
        assert!(err.contains(e), "lacks {e}: {err}");
    }
}

/// `mesh.clean_min_visible_views = 0` turns rule 4 off: `mesh.ply` is the closed cleaned
/// surface, there is no `mesh_closed.ply` (a stale one from an earlier run in the folder is
/// removed) and no second Chamfer.
#[test]
fn the_visibility_cut_is_a_switch_and_leaves_no_stale_closed_mesh() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path(), "");
    let out = tmp.path().join("run");
    ok(&reconstruct(&cfg, &out, &[]));
    assert!(out.join("mesh_closed.ply").is_file());
    ok(&reconstruct(
        &cfg,
        &out,
        &["--force", "--set", "mesh.clean_min_visible_views=0"],
    ));
    assert!(!out.join("mesh_closed.ply").exists());
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["mesh"]["clean"]["faces_unseen"].as_u64(), Some(0), "{m}");
    assert_eq!(m["mesh"]["faces"], m["mesh"]["closed_faces"], "{m}");
    assert!(m["chamfer_closed"].is_null(), "{m}");
    let written = dtu_eval::ply::read_mesh(&out.join("mesh.ply")).unwrap();
    assert_eq!(
        Some(written.faces.len() as u64),
        m["mesh"]["faces"].as_u64()
    );
}

/// The depth prior from stereo (`train.depth`): on from step 8 of 24, the tiny run
/// finishes, the same seed gives the same mesh bytes, the mesh differs from a run without it,
/// `metrics.json` says what the stereo found and what the prior did at the last step, a run
/// without masks still runs it (over every pixel), and bad values are refused by name.
#[test]
fn depth_prior_runs_is_deterministic_and_reported() {
    let PriorRuns {
        tmp,
        cfg,
        m,
        plain: pm,
        with_dir: a,
        ..
    } = prior_runs(
        "[train.depth]\nweight = 5.0\nstart_step = 8\nrays = 64\n[train.depth.mvs]\nplanes = 32\n",
    );
    let maps = &m["train"]["depth_maps"];
    let (considered, with, filled, holes) = (
        maps["considered"].as_u64().unwrap(),
        maps["with_depth"].as_u64().unwrap(),
        maps["filled"].as_u64().unwrap(),
        maps["hole_filled"].as_u64().unwrap(),
    );
    assert!(
        considered > 0 && with > 0 && with <= considered && filled + holes <= with,
        "{maps}"
    );
    let d = &m["train"]["depth_last"];
    let (rays, with_depth, carved) = (
        d["rays"].as_u64().unwrap(),
        d["with_depth"].as_u64().unwrap(),
        d["carved"].as_u64().unwrap(),
    );
    assert!(
        rays <= 64 && with_depth <= rays && carved <= with_depth,
        "{d}"
    );
    let loss = d["loss"].as_f64().unwrap();
    assert!(loss.is_finite() && loss >= 0.0, "{d}");
    assert!(std::fs::read_to_string(a.join("config.toml"))
        .unwrap()
        .contains("[train.depth]"));
    assert!(pm["train"].get("depth_maps").is_none(), "absent when off");
    assert!(pm["train"].get("depth_last").is_none(), "absent when off");
    // No masks: the stereo looks at every pixel of every training view.
    let nm = tmp.path().join("nomask");
    ok(&reconstruct(&cfg, &nm, &["--set", "data.masks=false"]));
    let mm: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(nm.join("metrics.json")).unwrap()).unwrap();
    let nmaps = &mm["train"]["depth_maps"];
    assert!(
        nmaps["considered"].as_u64().unwrap() > considered,
        "{nmaps} against {maps}"
    );
    for (set, words) in [
        (
            "train.depth.mvs.top_k=9",
            ["train.depth.mvs.top_k", "sources"],
        ),
        ("train.depth.spacing=0", ["train.depth.spacing", "positive"]),
        (
            "train.depth.mvs.fuse_radius=-1",
            ["train.depth.mvs.fuse_radius", "[0, 8]"],
        ),
    ] {
        fails_with(
            "",
            &["--set", "train.depth.weight=5", "--set", set],
            None,
            &words,
        );
    }
}
