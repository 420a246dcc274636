//! `scipy.io.loadmat` reads the simulator's `.mat` files and DTUeval's indexing finds every
//! ground-truth point observed: runs `scripts/check_gt_mat.py` on a scene written by
//! `neus-aug synth`, and on a tampered copy, which it must reject.

mod sim_common;

use std::process::Command;

fn run_check(scene: &std::path::Path) -> (bool, String) {
    let py = sim_common::python().expect("checked by the caller");
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/check_gt_mat.py");
    let out = Command::new(py)
        .arg(script)
        .arg("--scene")
        .arg(scene)
        .output()
        .expect("run check_gt_mat.py");
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

#[test]
fn scipy_reads_the_ground_truth_written_by_synth() {
    if sim_common::python().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("cup");
    let out = Command::new(env!("CARGO_BIN_EXE_neus-aug"))
        .args([
            "synth",
            "cup",
            "--resolution",
            "64x48",
            "--views",
            "5",
            "--gt-spacing",
            "2",
        ])
        .arg("--out")
        .arg(&scene)
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (ok, text) = run_check(&scene);
    assert!(ok && text.contains("OK: scipy.io.loadmat reads"), "{text}");

    // Tamper: a meta.json that disagrees with the files must be reported.
    let meta_path = scene.join("meta.json");
    let mut meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&meta_path).unwrap()).unwrap();
    let voxels = meta["gt"]["obs_voxels"].as_u64().unwrap();
    meta["gt"]["obs_voxels"] = (voxels + 1).into();
    std::fs::write(&meta_path, meta.to_string()).unwrap();
    let (ok, text) = run_check(&scene);
    assert!(!ok && text.contains("observed voxels"), "{text}");
}
