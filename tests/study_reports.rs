//! `neus-aug study collect` on fabricated results with known statistics (no training): the
//! tables, intervals, verdicts and plots of the Table 2, hard, pareto, reduced and degradation
//! reports; and every study record committed under `results/` still matching its plan under this
//! build. The runs themselves (resume, jobs, refusals) are in `tests/study.rs`.

mod common;

use common::study::fabricate;
use neus_aug::augment::AugMode;
use neus_aug::reconstruct::Preset;
use neus_aug::study::plan::{make_plan, run_dir};
use neus_aug::study::{collect, Grid, StudyOptions};
use std::collections::BTreeMap;
use std::path::Path;

#[test]
fn collect_on_known_numbers_gives_the_expected_tables() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("t2");
    let mut o = StudyOptions::new(Grid::Table2);
    o.scenes = vec!["blob".into(), "torus".into()];
    o.seeds = 3;
    let (plan, cfgs) = make_plan(&o, None, &dir).unwrap();
    // baseline 2 + seed/10 (+1 on torus); SIA exactly 0.1 lower; DIA 0.2 higher; DIA trains 3×.
    fabricate(
        &dir,
        &plan,
        &cfgs,
        |r| {
            let base = 2.0 + r.seed as f64 / 10.0 + if r.scene == "torus" { 1.0 } else { 0.0 };
            base + match r.arm {
                AugMode::None => 0.0,
                AugMode::Sia => -0.1,
                AugMode::Dia => 0.2,
            }
        },
        |r| if r.arm == AugMode::Dia { 300.0 } else { 100.0 },
    );
    let to = tmp.path().join("out");
    collect(&dir, &to).unwrap();
    let md = std::fs::read_to_string(to.join("report.md")).unwrap();
    // blob baseline mean 2.1, DIA 2.3, SIA 2.0 (best, bold), baseline runner-up (italic).
    for s in [
        "| blob | *2.100* | 2.300 | **2.000** |",
        "| torus | *3.100* | 3.300 | **3.000** |",
        "| mean | *2.600* | 2.800 | **2.500** |",
        "| train time (s) | 100 | 300 | 100 |",
        "| train time / baseline | 1.00× | 3.00× | 1.00× |",
        // A constant paired difference: a zero-width interval at the constant.
        "| blob | +0.200 [+0.200, +0.200] (n=3) | −0.100 [−0.100, −0.100] (n=3) |",
        "| mean | +0.200 [+0.200, +0.200] (n=6) | −0.100 [−0.100, −0.100] (n=6) |",
        "| blob | 0.100 | 0.100 | 0.100 |",
        "| blob | 0.840 / 1.260 |",
        "| DIA | +0.00 (+0.0 %) | +0.200 [+0.200, +0.200] (n=6) (+7.7 %) | disagrees: here the arm is worse",
        "| SIA | −0.12 (−5.9 %) | −0.100 [−0.100, −0.100] (n=6) (−3.8 %) | agrees: same direction",
    ] {
        assert!(md.contains(s), "report lacks {s:?}:\n{md}");
    }
    let csv = std::fs::read_to_string(to.join("runs.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 18);
    // Records without the geometry figures (all of these) keep the columns and files they had.
    assert!(
        csv.lines().next().unwrap().ends_with(",time_to_mesh"),
        "{csv}"
    );
    let runs_json = std::fs::read_to_string(to.join("runs.json")).unwrap();
    assert!(
        !runs_json.contains("floor_mm") && !md.contains("Geometry"),
        "{runs_json}"
    );
    assert!(csv
        .lines()
        .nth(1)
        .unwrap()
        .starts_with("blob-baseline-s0,blob,full,baseline,0,fast"));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(to.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["collected"], 18);

    // A part of the study (`collect --scenes torus --seeds 2`): torus at seeds 0 and 1 only
    // (baseline 3.0 and 3.1), reported as a study planned with those options.
    let part = |scenes: Option<&[&str]>, seeds: Option<u32>| {
        let opts = neus_aug::study::CollectOptions {
            subset: neus_aug::study::Subset {
                scenes: scenes.map(|l| l.iter().map(|s| s.to_string()).collect()),
                seeds,
            },
            ..Default::default()
        };
        neus_aug::study::collect_with(&dir, &tmp.path().join("part"), &opts)
    };
    let c = part(Some(&["torus"]), Some(2)).unwrap();
    assert_eq!((c.planned, c.collected), (6, 6));
    let md = std::fs::read_to_string(tmp.path().join("part/report.md")).unwrap();
    for s in [
        "2 seed(s) per cell (0–1), scenes: torus.",
        "--seeds 2 --scenes torus",
        "| torus | *3.050* | 3.250 | **2.950** |",
        "| torus | +0.200 [+0.200, +0.200] (n=2) | −0.100 [−0.100, −0.100] (n=2) |",
    ] {
        assert!(md.contains(s), "the part's report lacks {s:?}:\n{md}");
    }
    assert!(!md.contains("| blob |"), "{md}");
    // An unknown scene, or seeds the study does not have, are refused by option.
    let e = part(Some(&["torus", "nope"]), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("--scenes") && e.contains("nope") && e.contains("blob"),
        "{e}"
    );
    for n in [0, 4] {
        let e = part(None, Some(n)).unwrap_err().to_string();
        assert!(e.contains("--seeds") && e.contains("0..3"), "{e}");
    }

    // A metrics.json from another training is refused.
    let m = run_dir(&dir, &plan.runs[4].id).join("metrics.json");
    let text = std::fs::read_to_string(&m).unwrap();
    std::fs::write(
        &m,
        text.replace(&plan.runs[4].training_hash, "0123456789abcdef"),
    )
    .unwrap();
    let e = collect(&dir, &to).unwrap_err().to_string();
    assert!(
        e.contains(&plan.runs[4].id) && e.contains("0123456789abcdef"),
        "{e}"
    );
}

/// The `hard` grid's report on fabricated runs: every run but one carries the geometry figures
/// (floor, ratio, genus, components, normal error); `blob-baseline-s2` is a record written
/// before they existed and still loads, shown as unknown.
#[test]
fn hard_report_from_known_numbers_and_an_old_record() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("hard");
    let mut o = StudyOptions::new(Grid::Hard);
    assert_eq!(o.scenes.len(), neus_aug::sim::CATALOG.len());
    o.scenes = vec!["blob".into(), "torus".into()];
    let (plan, cfgs) = make_plan(&o, None, &dir).unwrap();
    // blob: the baseline only; torus: baseline, DIA and SIA.
    assert_eq!(plan.runs.len(), 3 + 3 * 3);
    // blob 0.5 + seed/10; torus baseline 1.0, DIA 1.2, SIA 0.8 (+ seed/10).
    let chamfer = |r: &neus_aug::study::RunSpec| {
        let base = if r.scene == "blob" { 0.5 } else { 1.0 };
        base + r.seed as f64 / 10.0
            + match r.arm {
                AugMode::None => 0.0,
                AugMode::Dia => 0.2,
                AugMode::Sia => -0.2,
            }
    };
    fabricate(&dir, &plan, &cfgs, chamfer, |_| 100.0);
    for r in &plan.runs {
        if r.id == "blob-baseline-s2" {
            continue;
        }
        let (floor, truth) = if r.scene == "blob" {
            (0.25, 0)
        } else {
            (0.2, 1)
        };
        // One DIA run on the torus closes the hole.
        let genus = if r.id == "torus-dia-s1" { 0 } else { truth };
        let path = run_dir(&dir, &r.id).join("metrics.json");
        let mut m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        m["floor_mm"] = floor.into();
        m["ratio_to_floor"] = (chamfer(r) / floor).into();
        m["gt_genus"] = truth.into();
        m["genus_matches"] = (genus == truth).into();
        m["normal_error_deg"] = 5.0.into();
        // The seen floor on the torus baseline only (the other arms' records predate it).
        if r.scene == "torus" && r.arm == AugMode::None {
            m["floor_seen"] = serde_json::json!({"chamfer_sum": 0.25, "mean_d2s": 0.1,
                "mean_s2d": 0.15, "min_views": 2, "area_share_cut": 0.3, "faces_judged": 100});
            m["ratio_to_floor_seen"] = (chamfer(r) / 0.25).into();
        }
        m["mesh"] = serde_json::json!({"vertices": 50, "faces": 90, "components": 1,
            "genus": genus, "largest_genus": genus, "raw_components": 5, "raw_faces": 100});
        // The depth prior: switched on by its check in one run, asked for in another.
        let maps = serde_json::json!({"considered": 10, "with_depth": 9, "filled": 1,
            "hole_filled": 1, "seconds": 1.0});
        if r.id == "torus-sia-s1" {
            m["train"]["depth_maps"] = maps.clone();
            m["train"]["depth_auto"] = serde_json::json!({"step": 200, "views": [0, 1],
                "rays": 100, "in_front": 20, "share": 0.2, "margin": 0.2, "threshold": 0.05,
                "triggered": true, "seconds": 1.0});
        } else if r.id == "torus-sia-s2" {
            m["train"]["depth_maps"] = maps;
        }
        std::fs::write(&path, m.to_string()).unwrap();
    }
    let to = tmp.path().join("out");
    collect(&dir, &to).unwrap();
    let md = std::fs::read_to_string(to.join("report.md")).unwrap();
    for s in [
        "# Study `hard`",
        // blob: Chamfer over 3 runs, ratio and genus over the 2 that know them.
        "| blob | baseline | 3/3 | 0.600 | 0.250 | 2.20 | 2/2 | 0, 0, — (0) | 5.0 → 1.0 | 5.0 | 25.00 |",
        "| torus | baseline | 3/3 | 1.100 | 0.200 | 5.50 | 3/3 | 1, 1, 1 (1) | 5.0 → 1.0 | 5.0 | 25.00 |",
        "| torus | DIA | 3/3 | 1.300 | 0.200 | 6.50 | 2/3 | 1, 0, 1 (1) |",
        "| torus | SIA | 3/3 | 0.900 | 0.200 | 4.50 | 3/3 |",
        // The seen floor and the ratio to it (1.1 / 0.25), unknown where the records lack it.
        "| 5.0 | 25.00 | 0.250 | 4.40 |",
        "| blob | baseline | 3/3 | 0.600 | 0.250 | 2.20 | 2/2 | 0, 0, — (0) | 5.0 → 1.0 | 5.0 | 25.00 | — | — |",
        "| torus | DIA | 3/3 | 1.300 | 0.200 | 6.50 | 2/3 | 1, 0, 1 (1) | 5.0 → 1.0 | 5.0 | 25.00 | — | — |",
        // The suite mean of the baseline's ratio: (2.20 + 5.50) / 2; to the seen floor, the
        // torus alone.
        "ratio to the floor **3.85×**",
        "Ratio to the seen floor: 4.40×.",
        // blob (2.20) is within 4× its floor, the torus baseline (5.50) is not.
        "Scenes within 4× their floor: 1/2.",
        // The median and the worst of the per-scene ratios; genus over the baseline's runs
        // that know it (blob 2 of 2, torus 3 of 3).
        "Median ratio 3.85×, worst 5.50× (torus); the true genus in 5 of 5 runs.",
        // Genus on the scenes with holes: 8 of 9 on the torus.
        "| torus | 3/3 | 2/3 | 3/3 | 8/9 |",
        "| all | 3/3 | 2/3 | 3/3 | 8/9 |",
        // Every run; the old record shows what it does not know as unknown.
        "| torus-dia-s1 | 1.300 | 0.200 | 6.50 | 0 (1) ≠ | 5 → 1 | 5.0 | 25.00 |",
        "| blob-baseline-s2 | 0.700 | — | — | — (?) | — → — | — | 25.00 |",
        // Paired differences only where the augmentations ran.
        "| torus | +0.200 [+0.200, +0.200] (n=3) | −0.200 [−0.200, −0.200] (n=3) |",
    ] {
        assert!(md.contains(s), "report lacks {s:?}:\n{md}");
    }
    assert!(!md.contains("| blob | +"), "no paired row for blob:\n{md}");
    let csv = std::fs::read_to_string(to.join("runs.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(header.ends_with(",time_to_mesh,floor_mm,ratio_to_floor,genus,gt_genus,genus_matches,components_raw,components,normal_error_deg,chamfer_closed,depth_prior,floor_seen_mm,ratio_to_floor_seen"), "{header}");
    let old = csv
        .lines()
        .find(|l| l.starts_with("blob-baseline-s2,"))
        .unwrap();
    assert!(old.ends_with(",,,,,,,,"), "{old}");
    // The depth prior's column: off where the record says neither.
    let torus = csv
        .lines()
        .find(|l| l.starts_with("torus-dia-s1,"))
        .unwrap();
    assert!(torus.ends_with(",off,,"), "{torus}");
    for (id, what) in [
        ("torus-sia-s1", "switched on,,"),
        ("torus-sia-s2", "asked,,"),
        ("torus-baseline-s0", "off,0.25,4"),
    ] {
        let l = csv
            .lines()
            .find(|l| l.starts_with(&format!("{id},")))
            .unwrap();
        assert!(l.ends_with(&format!(",{what}")), "{l}");
    }
    assert!(md.contains("| depth prior |"), "{md}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(to.join("summary.json")).unwrap()).unwrap();
    let suite = &summary["geometry"]["suite"][0];
    assert!(
        (suite["ratio_mean"].as_f64().unwrap() - 3.85).abs() < 1e-9,
        "{suite}"
    );
    assert!(
        (suite["ratio_seen_mean"].as_f64().unwrap() - 4.4).abs() < 1e-9,
        "{suite}"
    );
    assert_eq!(suite["scenes"], 2);
    let cells = summary["geometry"]["cells"].as_array().unwrap();
    assert_eq!(cells.len(), 4);
    assert_eq!(
        (
            cells[2]["genus_matches"].as_u64(),
            cells[2]["genus_known"].as_u64()
        ),
        (Some(2), Some(3))
    );
    // Collecting again gives the same bytes.
    let again = tmp.path().join("again");
    collect(&dir, &again).unwrap();
    for f in ["report.md", "runs.csv", "runs.json", "summary.json"] {
        assert_eq!(
            std::fs::read(to.join(f)).unwrap(),
            std::fs::read(again.join(f)).unwrap(),
            "{f}"
        );
    }
}

#[test]
fn pareto_and_reduced_reports_from_known_numbers() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("pareto");
    let o = StudyOptions::new(Grid::Pareto);
    let (plan, cfgs) = make_plan(&o, None, &dir).unwrap();
    assert_eq!(plan.options.preset, Preset::Fast);
    // Error falls with iterations and samples; time grows with them.
    let cost = |c: &neus_aug::reconstruct::RunConfig| {
        c.train.iterations as f64 * c.model.render.num_samples_per_ray as f64
            / (c.data.downscale as f64).powi(2)
            / 1000.0
    };
    let by_id: BTreeMap<String, f64> = plan
        .runs
        .iter()
        .zip(&cfgs)
        .map(|(r, c)| (r.id.clone(), cost(c)))
        .collect();
    fabricate(
        &dir,
        &plan,
        &cfgs,
        |r| 1.0 + 100.0 / by_id[&r.id] + if r.condition == "mc=128" { 0.5 } else { 0.0 },
        |r| by_id[&r.id],
    );
    let to = tmp.path().join("out");
    collect(&dir, &to).unwrap();
    let csv = std::fs::read_to_string(to.join("pareto.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 12, "{csv}");
    let row = |v: &str| {
        csv.lines()
            .find(|l| l.starts_with(&format!("{v},")))
            .unwrap_or_else(|| panic!("no {v} in {csv}"))
            .to_string()
    };
    // The mesh-only variant costs the centre's training: same time to mesh as the centre
    // (fabricated mesh times are equal), worse error → dominated.
    assert!(row("mc=128").ends_with(",false"), "{csv}");
    assert!(row("iterations=250").ends_with(",true"), "{csv}");
    let centre_t: f64 = row("centre").split(',').nth(6).unwrap().parse().unwrap();
    let mc_t: f64 = row("mc=128").split(',').nth(6).unwrap().parse().unwrap();
    assert_eq!(centre_t, mc_t);
    let png = std::fs::read(to.join("pareto.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let md = std::fs::read_to_string(to.join("report.md")).unwrap();
    assert!(md.contains("## Accuracy against time"), "{md}");
    // Another study's front beside this one's: the plot changes, the tables do not.
    let reference = neus_aug::study::report::read_reference_front(&to, "old build").unwrap();
    let with = tmp.path().join("with-ref");
    neus_aug::study::collect_with(
        &dir,
        &with,
        &neus_aug::study::CollectOptions {
            reference: Some(&reference),
            ..Default::default()
        },
    )
    .unwrap();
    assert_ne!(std::fs::read(with.join("pareto.png")).unwrap(), png);
    assert_eq!(
        std::fs::read_to_string(with.join("pareto.csv")).unwrap(),
        csv
    );

    let dir = tmp.path().join("reduced");
    let o = StudyOptions::new(Grid::Reduced);
    let (plan, cfgs) = make_plan(&o, None, &dir).unwrap();
    fabricate(
        &dir,
        &plan,
        &cfgs,
        |r| 3.0 - r.views_fraction.unwrap() - if r.arm == AugMode::Sia { 0.05 } else { 0.0 },
        |_| 10.0,
    );
    collect(&dir, &to).unwrap();
    let md = std::fs::read_to_string(to.join("report.md")).unwrap();
    assert!(md.contains("| views 10% | 2.900 | **2.850** |"), "{md}");
    assert!(
        md.contains("| all conditions | −0.050 [−0.050, −0.050] (n=15) |"),
        "{md}"
    );
    // Against the paper: each reduction agrees, so the claim over all of them does.
    assert!(
        md.contains("| views 10% | 5.72 / 4.77 (−0.95) | −0.050 [−0.050, −0.050] (n=3) | agrees"),
        "{md}"
    );
    assert!(
        md.contains("**agrees**: every one of the 4 conditions agrees"),
        "{md}"
    );
    assert!(to.join("chamfer_vs_views.png").is_file());
    assert!(!to.join("chamfer_by_degradation.png").exists());

    // A degraded grid draws one bar group per degradation beside the per-scene chart.
    let ddir = tmp.path().join("degraded");
    let dto = tmp.path().join("degraded-report");
    let o = StudyOptions::new(Grid::Degraded);
    let (plan, cfgs) = make_plan(&o, None, &ddir).unwrap();
    fabricate(&ddir, &plan, &cfgs, |_| 2.0, |_| 10.0);
    collect(&ddir, &dto).unwrap();
    let png = std::fs::read(dto.join("chamfer_by_degradation.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    assert_ne!(png, std::fs::read(dto.join("chamfer.png")).unwrap());
    let md = std::fs::read_to_string(dto.join("report.md")).unwrap();
    assert!(md.contains("`chamfer_by_degradation.png`"), "{md}");
    // Each of the five degradations is judged against its row of the paper's table.
    for paper in [
        "2.36 / 2.18",
        "2.01 / 1.90",
        "3.34 / 2.85",
        "2.68 / 2.39",
        "4.54 / 3.91",
    ] {
        assert!(md.contains(paper), "the paper's {paper} is missing:\n{md}");
    }
    // A reference front for a study that is not a pareto study is refused, not ignored.
    let opts = neus_aug::study::CollectOptions {
        reference: Some(&reference),
        ..Default::default()
    };
    let err = neus_aug::study::collect_with(&dir, &to, &opts)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("--reference-front") && err.contains("reduced"),
        "{err}"
    );
}

/// Every record committed under `results/` still matches its study's plan as this build reads
/// both: a key added to the configuration must keep the hashes of runs made before it (left out
/// of `config.toml` at its default), or every committed study stops collecting and resuming.
#[test]
fn the_committed_study_records_match_their_plans_under_this_build() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("results");
    let mut checked = 0;
    for entry in std::fs::read_dir(&root).unwrap() {
        let dir = entry.unwrap().path();
        let lines = match std::fs::read_to_string(dir.join("records.jsonl")) {
            Ok(t) if dir.join("study.toml").is_file() => t.lines().count(),
            _ => continue,
        };
        let (plan, records) = neus_aug::study::report::load_records(&dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        // The reduced grid's 100 % cells come from Table 2's records, not its own.
        assert!(
            records.len() >= lines.min(plan.runs.len()),
            "{}: {} of {lines} records match the plan",
            dir.display(),
            records.len()
        );
        checked += lines;
    }
    assert!(checked >= 135, "only {checked} committed records found");
}

/// A run folder written before every key was saved (schema 1: keys at their defaults left out,
/// and keys of since-removed features at "off") still loads: its configuration reads as the
/// same run, and a removed feature that was on is refused by name.
#[test]
fn a_schema_1_run_folder_still_loads() {
    use neus_aug::reconstruct::RunConfig;
    let text = include_str!("fixtures/schema1-fast-config.toml");
    let old = RunConfig::from_saved_toml(text, "fixture").unwrap();
    let mut now = Preset::Fast.config();
    now.scene = "blob".into();
    now.out = old.out.clone();
    now.apply_augment_to_model();
    assert_eq!(old, now, "the fixture is today's fast preset on blob");
    assert!(!text.contains("[train.depth]") && now.to_toml().contains("[train.depth.auto]"));
    // The study's configuration hash reads both texts alike.
    let o = Path::new("fixture");
    assert_eq!(
        neus_aug::study::plan::config_hash_of_toml(text, o).unwrap(),
        neus_aug::study::plan::config_hash_of_toml(&now.to_toml(), o).unwrap()
    );
    let on = text.replace("smooth_voxels = 0.0", "smooth_voxels = 1.5");
    let e = RunConfig::from_saved_toml(&on, "fixture")
        .unwrap_err()
        .to_string();
    assert!(e.contains("train.init.smooth_voxels"), "{e}");
}
