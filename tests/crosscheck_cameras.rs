//! Runs `scripts/crosscheck_cameras.py`: OpenCV's decomposition (as NeuS uses it) must agree
//! with ours, on a scene written by numpy/OpenCV and on one written by neus-aug.

mod common;

use std::process::Command;

fn python() -> Option<&'static str> {
    let ok = Command::new("python3")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        eprintln!("SKIPPED: python3 is not installed, the OpenCV cross-check cannot run");
    }
    ok.then_some("python3")
}

fn run_script(extra: &[&str]) {
    let Some(py) = python() else { return };
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/crosscheck_cameras.py");
    let out = Command::new(py)
        .arg(script)
        .args(["--neus-aug", env!("CARGO_BIN_EXE_neus-aug")])
        .args(extra)
        .output()
        .expect("run the cross-check script");
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "cross-check failed:\n{text}");
    assert!(text.contains("OK: neus-aug matches"), "{text}");
}

#[test]
fn opencv_agrees_on_a_scene_written_by_numpy() {
    run_script(&["--views", "25", "--seed", "3"]);
}

#[test]
fn opencv_agrees_on_a_scene_written_by_neus_aug() {
    let dir = tempfile::tempdir().unwrap();
    common::write_random_scene(dir.path(), 8, 99, 32, 24);
    run_script(&["--scene", dir.path().to_str().unwrap()]);
}
