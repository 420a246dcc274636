//! `neus-aug study` end to end on a tiny scene: a grid killed midway resumes and runs each run
//! exactly once; `study collect` regenerates the report bit for bit; job lines for a cluster
//! produce the planned run folders; bad input (an unknown grid, a folder of another
//! configuration, a tampered run) is refused with a clear message. The collector on fabricated
//! results with known statistics is in `tests/study_reports.rs`.

mod common;

use common::study::fabricate;
use common::tiny::{neus_aug, scene as tiny_scene};
use neus_aug::augment::AugMode;
use neus_aug::study::plan::{make_plan, run_dir, run_state, RunState, StudyPlan};
use neus_aug::study::{collect, Grid, StudyOptions};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn write_config(dir: &Path) -> PathBuf {
    common::tiny::write_config(dir, 40, "")
}

/// `neus-aug study table2` on the tiny scene.
fn study_cmd(cfg: &Path, seeds: u32, folder_flag: &str, dir: &Path) -> Command {
    let mut c = neus_aug();
    c.arg("study")
        .arg("table2")
        .arg("--scenes")
        .arg(tiny_scene())
        .args(["--seeds", &seeds.to_string(), "--config"])
        .arg(cfg)
        .arg(folder_flag)
        .arg(dir)
        .arg("--quiet");
    c
}

fn ok(o: &Output) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(
        o.status.success(),
        "command failed:\n{}\n{err}",
        String::from_utf8_lossy(&o.stdout)
    );
    err
}

fn fails(o: &Output) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(
        !o.status.success(),
        "expected a failure, got success:\n{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// Every file under `dir` (relative path → bytes).
fn tree(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut m = BTreeMap::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        m.insert(
            p.strip_prefix(dir).unwrap().to_path_buf(),
            std::fs::read(&p).unwrap(),
        );
    }
    m
}

fn run_folders(dir: &Path) -> Vec<PathBuf> {
    let runs = dir.join("runs");
    if !runs.is_dir() {
        return vec![];
    }
    let mut v: Vec<PathBuf> = std::fs::read_dir(runs)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    v
}

fn log_lines(dir: &Path, verb: &str) -> Vec<String> {
    std::fs::read_to_string(dir.join("study.log"))
        .unwrap_or_default()
        .lines()
        .filter_map(|l| {
            let mut w = l.split_whitespace().skip(1);
            (w.next() == Some(verb)).then(|| w.next().unwrap().to_string())
        })
        .collect()
}

#[test]
fn a_killed_grid_resumes_runs_each_run_once_and_collects_bit_for_bit() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let dir = tmp.path().join("study");
    // 3 arms × 2 seeds = 6 runs. Kill once a run has finished and another is mid-training.
    let mut child = study_cmd(&cfg, 2, "--out", &dir)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    loop {
        let f = run_folders(&dir);
        let done = f.iter().filter(|p| p.join("metrics.json").exists()).count();
        let partial = f
            .iter()
            .filter(|p| {
                p.join("checkpoint.safetensors").exists() && !p.join("metrics.json").exists()
            })
            .count();
        if done >= 1 && partial >= 1 {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(240),
            "no finished + unfinished pair appeared"
        );
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the study ended ({status}) before it could be killed");
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().unwrap(); // SIGKILL: the study and its current run stop together.
    child.wait().unwrap();
    let folders = run_folders(&dir);
    let finished: BTreeMap<PathBuf, (Vec<u8>, std::time::SystemTime)> = folders
        .iter()
        .filter(|p| p.join("metrics.json").exists())
        .map(|p| {
            let m = p.join("metrics.json");
            (
                p.clone(),
                (
                    std::fs::read(&m).unwrap(),
                    std::fs::metadata(&m).unwrap().modified().unwrap(),
                ),
            )
        })
        .collect();
    let interrupted: Vec<PathBuf> = folders
        .iter()
        .filter(|p| p.join("checkpoint.safetensors").exists() && !p.join("metrics.json").exists())
        .cloned()
        .collect();
    assert!(
        finished.len() < 6 && !interrupted.is_empty(),
        "killed too late to prove anything: {} finished",
        finished.len()
    );
    assert!(
        !dir.join("report").exists(),
        "no report before the grid ends"
    );

    // Resume: the same command finishes the grid.
    ok(&study_cmd(&cfg, 2, "--out", &dir).output().unwrap());
    let plan = StudyPlan::load(&dir).unwrap();
    assert_eq!(plan.runs.len(), 6);
    let done = log_lines(&dir, "done");
    for r in &plan.runs {
        assert_eq!(
            done.iter().filter(|d| **d == r.id).count(),
            1,
            "run {} finished {} times: {done:?}",
            r.id,
            done.iter().filter(|d| **d == r.id).count()
        );
        assert_eq!(
            run_state(&dir, r, None, &Default::default()).unwrap(),
            RunState::Done
        );
    }
    for (p, (bytes, mtime)) in &finished {
        let m = p.join("metrics.json");
        assert_eq!(
            &std::fs::read(&m).unwrap(),
            bytes,
            "{} was redone",
            p.display()
        );
        assert_eq!(&std::fs::metadata(&m).unwrap().modified().unwrap(), mtime);
    }
    for p in &interrupted {
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(p.join("metrics.json")).unwrap())
                .unwrap();
        assert!(
            m["train"]["resumed_from"].as_u64().is_some(),
            "{} did not resume from its checkpoint: {}",
            p.display(),
            m["train"]
        );
    }

    // The report written at the end equals `study collect`, twice, bit for bit.
    let report = tree(&dir.join("report"));
    for name in [
        "report.md",
        "runs.csv",
        "runs.json",
        "summary.json",
        "chamfer.png",
    ] {
        assert!(report.contains_key(Path::new(name)), "{name} missing");
    }
    for again in ["again1", "again2"] {
        let to = tmp.path().join(again);
        let out = neus_aug()
            .args(["study", "collect"])
            .arg(&dir)
            .arg("--to")
            .arg(&to)
            .output()
            .unwrap();
        ok(&out);
        assert_eq!(
            tree(&to),
            report,
            "collect into {again} differs from the report"
        );
    }
    let md = String::from_utf8(report[Path::new("report.md")].clone()).unwrap();
    for s in [
        "| tiny |",
        "| scene | baseline | DIA | SIA |",
        "SIA − baseline",
        "train time / baseline",
        "Runs: 6 planned, 6 collected",
        "| tiny | 2/2 | 2/2 | 2/2 |",
    ] {
        assert!(md.contains(s), "report lacks {s:?}:\n{md}");
    }

    // A third invocation finds everything done and starts nothing.
    let starts = log_lines(&dir, "start").len();
    ok(&study_cmd(&cfg, 2, "--out", &dir).output().unwrap());
    assert_eq!(log_lines(&dir, "start").len(), starts);

    // Other options into the same folder: refused, nothing run or created.
    let err = fails(&study_cmd(&cfg, 3, "--out", &dir).output().unwrap());
    assert!(
        err.contains("planned with other options") && err.contains("seeds: 2 → 3"),
        "{err}"
    );
    assert_eq!(run_folders(&dir).len(), 6);

    // A run folder whose config.toml is not the planned one is never mixed in.
    let victim = run_dir(&dir, &plan.runs[1].id);
    let text = std::fs::read_to_string(victim.join("config.toml")).unwrap();
    let tampered = text.replace("iterations = 40", "iterations = 41");
    assert_ne!(text, tampered);
    std::fs::write(victim.join("config.toml"), tampered).unwrap();
    let err = fails(
        &neus_aug()
            .args(["study", "collect"])
            .arg(&dir)
            .output()
            .unwrap(),
    );
    assert!(
        err.contains(&plan.runs[1].id)
            && err.contains("train.iterations: 41 → 40")
            && err.contains("another configuration"),
        "{err}"
    );
    let err = fails(&study_cmd(&cfg, 2, "--out", &dir).output().unwrap());
    assert!(err.contains(&plan.runs[1].id), "{err}");
}

#[test]
fn emitted_job_lines_make_the_planned_runs_and_mix_with_local_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let dir = tmp.path().join("jobs");
    let o = study_cmd(&cfg, 1, "--emit-jobs", &dir).output().unwrap();
    ok(&o);
    let jobs = std::fs::read_to_string(dir.join("jobs.txt")).unwrap();
    let lines: Vec<&str> = jobs.lines().collect();
    assert_eq!(lines.len(), 3, "{jobs}");
    let slurm = std::fs::read_to_string(dir.join("slurm.sbatch")).unwrap();
    assert!(slurm.contains("#SBATCH --array=1-3"), "{slurm}");
    for script in ["slurm.sbatch", "parallel.sh"] {
        let st = Command::new("bash")
            .arg("-n")
            .arg(dir.join(script))
            .status()
            .unwrap();
        assert!(st.success(), "{script} does not parse");
    }
    assert!(dir.join("base.toml").is_file() && dir.join("logs").is_dir());
    assert!(!dir.join("runs").exists(), "emitting jobs runs nothing");

    // One job line, as a cluster node runs it: from the study folder, through bash.
    let run_line = |line: &str| {
        Command::new("bash")
            .arg("-c")
            .arg(line)
            .current_dir(&dir)
            .env("NEUS_AUG", env!("CARGO_BIN_EXE_neus-aug"))
            .env("RAYON_NUM_THREADS", "2")
            .output()
            .unwrap()
    };
    ok(&run_line(lines[0]));
    let plan = StudyPlan::load(&dir).unwrap();
    let first = &plan.runs[0];
    assert_eq!(
        run_state(&dir, first, None, &Default::default()).unwrap(),
        RunState::Done,
        "the job line made the planned configuration"
    );
    let metrics = run_dir(&dir, &first.id).join("metrics.json");
    let before = std::fs::read(&metrics).unwrap();
    ok(&run_line(lines[0])); // a finished run is skipped, not redone
    assert_eq!(std::fs::read(&metrics).unwrap(), before);

    // Collect what exists.
    let o = neus_aug()
        .args(["study", "collect"])
        .arg(&dir)
        .output()
        .unwrap();
    ok(&o);
    let md = std::fs::read_to_string(dir.join("report/report.md")).unwrap();
    assert!(
        md.contains("Runs: 3 planned, 1 collected, 2 missing"),
        "{md}"
    );

    // The local runner finishes the rest and leaves the cluster's run alone.
    ok(&study_cmd(&cfg, 1, "--out", &dir).output().unwrap());
    assert_eq!(std::fs::read(&metrics).unwrap(), before);
    let started = log_lines(&dir, "start");
    assert_eq!(started.len(), 2, "{started:?}");
    assert!(!started.contains(&first.id));
}

#[test]
fn unknown_grids_and_foreign_folders_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let err = fails(&neus_aug().args(["study", "table3"]).output().unwrap());
    for g in [
        "table3",
        "table2",
        "reduced",
        "degraded",
        "degraded-mild",
        "pareto",
    ] {
        assert!(err.contains(g), "lacks {g}: {err}");
    }
    let err = fails(
        &neus_aug()
            .args(["study", "collect"])
            .arg(tmp.path())
            .output()
            .unwrap(),
    );
    assert!(err.contains("not a study folder"), "{err}");
    // A folder with run results but no plan is not adopted.
    let foreign = tmp.path().join("foreign");
    std::fs::create_dir_all(foreign.join("runs/x")).unwrap();
    let err = fails(
        &neus_aug()
            .args(["study", "smoke", "--out"])
            .arg(&foreign)
            .output()
            .unwrap(),
    );
    assert!(err.contains("no study.toml"), "{err}");
    let err = fails(
        &neus_aug()
            .args(["study", "table2", "--set", "seed=3", "--dry-run"])
            .output()
            .unwrap(),
    );
    assert!(err.contains("seed=3") && err.contains("per run"), "{err}");
    let err = fails(
        &neus_aug()
            .args(["study", "table2", "--scenes", "blob,nope", "--dry-run"])
            .output()
            .unwrap(),
    );
    assert!(err.contains("nope") && err.contains("torus"), "{err}");
}

#[test]
fn pareto_mesh_variants_reuse_the_centre_training() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let dir = tmp.path().join("pareto");
    let pareto = |flag: &str| {
        let mut c = neus_aug();
        c.args(["study", "pareto", "--scenes"])
            .arg(tiny_scene())
            .arg("--config")
            .arg(&cfg)
            .arg(flag)
            .arg(&dir)
            .arg("--quiet");
        c.output().unwrap()
    };
    // The job list first: every line (with the reuse prefix) is valid shell.
    ok(&pareto("--emit-jobs"));
    let st = Command::new("bash")
        .arg("-n")
        .arg(dir.join("jobs.txt"))
        .status()
        .unwrap();
    assert!(st.success(), "jobs.txt does not parse");
    let jobs = std::fs::read_to_string(dir.join("jobs.txt")).unwrap();
    assert_eq!(jobs.lines().count(), 12);
    assert_eq!(
        jobs.lines()
            .filter(|l| l.contains("cp runs/tiny-centre-s0/checkpoint.safetensors"))
            .count(),
        2,
        "{jobs}"
    );
    // Then run it here, in the same folder.
    ok(&pareto("--out"));
    let reused = log_lines(&dir, "reuse");
    assert_eq!(reused, ["tiny-mc16-s0", "tiny-mc64-s0"], "{reused:?}");
    let plan = StudyPlan::load(&dir).unwrap();
    let read = |id: &str| -> serde_json::Value {
        serde_json::from_str(
            &std::fs::read_to_string(run_dir(&dir, id).join("metrics.json")).unwrap(),
        )
        .unwrap()
    };
    let centre = read("tiny-centre-s0");
    for id in &reused {
        let m = read(id);
        assert_eq!(m["train"]["resumed_from"], 40, "{id} retrained");
        assert_eq!(m["config_hash"], centre["config_hash"]);
        assert_ne!(m["mesh"]["vertices"], centre["mesh"]["vertices"], "{id}");
    }
    let csv = std::fs::read_to_string(dir.join("report/pareto.csv")).unwrap();
    assert_eq!(csv.lines().count(), 13, "{csv}");
    let t = |v: &str| -> f64 {
        let l = csv
            .lines()
            .find(|l| l.starts_with(&format!("{v},")))
            .unwrap();
        l.split(',').nth(6).unwrap().parse().unwrap()
    };
    let centre_train = centre["timings_s"]["train"].as_f64().unwrap();
    assert!(
        t("mc=16") > centre_train,
        "a reused training still costs its training time"
    );
    assert!(dir.join("report/pareto.png").is_file());
    assert_eq!(plan.runs.len(), 12);
}

/// `study collect` from the committed records alone (`study.toml` + `records.jsonl`, no run
/// folders) writes the reports bit for bit as from the run folders; a record of another
/// configuration is refused; and a study with a record counts that run finished.
#[test]
fn collect_from_records_alone_rebuilds_every_report() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("t2");
    let mut o = StudyOptions::new(Grid::Table2);
    o.scenes = vec!["blob".into(), "torus".into()];
    o.seeds = 2;
    let (plan, cfgs) = make_plan(&o, None, &dir).unwrap();
    fabricate(
        &dir,
        &plan,
        &cfgs,
        |r| 1.0 + r.seed as f64 / 7.0 + if r.arm == AugMode::Sia { -0.05 } else { 0.0 },
        |_| 100.0,
    );
    let (from_runs, from_records) = (tmp.path().join("a"), tmp.path().join("b"));
    collect(&dir, &from_runs).unwrap();
    let lines = std::fs::read_to_string(dir.join("records.jsonl")).unwrap();
    assert_eq!(lines.lines().count(), plan.runs.len());
    // The committed part of the study: the plan and the records.
    let committed = tmp.path().join("committed");
    std::fs::create_dir_all(&committed).unwrap();
    for f in ["study.toml", "records.jsonl"] {
        std::fs::copy(dir.join(f), committed.join(f)).unwrap();
    }
    collect(&committed, &from_records).unwrap();
    let (ta, tb) = (tree(&from_runs), tree(&from_records));
    assert_eq!(ta.keys().collect::<Vec<_>>(), tb.keys().collect::<Vec<_>>());
    for (k, v) in &ta {
        assert!(tb[k] == *v, "{} differs", k.display());
    }
    // A finished run's record makes it done for a study continued elsewhere.
    let records = neus_aug::study::store::read(&committed).unwrap();
    assert_eq!(
        run_state(&committed, &plan.runs[0], None, &records).unwrap(),
        RunState::Done
    );
    // A record whose configuration is not the plan's is refused, naming the run.
    let tampered = lines.replacen("iterations = 2000", "iterations = 1999", 1);
    assert_ne!(tampered, lines);
    std::fs::write(committed.join("records.jsonl"), tampered).unwrap();
    let e = collect(&committed, &from_records).unwrap_err().to_string();
    assert!(e.contains(&plan.runs[0].id), "{e}");
}

/// The reduced grid's 100 % cells are Table 2's runs of the same scene, seed and arm: with the
/// Table 2 study's records to reuse, they count as finished without training; its other cells
/// do not (their configurations differ).
#[test]
fn the_reduced_grid_reuses_table2_records_for_its_full_cells() {
    let tmp = tempfile::tempdir().unwrap();
    let t2 = tmp.path().join("t2");
    let mut o = StudyOptions::new(Grid::Table2);
    o.scenes = vec!["blob".into()];
    o.seeds = 2;
    let (plan, cfgs) = make_plan(&o, None, &t2).unwrap();
    fabricate(&t2, &plan, &cfgs, |_| 1.0, |_| 100.0);
    collect(&t2, &tmp.path().join("t2-report")).unwrap();
    let red = tmp.path().join("red");
    let mut r = StudyOptions::new(Grid::Reduced);
    r.scenes = vec!["blob".into()];
    r.seeds = 2;
    let (rplan, rcfgs) = make_plan(&r, None, &red).unwrap();
    neus_aug::study::plan::open_folder(&red, &rplan, &rcfgs, None).unwrap();
    let n = neus_aug::study::plan::import_records(&red, &rplan, std::slice::from_ref(&t2)).unwrap();
    // 100 % × {baseline, SIA} × 2 seeds.
    assert_eq!(n, 4);
    let records = neus_aug::study::store::read(&red).unwrap();
    for spec in &rplan.runs {
        let full = spec.views_fraction == Some(1.0);
        assert_eq!(records.contains_key(&spec.id), full, "{}", spec.id);
        if full {
            assert_eq!(
                run_state(&red, spec, None, &records).unwrap(),
                RunState::Done
            );
        }
    }
    // Nothing to reuse from a folder without records.
    let e = neus_aug::study::plan::import_records(&red, &rplan, &[tmp.path().join("nothing")])
        .unwrap_err()
        .to_string();
    assert!(e.contains("records.jsonl"), "{e}");
}

/// `study outside` renders every mesh of `--meshes` once into the study folder's `scenes/`,
/// plans the baseline on each, and keeps the rendered scenes when called again; a dry run
/// renders nothing and plans the scenes by the folders they will have; a folder without meshes
/// is refused with the way to fetch them.
#[test]
fn the_outside_grid_renders_each_mesh_once_and_plans_the_baseline() {
    let tmp = tempfile::tempdir().unwrap();
    let meshes = tmp.path().join("meshes");
    std::fs::create_dir_all(&meshes).unwrap();
    let err = fails(
        &neus_aug()
            .args(["study", "outside", "--dry-run", "--meshes"])
            .arg(&meshes)
            .arg("--out")
            .arg(tmp.path().join("none"))
            .output()
            .unwrap(),
    );
    assert!(
        err.contains("no .ply or .obj") && err.contains("fetch_outside.py"),
        "{err}"
    );
    // An octahedron, stretched so it has an up axis.
    let obj = "v 1 0 0\nv -1 0 0\nv 0 2 0\nv 0 -2 0\nv 0 0 1\nv 0 0 -1\n\
               f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n";
    std::fs::write(meshes.join("gem.obj"), obj).unwrap();
    std::fs::write(meshes.join("notes.txt"), "not a mesh").unwrap();
    let dir = tmp.path().join("outside");
    let cmd = |mode: &[&str]| {
        let mut c = neus_aug();
        c.args(["study", "outside", "--seeds", "2", "--meshes"])
            .arg(&meshes)
            .args(mode)
            .arg(&dir);
        c
    };
    let dry = ["--dry-run", "--out"];
    let jobs = ["--emit-jobs"];
    // A dry run writes nothing and still plans both runs.
    let o = cmd(&dry).output().unwrap();
    let err = ok(&o);
    assert!(
        err.contains("would render") && !err.contains("rendering"),
        "{err}"
    );
    assert!(!dir.exists(), "a dry run wrote {}", dir.display());
    let plan = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(plan.contains("(2 runs)"), "{plan}");
    for id in ["gem-baseline-s0", "gem-baseline-s1"] {
        assert!(plan.contains(id), "{plan}");
    }
    assert!(plan.contains("--preset fast --aug none"), "{plan}");
    assert!(plan.contains("scenes/gem"), "{plan}");
    // Planning for real renders the scene once.
    let err = ok(&cmd(&jobs).output().unwrap());
    assert!(err.contains("rendering"), "{err}");
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("scenes/gem/meta.json")).unwrap())
            .unwrap();
    assert_eq!(meta["mesh_genus"], 0);
    // Called again: the scene is reused, not rendered again, and a dry run plans the same runs.
    let before = std::fs::metadata(dir.join("scenes/gem/meta.json"))
        .unwrap()
        .modified()
        .unwrap();
    let err = ok(&cmd(&jobs).output().unwrap());
    assert!(!err.contains("rendering"), "{err}");
    let o = cmd(&dry).output().unwrap();
    let err = ok(&o);
    assert!(!err.contains("render"), "{err}");
    let again = String::from_utf8_lossy(&o.stdout).into_owned();
    assert_eq!(
        plan.lines().count(),
        again.lines().count(),
        "{plan}\n{again}"
    );
    let after = std::fs::metadata(dir.join("scenes/gem/meta.json"))
        .unwrap()
        .modified()
        .unwrap();
    assert_eq!(before, after);
}

/// A reader that stops early (`| head`) ends the listing quietly: no panic on the closed pipe.
#[test]
fn a_closed_pipe_ends_a_long_listing_without_a_panic() {
    use std::io::{BufRead, BufReader};
    // 20 seeds × 27 runs of ~200 bytes: more than a pipe's buffer, so writes hit the closed pipe.
    let mut child = neus_aug()
        .args(["study", "table2", "--seeds", "20", "--dry-run"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.starts_with("# study table2"), "{first}");
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
}

/// `--reuse-training DIR`: a study that differs from a finished one only in mesh settings
/// borrows each run's final checkpoint and re-extracts (no step trained), and its mesh differs;
/// a study of other training borrows nothing and trains; a folder that is no study is refused.
#[test]
fn mesh_only_variants_reuse_another_studys_training() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path());
    let (base, variant, other) = (
        tmp.path().join("base"),
        tmp.path().join("variant"),
        tmp.path().join("other"),
    );
    let hard = |dir: &Path, extra: &[&str]| {
        let mut c = neus_aug();
        c.args(["study", "hard", "--seeds", "1", "--scenes"])
            .arg(tiny_scene())
            .arg("--config")
            .arg(&cfg)
            .args(extra)
            .arg("--out")
            .arg(dir)
            .arg("--quiet");
        c.output().unwrap()
    };
    ok(&hard(&base, &[]));
    let ids: Vec<String> = run_folders(&base)
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(ids.len(), 1, "{ids:?}");
    let reuse = base.to_str().unwrap();
    let read = |dir: &Path| -> serde_json::Value {
        let p = run_dir(dir, &ids[0]).join("metrics.json");
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    // Mesh settings only: the checkpoint is borrowed, nothing is trained, the mesh changes.
    ok(&hard(
        &variant,
        &["--set", "mesh.fine_res=24", "--reuse-training", reuse],
    ));
    assert_eq!(log_lines(&variant, "reuse"), ids);
    let (b, v) = (read(&base), read(&variant));
    assert_eq!(v["train"]["resumed_from"], 40, "the variant trained: {v}");
    assert_eq!(b["train"]["resumed_from"], serde_json::Value::Null);
    assert_eq!(v["config_hash"], b["config_hash"]);
    assert_ne!(v["mesh"]["vertices"], b["mesh"]["vertices"]);
    // Other training (fewer steps): nothing to borrow; it trains.
    ok(&hard(
        &other,
        &["--set", "train.iterations=30", "--reuse-training", reuse],
    ));
    assert!(log_lines(&other, "reuse").is_empty());
    assert_eq!(
        read(&other)["train"]["resumed_from"],
        serde_json::Value::Null
    );
    // A folder that holds no study is refused before anything runs.
    let err = fails(&hard(
        &tmp.path().join("x"),
        &["--reuse-training", tmp.path().to_str().unwrap()],
    ));
    assert!(
        err.contains("--reuse-training") && err.contains("runs/"),
        "{err}"
    );
    assert!(!tmp.path().join("x").exists());
}
