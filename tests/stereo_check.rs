//! `neus-aug stereo-check` (hidden): the depth prior's stereo against a synthetic scene's true
//! mesh. On a small render of the textured default scene most stereo depths must sit on the true
//! surface; a scene without a true mesh is refused with the reason.

use std::process::Command;

fn neus_aug() -> Command {
    Command::new(env!("CARGO_BIN_EXE_neus-aug"))
}

#[test]
fn the_stereo_of_a_textured_blob_is_mostly_on_the_true_surface() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("blob");
    let st = neus_aug()
        .args(["synth", "blob", "--resolution", "160x120", "--views", "12"])
        .args(["--gt-spacing", "2", "--quiet", "--out"])
        .arg(&scene)
        .status()
        .unwrap();
    assert!(st.success());
    let o = neus_aug()
        .arg("stereo-check")
        .arg(&scene)
        .args(["--set", "data.holdout=0", "--tol-mm", "2"])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let all = out
        .lines()
        .find(|l| l.starts_with("all"))
        .unwrap_or_else(|| panic!("no 'all' row:\n{out}"));
    let cols: Vec<&str> = all.split_whitespace().collect();
    let pixels: usize = cols[1].parse().unwrap();
    let right: f64 = cols[2].parse().unwrap();
    assert!(pixels > 1000, "{out}");
    assert!(right > 70.0, "{out}");
    // Without a true mesh there is nothing to check against.
    std::fs::remove_file(scene.join("gt_mesh.ply")).unwrap();
    let o = neus_aug().arg("stereo-check").arg(&scene).output().unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("no gt_mesh.ply") && !err.contains("panicked"),
        "{err}"
    );
}
