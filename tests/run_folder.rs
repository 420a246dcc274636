//! A finished run survives a failed `--force`; a run that trains on nothing, or whose mesh is
//! empty, ends with an error and no `metrics.json`; `--resume` refuses a folder without a run
//! and inputs that changed; the quiet skips of the depth switch and of a run without masks are
//! said. Tiny scene and configuration of `tests/common/tiny.rs` (a few seconds a run).

mod common;

use common::tiny::{neus_aug, scene as tiny_scene};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn write_config(dir: &Path) -> PathBuf {
    common::tiny::write_config(dir, 12, "")
}

/// `neus-aug reconstruct SCENE --config CONFIG --out OUT --quiet EXTRA...` as `cmd` runs it.
fn reconstruct_with(
    mut cmd: Command,
    scene: &Path,
    config: &Path,
    out: &Path,
    extra: &[&str],
) -> Output {
    cmd.arg("reconstruct")
        .arg(scene)
        .args(["--config", config.to_str().unwrap(), "--out"])
        .arg(out)
        .arg("--quiet")
        .args(extra)
        .output()
        .unwrap()
}

fn reconstruct(config: &Path, out: &Path, extra: &[&str]) -> Output {
    reconstruct_with(neus_aug(), tiny_scene(), config, out, extra)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn ok(o: &Output) -> String {
    assert!(o.status.success(), "command failed:\n{}", stderr(o));
    stderr(o)
}

/// Fails, without a panic, with every one of `expect` in the message.
fn refused(o: &Output, expect: &[&str]) -> String {
    let err = stderr(o);
    assert!(!o.status.success(), "expected a failure for {expect:?}");
    for e in expect {
        assert!(err.contains(e), "message lacks {e:?}:\n{err}");
    }
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// The bytes of a finished run's files that must survive.
fn finished(out: &Path) -> Vec<(&'static str, Vec<u8>)> {
    [
        "mesh.ply",
        "metrics.json",
        "checkpoint.safetensors",
        "config.toml",
    ]
    .into_iter()
    .map(|f| (f, std::fs::read(out.join(f)).unwrap()))
    .collect()
}

/// `neus-aug` under a file size limit of 20 KiB (SIGXFSZ ignored): `config.toml` fits, the first
/// checkpoint does not, so the run fails part-way as on a full disk.
fn with_small_file_limit() -> Command {
    let mut c = Command::new("sh");
    c.arg("-c")
        .arg("trap '' XFSZ; ulimit -f 40; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_neus-aug"))
        .env("RAYON_NUM_THREADS", "2");
    c
}

#[test]
fn a_failed_force_leaves_the_finished_run_whole() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let out = tmp.path().join("run");
    ok(&reconstruct(&cfg, &out, &[]));
    let before = finished(&out);
    // The replacement (another seed) fails writing its first checkpoint.
    let o = reconstruct_with(
        with_small_file_limit(),
        tiny_scene(),
        &cfg,
        &out,
        &["--force", "--seed", "3"],
    );
    refused(&o, &["checkpoint", "is back in place"]);
    for (f, bytes) in &before {
        assert!(
            std::fs::read(out.join(f)).unwrap() == *bytes,
            "{f} changed after the failed --force"
        );
    }
    assert!(!out.join(".previous-run").exists());
    assert!(out.join("renders").is_dir(), "the renders came back too");
    // A replacement that finishes takes the place of the old run.
    ok(&reconstruct(&cfg, &out, &["--force", "--seed", "3"]));
    assert!(!out.join(".previous-run").exists());
    assert_ne!(std::fs::read(out.join("mesh.ply")).unwrap(), before[0].1);
}

#[test]
fn a_replacement_killed_midway_gives_the_old_run_back() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let out = tmp.path().join("run");
    ok(&reconstruct(&cfg, &out, &[]));
    let before = finished(&out);
    // What a kill -9 of a `--force` run leaves: the old run aside, the new one's first files.
    let prev = out.join(".previous-run");
    std::fs::create_dir(&prev).unwrap();
    for f in [
        "mesh.ply",
        "metrics.json",
        "checkpoint.safetensors",
        "config.toml",
        "renders",
    ] {
        std::fs::rename(out.join(f), prev.join(f)).unwrap();
    }
    std::fs::write(out.join("config.toml"), "half a new run").unwrap();
    // The next command moves the old run back first, then treats the folder as finished.
    let o = reconstruct(&cfg, &out, &[]);
    let err = refused(&o, &["already holds a finished run"]);
    assert!(err.contains("has been moved back"), "{err}");
    for (f, bytes) in &before {
        assert!(std::fs::read(out.join(f)).unwrap() == *bytes, "{f}");
    }
    assert!(!prev.exists());
}

#[test]
fn an_empty_mesh_is_an_error_not_a_finished_run() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let out = tmp.path().join("run");
    // Rule 4 keeps only faces 99 training cameras see: none, of 7.
    let o = reconstruct(&cfg, &out, &["--set", "mesh.clean_min_visible_views=99"]);
    refused(&o, &["the mesh is empty", "clean_min_visible_views"]);
    assert!(!out.join("metrics.json").exists());
    assert!(
        out.join("mesh_raw.ply").is_file(),
        "the raw mesh is kept to look at"
    );
}

/// A copy of the tiny scene whose cameras, moved 50 normalised units sideways, look past the
/// region the normalisation puts the object in.
fn scene_looking_elsewhere(dir: &Path) -> PathBuf {
    let scene = neus_aug::scene::Scene::load(tiny_scene(), &Default::default()).unwrap();
    let n = &scene.normalization;
    // Back to world millimetres (what cameras_sphere.npz holds), then 50 units aside.
    let cams: Vec<_> = scene
        .views
        .iter()
        .map(|v| {
            let mut c = v.camera.clone();
            c.center = c.center * n.scale + nalgebra::Vector3::from(n.center);
            c.center.x -= 50.0 * n.scale;
            c
        })
        .collect();
    let out = dir.join("elsewhere");
    copy_dir(tiny_scene(), &out);
    let refs: Vec<_> = cams.iter().collect();
    neus_aug::scene::write_cameras(&out, &refs, &scene.normalization).unwrap();
    out
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        let t = to.join(p.file_name().unwrap());
        if p.is_dir() {
            copy_dir(&p, &t);
        } else {
            std::fs::copy(&p, &t).unwrap();
        }
    }
}

#[test]
fn a_region_no_camera_sees_is_refused_before_training() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let scene = scene_looking_elsewhere(tmp.path());
    let out = tmp.path().join("run");
    let o = reconstruct_with(neus_aug(), &scene, &cfg, &out, &[]);
    refused(
        &o,
        &["nothing to reconstruct", "meets the reconstruction region"],
    );
    assert!(!out.join("metrics.json").exists());
    assert!(!out.join("checkpoint.safetensors").exists());
}

#[test]
fn resume_needs_a_run_and_the_inputs_it_started_with() {
    let tmp = tempfile::tempdir().unwrap();
    // `--resume` alone on a folder without a run: refused, nothing made.
    let empty = tmp.path().join("nothing");
    let o = neus_aug()
        .args(["reconstruct", "--quiet", "--resume", "--out"])
        .arg(&empty)
        .output()
        .unwrap();
    refused(&o, &["holds no run to resume"]);
    assert!(!empty.exists());
    // A run stopped part-way, then one of its images changed: the resume is refused.
    let cfg = write_config(tmp.path());
    let scene = tmp.path().join("scene");
    copy_dir(tiny_scene(), &scene);
    let out = tmp.path().join("run");
    let o = reconstruct_with(neus_aug(), &scene, &cfg, &out, &["--stop-after", "4"]);
    refused(&o, &["stopped after step 4"]);
    let mut names: Vec<PathBuf> = std::fs::read_dir(scene.join("image"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    names.sort();
    let mut img = neus_aug::scene::RgbImage::load(&names[1]).unwrap();
    img.data.iter_mut().take(300).for_each(|v| *v = 1.0 - *v);
    img.save(&names[1]).unwrap();
    let o = reconstruct_with(neus_aug(), &scene, &cfg, &out, &["--resume"]);
    refused(&o, &["other inputs", "digest"]);
    assert!(!out.join("metrics.json").exists());
}

#[test]
fn quiet_skips_are_said_and_recorded() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    // The depth switch's step falls after the last of 12 steps.
    let out = tmp.path().join("late");
    let err = ok(&reconstruct(
        &cfg,
        &out,
        &["--set", "train.depth.auto.min_step=100"],
    ));
    assert!(err.contains("does not check"), "{err}");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    let why = m["train"]["depth_auto_skipped"].as_str().unwrap();
    assert!(why.contains("min_step = 100"), "{why}");
    // No masks and no learned background: said once, with the key that fixes it.
    let out = tmp.path().join("nomask");
    let o = reconstruct(
        &cfg,
        &out,
        &["--set", "data.masks=false", "--set", "eval.enabled=false"],
    );
    let err = ok(&o);
    assert_eq!(err.matches("model.background.kind").count(), 1, "{err}");
}

#[test]
fn an_output_folder_that_is_a_dangling_link_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let out = tmp.path().join("dl");
    std::os::unix::fs::symlink(tmp.path().join("gone"), &out).unwrap();
    let o = reconstruct(&cfg, &out, &[]);
    refused(&o, &["symbolic link", "gone", "does not exist"]);
    assert!(!tmp.path().join("gone").exists());
}
