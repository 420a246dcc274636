//! Runs `scripts/crosscheck_mcubes.py`: PyMCubes and scikit-image must give the same vertex and
//! triangle counts and vertex positions as `neus-aug mcubes` on analytic SDFs (sphere, torus,
//! box, two spheres) at small resolutions, plus the world mapping and the two-pass extraction.

use std::process::Command;

#[test]
fn pymcubes_and_scikit_image_agree_on_analytic_sdfs() {
    let ok = Command::new("python3")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        eprintln!(
            "SKIPPED: python3 is not installed, the PyMCubes/scikit-image cross-check cannot run"
        );
        return;
    }
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/crosscheck_mcubes.py");
    let out = Command::new("python3")
        .arg(script)
        .args(["--neus-aug", env!("CARGO_BIN_EXE_neus-aug")])
        .args(["--res", "33,48"])
        .output()
        .expect("run the cross-check script");
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "cross-check failed:\n{text}");
    assert!(
        text.contains("OK: neus-aug matches PyMCubes and scikit-image"),
        "{text}"
    );
}
