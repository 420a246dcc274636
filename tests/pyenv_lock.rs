//! Runs `scripts/test_pyenv.py`: the Python bootstrap's one inter-process lock must make parallel
//! cross-check scripts create the venv once and run `apt-get update` + `apt-get install` once, in
//! that order (against a fake apt-get), and must stop with a message naming the package to install
//! by hand when it cannot install. Standard library only: no venv, no network, no root needed.
//! Skipped, saying why, only when python3 is absent.

use std::process::Command;

#[test]
fn pyenv_lock_serialises_parallel_installs() {
    if Command::new("python3").arg("--version").output().is_err() {
        eprintln!("SKIPPED: python3 is not installed, the _pyenv lock test cannot run");
        return;
    }
    let out = Command::new("python3")
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scripts/test_pyenv.py"
        ))
        .output()
        .expect("spawn python3");
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{text}");
    assert!(out.status.success(), "_pyenv lock test failed:\n{text}");
    assert!(text.contains("all pyenv checks passed"), "{text}");
}
