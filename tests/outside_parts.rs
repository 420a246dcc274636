//! `scripts/outside_parts.py`, the outside benchmark's per-part table, on known numbers: the
//! aggregates (per-mesh mean ratio, then median and worst over meshes; the genus share over runs
//! with a known truth), the pairing with the recipe's runs, the fill from the recipe for a part
//! run only where it acts, and the refusal of a folder with no `runs.csv`.

use std::path::Path;
use std::process::Command;

const HEADER: &str = "id,scene,seed,chamfer_sum,ratio_to_floor,genus,gt_genus,genus_matches";

/// A `runs.csv` with the columns the script reads; rows are (scene, seed, Chamfer, ratio, genus,
/// true genus), the true genus negative when unknown.
fn write_runs(dir: &Path, rows: &[(&str, u32, f64, f64, i32, i32)]) {
    std::fs::create_dir_all(dir).unwrap();
    let mut text = String::from(HEADER);
    for &(scene, seed, chamfer, ratio, genus, truth) in rows {
        let matches = if truth < 0 {
            String::new()
        } else {
            (genus == truth).to_string()
        };
        let truth = if truth < 0 {
            String::new()
        } else {
            truth.to_string()
        };
        text += &format!(
            "\n{scene}-baseline-s{seed},{scene},{seed},{chamfer},{ratio},{genus},{truth},{matches}"
        );
    }
    std::fs::write(dir.join("runs.csv"), text + "\n").unwrap();
}

fn run(args: &[&Path]) -> Option<std::process::Output> {
    if Command::new("python3").arg("--version").output().is_err() {
        eprintln!("SKIPPED outside_parts.py: python3 is not installed");
        return None;
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/outside_parts.py");
    Some(
        Command::new("python3")
            .arg(script)
            .args(args)
            .output()
            .expect("python3 runs"),
    )
}

#[test]
fn the_per_part_table_aggregates_pairs_and_fills_as_documented() {
    let tmp = tempfile::tempdir().unwrap();
    let (base, part, some) = (
        tmp.path().join("base"),
        tmp.path().join("part"),
        tmp.path().join("some"),
    );
    // Recipe: per-mesh mean ratios a 2.0, b 4.0, c 9.0 → median 4.0, worst 9.0 (c), mean 5.0;
    // genus right in 3 of the 4 runs with a known truth (c's is unknown).
    let recipe = [
        ("a", 0, 1.0, 1.0, 0, 0),
        ("a", 1, 1.0, 3.0, 0, 0),
        ("b", 0, 2.0, 4.0, 1, 1),
        ("b", 1, 2.0, 4.0, 5, 1),
        ("c", 0, 3.0, 9.0, 2, -1),
        ("c", 1, 3.0, 9.0, 2, -1),
    ];
    write_runs(&base, &recipe);
    // A part off on every run: a and b unchanged, c better (ratio 3.0, Chamfer 1.0 → −2.0 mm).
    let off: Vec<_> = recipe
        .iter()
        .map(|&(s, seed, ch, r, g, t)| match s {
            "c" => (s, seed, 1.0, 3.0, g, t),
            _ => (s, seed, ch, r, g, t),
        })
        .collect();
    write_runs(&part, &off);
    // A part run only where it acts (b at seed 1, now right and worse by 50 %), the rest filled.
    write_runs(&some, &[("b", 1, 3.0, 6.0, 1, 1)]);
    let label_part = format!("off={}", part.display());
    let label_some = format!("some={}+", some.display());
    let Some(o) = run(&[
        &base,
        Path::new(&label_part),
        Path::new(&label_some),
        Path::new("--changed"),
    ]) else {
        return;
    };
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let line = |prefix: &str| {
        out.lines()
            .find(|l| l.starts_with(prefix))
            .unwrap_or_else(|| panic!("no line starting {prefix:?} in\n{out}"))
            .to_string()
    };
    assert_eq!(
        line("| recipe (seeds 0, 1)"),
        "| recipe (seeds 0, 1) | 6 | 4.00× | 9.00× (`c`) | 5.00× | 3 of 4 | — |"
    );
    // c's mean ratio 3.0: median of {2, 4, 3} = 3.0, worst b 4.0, mean 3.0; Δ = −4/6 mm.
    assert_eq!(
        line("| off (seeds 0, 1)"),
        "| off (seeds 0, 1) | 6 | 3.00× | 4.00× (`b`) | 3.00× | 3 of 4 | -0.667, 2 / 0 |"
    );
    // b's mean ratio 5.0 → median 5.0, worst c 9.0, mean 5.33; genus now 4 of 4; Δ = +1/6 mm.
    assert_eq!(
        line("| some (seeds 0, 1)"),
        "| some (seeds 0, 1) | 6 | 5.00× | 9.00× (`c`) | 5.33× | 4 of 4 | +0.167, 0 / 1 |"
    );
    // The recipe's row is printed once for the seeds and runs they share.
    assert_eq!(out.matches("| recipe").count(), 1, "{out}");
    assert!(
        out.contains("some: b-baseline-s1: 2.000 → 3.000 mm, genus 5 → 1 (truth 1)"),
        "{out}"
    );
    assert!(!out.contains("some: a-baseline"), "{out}");
}

#[test]
fn a_folder_without_runs_csv_is_refused_with_the_collect_command() {
    let tmp = tempfile::tempdir().unwrap();
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let label = format!("x={}", empty.display());
    let Some(o) = run(&[&empty, Path::new(&label)]) else {
        return;
    };
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("no runs.csv") && err.contains("study collect"),
        "{err}"
    );
}
