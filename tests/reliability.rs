//! Run folders that never lose or lie, and inputs refused with the key and value named.
//! Each test is one BAD or WEAK case of the issue: a clear error, and what was there left intact.
//! Training runs use the tiny scene and configuration of `tests/common/tiny.rs` (a few seconds).

mod common;

use common::tiny::{neus_aug, scene as tiny_scene};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn write_config(dir: &Path) -> PathBuf {
    common::tiny::write_config(dir, 12, "")
}

/// `neus-aug reconstruct <tiny scene> --config CONFIG --out OUT --quiet EXTRA...`.
fn reconstruct(config: &Path, out: &Path, extra: &[&str]) -> Output {
    neus_aug()
        .arg("reconstruct")
        .arg(tiny_scene())
        .args(["--config", config.to_str().unwrap(), "--out"])
        .arg(out)
        .arg("--quiet")
        .args(extra)
        .output()
        .unwrap()
}

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "command failed:\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        stderr(o)
    );
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
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

/// Every file under `dir` (recursively) with its bytes, for "nothing changed" checks.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut v = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                v.push((p.clone(), std::fs::read(&p).unwrap()));
            }
        }
    }
    v.sort();
    v
}

/// `neus-aug reconstruct --print-config EXTRA...` (resolution only, no training).
fn print_config(extra: &[&str]) -> Output {
    neus_aug()
        .args(["reconstruct", "--print-config", "--preset", "fast"])
        .args(extra)
        .output()
        .unwrap()
}

// ---------------------------------------------------------------- BAD 1: a user's folder

#[test]
fn bad1_foreign_non_empty_out_is_refused_and_left_intact() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let out = tmp.path().join("mine");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("mesh.ply"), "my own mesh").unwrap();
    std::fs::write(out.join("config.toml"), "my = \"own config\"\n").unwrap();
    let before = snapshot(&out);
    let o = reconstruct(&cfg, &out, &[]);
    refused(
        &o,
        &["not empty", "does not hold a neus-aug run", "mesh.ply"],
    );
    assert_eq!(snapshot(&out), before);
    // --force does not make a foreign folder a run folder either.
    refused(&reconstruct(&cfg, &out, &["--force"]), &["not empty"]);
    assert_eq!(snapshot(&out), before);
}

// ------------------------------------------- BAD 2: --force validates before deleting anything

#[test]
fn bad2_force_with_a_bad_config_or_empty_masks_keeps_the_finished_run() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let out = tmp.path().join("run");
    ok(&reconstruct(&cfg, &out, &[]));
    let before = snapshot(&out);
    assert!(out.join("mesh.ply").is_file() && out.join("metrics.json").is_file());
    // A bad value: refused at resolve time, before the folder is looked at.
    let o = reconstruct(&cfg, &out, &["--force", "--set", "model.render.radius=-1"]);
    refused(&o, &["model.render.radius", "-1"]);
    assert_eq!(snapshot(&out), before);
    // A scene whose masks are all empty: refused after loading, still before any deletion.
    let scene = tmp.path().join("empty-masks");
    for sub in ["image", "mask"] {
        std::fs::create_dir_all(scene.join(sub)).unwrap();
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
    let o = neus_aug()
        .arg("reconstruct")
        .arg(&scene)
        .args(["--config", cfg.to_str().unwrap(), "--out"])
        .arg(&out)
        .args(["--quiet", "--force"])
        .output()
        .unwrap();
    refused(&o, &["mask", "empty"]);
    assert_eq!(
        snapshot(&out),
        before,
        "a refused --force deleted something"
    );
}

// ------------------------------------------------------------ BAD 3: one writer per run folder

#[test]
fn bad3_a_held_run_lock_refuses_a_second_writer_naming_the_pid() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let out = tmp.path().join("run");
    std::fs::create_dir(&out).unwrap();
    let lock = neus_aug::reconstruct::RunLock::acquire(&out).unwrap();
    let before = snapshot(&out);
    let o = reconstruct(&cfg, &out, &[]);
    refused(
        &o,
        &[
            "in use by another neus-aug process",
            &format!("pid {}", std::process::id()),
        ],
    );
    assert_eq!(snapshot(&out), before);
    drop(lock);
    ok(&reconstruct(&cfg, &out, &[]));
}

#[test]
fn bad3_two_processes_into_one_folder_exactly_one_succeeds() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let out = tmp.path().join("run");
    let spawn = |seed: &str| {
        neus_aug()
            .arg("reconstruct")
            .arg(tiny_scene())
            .args(["--config", cfg.to_str().unwrap(), "--out"])
            .arg(&out)
            .args(["--quiet", "--seed", seed])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    let (a, b) = (spawn("0"), spawn("1"));
    let outs = [a.wait_with_output().unwrap(), b.wait_with_output().unwrap()];
    let wins = outs.iter().filter(|o| o.status.success()).count();
    assert_eq!(
        wins,
        1,
        "both or neither succeeded:\n{}\n{}",
        stderr(&outs[0]),
        stderr(&outs[1])
    );
    let loser = outs.iter().find(|o| !o.status.success()).unwrap();
    let err = stderr(loser);
    // Refused while the other ran, or (if it started late) because the run had finished.
    assert!(
        err.contains("in use by another neus-aug process")
            || err.contains("already holds a finished run"),
        "{err}"
    );
    let winner_seed = if outs[0].status.success() { 0 } else { 1 };
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["seed"], winner_seed, "the results are the winner's");
}

#[test]
fn bad3_a_stale_lock_of_a_dead_process_is_taken_over() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let out = tmp.path().join("run");
    std::fs::create_dir(&out).unwrap();
    // The pid of a process that has ended: its lock file remains, unlocked.
    let mut child = Command::new("true").spawn().unwrap();
    let dead = child.id();
    child.wait().unwrap();
    std::fs::write(
        out.join(neus_aug::reconstruct::LOCK_FILE),
        format!("{dead}\n"),
    )
    .unwrap();
    let o = neus_aug()
        .arg("reconstruct")
        .arg(tiny_scene())
        .args(["--config", cfg.to_str().unwrap(), "--out"])
        .arg(&out)
        .output()
        .unwrap();
    ok(&o);
    assert!(
        stderr(&o).contains(&format!("taking over the lock of pid {dead}")),
        "{}",
        stderr(&o)
    );
    assert!(out.join("metrics.json").is_file());
    assert_eq!(
        std::fs::read_to_string(out.join(neus_aug::reconstruct::LOCK_FILE)).unwrap(),
        "",
        "a finished run releases its lock"
    );
}

// ------------------------------------------- BAD 4: --resume reads the run's own config.toml

#[test]
fn bad4_resume_needs_no_flags_and_a_refused_resume_changes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let out = tmp.path().join("run");
    let o = reconstruct(&cfg, &out, &["--seed", "3", "--stop-after", "5"]);
    assert!(!o.status.success() && out.join("checkpoint.safetensors").is_file());
    let before = snapshot(&out);
    // A changed value: refused, naming the key, and nothing on disk changes.
    for (args, key) in [
        (vec!["--seed", "4"], "seed"),
        (vec!["--set", "train.iterations=13"], "train.iterations"),
        (vec!["--preset", "paper"], "preset"),
    ] {
        let o = neus_aug()
            .args([
                "reconstruct",
                "--out",
                out.to_str().unwrap(),
                "--resume",
                "--quiet",
            ])
            .args(&args)
            .output()
            .unwrap();
        refused(&o, &["cannot resume", key]);
        assert_eq!(snapshot(&out), before, "{args:?} changed the run folder");
    }
    // Flags that agree are accepted; none at all is the README's form.
    let o = neus_aug()
        .args([
            "reconstruct",
            "--out",
            out.to_str().unwrap(),
            "--resume",
            "--quiet",
        ])
        .output()
        .unwrap();
    ok(&o);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["train"]["resumed_from"], 5);
    assert_eq!(m["seed"], 3);
    assert_eq!(m["train"]["iterations"], 12);
    assert_eq!(
        std::fs::read(out.join("config.toml")).unwrap(),
        before
            .iter()
            .find(|(p, _)| p.ends_with("config.toml"))
            .unwrap()
            .1,
        "the run's config.toml is the one it started with"
    );
}

// ----------------------------------------- BAD 5: optimiser state checked finite on load

/// Overwrites the first 16 bytes of the first tensor named `prefix*` that has at least 16 bytes,
/// in a safetensors file, with 0xFF (NaN); returns the tensor's name.
fn corrupt_tensor(path: &Path, prefix: &str) -> String {
    let mut bytes = std::fs::read(path).unwrap();
    let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let header: serde_json::Value = serde_json::from_slice(&bytes[8..8 + n]).unwrap();
    let (name, t) = header
        .as_object()
        .unwrap()
        .iter()
        .find(|(k, t)| {
            let o = &t["data_offsets"];
            k.starts_with(prefix) && o[1].as_u64().unwrap() - o[0].as_u64().unwrap() >= 16
        })
        .unwrap();
    let start = 8 + n + t["data_offsets"][0].as_u64().unwrap() as usize;
    bytes[start..start + 16].fill(0xFF);
    std::fs::write(path, bytes).unwrap();
    name.clone()
}

#[test]
fn bad5_corrupt_optimiser_moments_are_refused_on_resume() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    for prefix in ["adam_m.", "adam_v.", "occupancy.occ"] {
        let out = tmp.path().join(prefix.trim_end_matches('.'));
        let o = reconstruct(&cfg, &out, &["--stop-after", "5"]);
        assert!(!o.status.success());
        let name = corrupt_tensor(&out.join("checkpoint.safetensors"), prefix);
        let before = snapshot(&out);
        let o = reconstruct(&cfg, &out, &["--resume"]);
        refused(
            &o,
            &["not a valid neus-aug checkpoint", &name, "not finite"],
        );
        assert!(!out.join("metrics.json").exists());
        assert_eq!(snapshot(&out), before);
    }
}

// ------------------------------------------------- BAD 6 and 7, WEAK: values checked at resolve

#[test]
fn bad6_preset_cannot_be_set_with_set() {
    let o = print_config(&["--set", "preset=paper"]);
    refused(&o, &["preset", "--preset NAME"]);
    assert!(o.stdout.is_empty());
}

#[test]
fn bad7_nan_and_negative_floats_are_refused_naming_key_and_value() {
    for (set, expect) in [
        ("mesh.pad_fraction=nan", &["mesh.pad_fraction", "NaN"][..]),
        ("mesh.pad_fraction=-0.4", &["mesh.pad_fraction", "-0.4"]),
        (
            "model.render.occupancy.threshold=nan",
            &["model.render.occupancy.threshold", "NaN"],
        ),
        (
            "model.render.occupancy.threshold=-1.0",
            &["model.render.occupancy.threshold", "-1"],
        ),
        (
            "model.render.variance_init=nan",
            &["model.render.variance_init", "NaN"],
        ),
        ("augment.sia_p.hue=inf", &["augment.sia_p.hue", "inf"]),
        (
            "model.field.hash_grid.init_range=-1.0",
            &["model.field.hash_grid.init_range", "-1"],
        ),
        ("model.loss.eikonal=nan", &["model.loss.eikonal"]),
    ] {
        let o = print_config(&["--set", set]);
        refused(&o, expect);
        assert!(o.stdout.is_empty(), "{set}: config printed");
    }
}

#[test]
fn weak_counts_and_resolutions_name_their_own_key() {
    for (set, expect) in [
        (
            "model.render.train_num_rays=0",
            &["model.render.train_num_rays", "= 0"][..],
        ),
        (
            "model.render.max_train_num_rays=0",
            &["model.render.max_train_num_rays"],
        ),
        ("mesh.coarse_res=0", &["mesh.coarse_res", "= 0"]),
        (
            "model.render.fd_central_every=0",
            &["model.render.fd_central_every", "= 0", "1..=64"],
        ),
        (
            "model.render.fd_central_every=65",
            &["model.render.fd_central_every", "65"],
        ),
        (
            "model.render.fd_one_sided_span=5.0",
            &["model.render.fd_one_sided_span", "= 5", "[0.25, 2]"],
        ),
        ("mesh.fine_res=100000", &["mesh.fine_res", "100000", "2048"]),
        (
            "model.render.background=[2, 2, 2]",
            &["model.render.background", "[0, 1]"],
        ),
    ] {
        let o = print_config(&["--set", set]);
        let err = refused(&o, expect);
        assert!(o.stdout.is_empty(), "{set}: --print-config accepted it");
        if set.starts_with("model.render.train_num_rays") {
            assert!(!err.contains("num_samples_per_ray"), "{err}");
        }
        if set.starts_with("mesh.coarse_res") {
            assert!(!err.contains("fine_res"), "{err}");
        }
    }
}

#[test]
fn weak_seed_beyond_i64_is_refused_not_wrapped() {
    let o = print_config(&["--seed", "18446744073709551615"]);
    let err = refused(&o, &["--seed", "18446744073709551615", "too large"]);
    assert!(!err.contains("-1"), "{err}");
    // The largest accepted seed round-trips.
    let o = print_config(&["--seed", "9223372036854775807"]);
    ok(&o);
    assert!(String::from_utf8_lossy(&o.stdout).contains("seed = 9223372036854775807"));
}

#[test]
fn weak_each_cause_is_printed_once() {
    // --out below a regular file: the OS error appears once, not "X: X".
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let file = tmp.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let o = reconstruct(&cfg, &file.join("sub"), &[]);
    let err = refused(&o, &["Not a directory"]);
    assert_eq!(err.matches("Not a directory").count(), 1, "{err}");
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
}

// -------------------------------------------------- BAD 8 and WEAK: augment's output files

/// A 64×64 noise PNG (compresses badly: well over 512 bytes).
fn noise_png(path: &Path) {
    let mut img = neus_aug::scene::RgbImage::new(64, 64);
    let mut x = 12345u32;
    for v in img.data.iter_mut() {
        x = x.wrapping_mul(1_103_515_245).wrapping_add(12345);
        *v = (x >> 16) as f32 / 65536.0;
    }
    img.save(path).unwrap();
}

/// Runs `neus-aug ARGS` with a 512-byte file size limit and SIGXFSZ ignored, so a write past
/// the limit fails with EFBIG (as a full disk fails with ENOSPC).
fn with_small_file_limit(args: &[&str]) -> Output {
    let mut script = String::from("trap '' XFSZ; ulimit -f 1; exec \"$0\"");
    for i in 1..=args.len() {
        script.push_str(&format!(" \"${i}\""));
    }
    Command::new("sh")
        .arg("-c")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_neus-aug"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn bad8_augment_apply_reports_write_errors_and_leaves_no_truncated_png() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in.png");
    noise_png(&input);
    assert!(std::fs::metadata(&input).unwrap().len() > 2048);
    let out = tmp.path().join("out.png");
    let o = with_small_file_limit(&[
        "augment",
        "--apply",
        "brightness:0.1",
        input.to_str().unwrap(),
        out.to_str().unwrap(),
    ]);
    refused(&o, &["out.png"]);
    assert!(!out.exists(), "a truncated PNG was left");
    assert_eq!(
        std::fs::read_dir(tmp.path()).unwrap().count(),
        1,
        "a temporary file was left"
    );
    // A previous output survives a failed rewrite.
    std::fs::write(&out, "previous").unwrap();
    let o = with_small_file_limit(&[
        "augment",
        "--apply",
        "brightness:0.1",
        input.to_str().unwrap(),
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "previous");
}

#[test]
fn weak_failed_contact_sheet_leaves_no_truncated_png() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in.png");
    noise_png(&input);
    let dir = tmp.path().join("sheet");
    let o = with_small_file_limit(&[
        "augment",
        input.to_str().unwrap(),
        "--out",
        dir.to_str().unwrap(),
    ]);
    refused(&o, &["contact_sheet.png"]);
    assert!(!dir.join("contact_sheet.png").exists());
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "leftovers");
}

#[test]
fn weak_augment_apply_to_jpg_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in.png");
    noise_png(&input);
    let out = tmp.path().join("out.jpg");
    let o = neus_aug()
        .args(["augment", "--apply", "hue:0.25"])
        .arg(&input)
        .arg(&out)
        .output()
        .unwrap();
    refused(&o, &["out.jpg", ".png"]);
    assert!(!out.exists());
}

// -------------------------------------------- BAD 9: eval --json never replaces a special file

#[test]
fn bad9_eval_json_refuses_fifo_and_symlink() {
    let tmp = tempfile::tempdir().unwrap();
    let pts: Vec<[f32; 3]> = (0..20).map(|i| [i as f32, 0.0, 0.0]).collect();
    let a = tmp.path().join("a.ply");
    dtu_eval::ply::write_points(&a, &pts, None).unwrap();
    let sp = dtu_eval::atomic::special_files::SpecialFiles::make(tmp.path());
    for (p, what) in [(&sp.fifo, "FIFO"), (&sp.link, "symbolic link")] {
        let o = neus_aug()
            .args(["eval", "--mesh"])
            .arg(&a)
            .arg("--ref")
            .arg(&a)
            .arg("--json")
            .arg(p)
            .output()
            .unwrap();
        refused(&o, &[what, "refusing"]);
    }
    sp.assert_intact();
}

// ------------------------------------------------------------ BAD 10: synth --views is capped

#[test]
fn bad10_synth_views_is_capped_with_a_clear_error() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("scene");
    let o = neus_aug()
        .args(["synth", "blob", "--views", "1000000000", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    refused(&o, &["rig.views", "1000000000", "at most 1000"]);
    assert!(!out.exists());
}
