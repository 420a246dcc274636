//! `dtu-eval` output files and usage errors: `--json` never replaces a FIFO, a device or
//! a symbolic link; `--vis-dir` naming a file, and `--scan` without `--gt-root`, give messages
//! that say what is wrong; each cause of an error is printed once.

use dtu_eval::ply::write_points;
use std::path::Path;
use std::process::{Command, Output};

/// Two small point sets for plain mode, written into `dir`; returns the argument prefix.
fn plain_args(dir: &Path) -> Vec<String> {
    let a: Vec<[f32; 3]> = (0..50).map(|i| [i as f32, 0.0, 0.0]).collect();
    let b: Vec<[f32; 3]> = (0..50).map(|i| [i as f32, 0.5, 0.0]).collect();
    let (pa, pb) = (dir.join("a.ply"), dir.join("b.ply"));
    write_points(&pa, &a, None).unwrap();
    write_points(&pb, &b, None).unwrap();
    vec![
        "--mesh".into(),
        pa.display().to_string(),
        "--ref".into(),
        pb.display().to_string(),
    ]
}

fn dtu_eval(args: &[String]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dtu-eval"))
        .args(args)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn json_output_refuses_fifo_symlink_and_device() {
    let dir = tempfile::tempdir().unwrap();
    let base = plain_args(dir.path());
    let sp = dtu_eval::atomic::special_files::SpecialFiles::make(dir.path());
    let (fifo, link) = (&sp.fifo, &sp.link);
    for (path, what) in [
        (fifo.as_path(), "FIFO"),
        (link.as_path(), "symbolic link"),
        (Path::new("/dev/null"), "device"),
    ] {
        let mut args = base.clone();
        args.extend(["--json".into(), path.display().to_string()]);
        let o = dtu_eval(&args);
        let err = stderr(&o);
        assert!(!o.status.success(), "--json {what} accepted");
        assert!(
            err.contains(what) && err.contains("refusing"),
            "{what}: {err}"
        );
    }
    sp.assert_intact();
    // A regular file is replaced as before.
    let mut args = base.clone();
    args.extend(["--json".into(), sp.target.display().to_string()]);
    let o = dtu_eval(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&sp.target).unwrap()).unwrap();
    // Points 0.5 apart along y: both directed means are 0.5.
    assert!((v["mean_d2s"].as_f64().unwrap() - 0.5).abs() < 1e-6, "{v}");
}

#[test]
fn vis_dir_naming_a_file_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let mut args = plain_args(dir.path());
    let file = dir.path().join("not-a-dir");
    std::fs::write(&file, "x").unwrap();
    args.extend(["--vis-dir".into(), file.display().to_string()]);
    let o = dtu_eval(&args);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert!(
        err.contains("--vis-dir") && err.contains("is not a folder"),
        "{err}"
    );
    assert!(!err.contains("os error 17"), "{err}");
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
}

#[test]
fn scan_without_gt_root_names_the_missing_option() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = plain_args(dir.path())[1].clone();
    for (extra, expect) in [
        (vec!["--scan", "24"], "--scan needs --gt-root"),
        (vec!["--gt-root", "/x"], "--gt-root needs --scan"),
        (vec![], "nothing to compare"),
    ] {
        let mut args = vec!["--mesh".to_string(), mesh.clone()];
        args.extend(extra.iter().map(|s| s.to_string()));
        let o = dtu_eval(&args);
        let err = stderr(&o);
        assert!(!o.status.success());
        assert!(err.contains(expect), "{extra:?}: {err}");
        assert!(!err.contains("not both"), "{err}");
    }
}

#[test]
fn each_cause_is_printed_once() {
    // The json's folder cannot be created (a file is in the way): the OS error once, not twice.
    let dir = tempfile::tempdir().unwrap();
    let mut args = plain_args(dir.path());
    let file = dir.path().join("file");
    std::fs::write(&file, "x").unwrap();
    args.extend([
        "--json".into(),
        file.join("sub/report.json").display().to_string(),
    ]);
    let o = dtu_eval(&args);
    let err = stderr(&o);
    assert!(!o.status.success());
    let cause = "Not a directory";
    assert_eq!(err.matches(cause).count(), 1, "{err}");
}
