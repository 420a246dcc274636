//! Regression test for the membrane across a hole: a tiny `torus` (24 views at
//! 100×75, the held-out view looks through the hole) trained for 300 steps of the fast preset.
//!
//! With the references' clamped mask BCE (`model.loss.mask_bce = "clamp"`) a membrane closes the
//! hole: measured on the development machine (fast preset with its coarse-to-fine levels),
//! held-out silhouette IoU 0.70 and 11.7k mesh faces outside every training mask; with the
//! default squashed BCE the hole stays open (IoU 0.93, no face outside the masks). The test
//! asserts the open hole, so it fails when the membrane returns.
//!
//! Also the truth a reconstruction is judged against: the true genus and the
//! Chamfer floor that `meta.json` records, and what `metrics.json` makes of them; and the depth
//! prior's automatic switch, which must fire on a cup and not on a blob.

mod common;

use common::tiny::neus_aug;
use neus_aug::sim;

/// Writes the built-in scene `name` into `dir` at the size these tests use (24 views at 100×75,
/// one sample per pixel, ground-truth points every 1 mm); returns its DTU scan number.
fn small_scene(name: &str, dir: &std::path::Path) -> u32 {
    let mut desc = sim::builtin(name).unwrap();
    desc.rig.views = 24;
    desc.rig.resolution = [100, 75];
    desc.render.spp = 1;
    desc.gt.spacing_mm = 1.0;
    sim::generate(&desc, dir, &Default::default()).unwrap();
    desc.scan
}

#[test]
fn torus_hole_stays_open() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("torus");
    small_scene("torus", &scene);
    let out = tmp.path().join("run");
    let o = neus_aug()
        .arg("reconstruct")
        .arg(&scene)
        .args([
            "--preset",
            "fast",
            "--iterations",
            "300",
            "--seed",
            "0",
            "--quiet",
        ])
        .args(["--set", "mesh.coarse_res=64", "--set", "mesh.fine_res=96"])
        .args(["--set", "data.holdout=1", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    let iou = m["mask_iou_heldout"].as_f64().unwrap();
    let culled = m["mesh"]["clean"]["faces_culled_by_masks"]
        .as_u64()
        .unwrap();
    let raw = m["mesh"]["raw_faces"].as_u64().unwrap();
    assert!(
        iou > 0.85,
        "held-out silhouette IoU {iou:.3}: a membrane fills the hole\n{m:#}"
    );
    assert!(
        (culled as f64) < 0.02 * raw as f64,
        "{culled} of {raw} faces lie outside the training masks: a membrane fills the hole"
    );
    // The cleaned closed surface is in one piece, and has the hole (genus 1, measured on the
    // closed surface: the scored `mesh.ply` lacks the underside no camera sees).
    assert_eq!(
        m["mesh"]["clean"]["components_after"].as_u64(),
        Some(1),
        "{m:#}"
    );
    assert_eq!(m["mesh"]["largest_genus"].as_i64(), Some(1), "{m:#}");
}

/// The depth prior's automatic switch (`train.depth.auto`) on two small scenes (24
/// views at 100×75, the `fast` preset told its run is 300 steps long, so the check comes after
/// step 200): on `cup` the field has closed the cavity and the switch fires, on `blob` it does
/// not. Measured on the development machine: 22.9 % of the cup's rays with solid more than 0.2
/// in front of their stereo depth, 0.74 % of the blob's (threshold 5 %; at full size 23.7 % and
/// 0.23 %, `results/geometry/depth-auto-2026-11-28`). The runs stop after the check.
#[test]
fn depth_auto_switch_fires_on_a_cup_and_not_on_a_blob() {
    let tmp = tempfile::tempdir().unwrap();
    for (name, fires) in [("cup", true), ("blob", false)] {
        let scene = tmp.path().join(name);
        small_scene(name, &scene);
        let out = tmp.path().join(format!("{name}-run"));
        let o = neus_aug()
            .arg("reconstruct")
            .arg(&scene)
            .args(["--preset", "fast", "--iterations", "300", "--seed", "0"])
            .args(["--stop-after", "201", "--quiet", "--set", "data.holdout=1"])
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("stopped after step 201"), "{name}: {err}");
        let d: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("depth_auto.json")).unwrap())
                .unwrap();
        assert_eq!(d["step"].as_u64(), Some(200), "{name}: {d}");
        assert!(d["rays"].as_u64().unwrap() > 5000, "{name}: {d}");
        let share = d["share"].as_f64().unwrap();
        assert_eq!(d["triggered"].as_bool(), Some(fires), "{name}: {d}");
        if fires {
            assert!(
                share > 0.10,
                "{name}: a lid over the cavity should show clearly: {d}"
            );
        } else {
            assert!(share < 0.025, "{name}: {d}");
        }
    }
}

/// The seen floor (`reconstruct::seen_floor`) on two small scenes (24 views at 100×75, every
/// view a training camera): with no cut it is the floor `meta.json` holds (the subdivided truth
/// is the same surface); cutting what fewer than 2 cameras see costs the cup's completeness
/// more than the blob's, since only one camera of the DTU-style rig sees the cup's inner wall
/// near the bottom. Measured on the development machine: completeness +0.401 mm on the cup,
/// +0.092 on the blob (the small rig sees less of both than the full one; at full size, 400×300
/// and 46 training views, see `results/geometry/seen-floor-2026-11-28`).
#[test]
fn the_seen_floor_cuts_what_one_camera_sees() {
    use neus_aug::mesh::clean::SpeckRule;
    use neus_aug::reconstruct::seen_floor::{seen_floor, SeenRule};
    use neus_aug::scene::{LoadOptions, Scene};
    let tmp = tempfile::tempdir().unwrap();
    let mut extra = Vec::new();
    for name in ["cup", "blob"] {
        let dir = tmp.path().join(name);
        let scan = small_scene(name, &dir);
        let scene = Scene::load(&dir, &LoadOptions::default()).unwrap();
        let cameras: Vec<_> = scene.views.iter().map(|v| &v.camera).collect();
        let gt = dtu_eval::protocol::GroundTruth::load(&dir, scan).unwrap();
        let truth = dtu_eval::ply::read_mesh(&dir.join("gt_mesh.ply")).unwrap();
        let floor = sim::SceneTruth::read(&dir).floor.unwrap();
        let params = dtu_eval::report::DtuParams::default();
        let at = |min_views| {
            let rule = SeenRule {
                min_views,
                margin_mm: 0.0,
                min_area_share: 0.02,
                specks: SpeckRule::Piece,
            };
            seen_floor(
                &truth,
                &scene.normalization,
                &cameras,
                &rule,
                &gt,
                &params,
                0,
            )
            .unwrap()
            .unwrap()
        };
        let (none, one, two) = (at(0), at(1), at(2));
        // Uncut, the scored mesh is the true mesh: the floor to the bit at the floor's seed.
        assert_eq!(none.area_share_cut, 0.0, "{name}");
        let uncut = seen_floor(
            &truth,
            &scene.normalization,
            &cameras,
            &SeenRule {
                min_views: 0,
                margin_mm: 0.0,
                min_area_share: 0.02,
                specks: SpeckRule::Piece,
            },
            &gt,
            &params,
            sim::FLOOR_SEED,
        )
        .unwrap()
        .unwrap();
        assert_eq!(uncut.chamfer_sum, floor.chamfer_sum, "{name}");
        // Fewer faces can only lose completeness (up to the protocol's sampling).
        assert!(
            two.mean_s2d >= one.mean_s2d - 1e-3,
            "{name}: {one:?} {two:?}"
        );
        assert!(two.area_share_cut > one.area_share_cut, "{name}");
        extra.push(two.mean_s2d - one.mean_s2d);
        eprintln!("{name}: none {none:?}\n one {one:?}\n two {two:?}");
    }
    let (cup, blob) = (extra[0], extra[1]);
    assert!(
        cup > 0.2 && cup > 2.0 * blob,
        "completeness the 2-view cut costs: cup {cup:.3} mm, blob {blob:.3} mm"
    );
}

/// `reconstruct SCENE --config CFG --out OUT --set SET --quiet`, which must succeed; its stderr
/// and `metrics.json`.
fn reconstruct_tiny(
    scene: &std::path::Path,
    cfg: &std::path::Path,
    out: &std::path::Path,
    set: &str,
) -> (String, serde_json::Value) {
    let o = neus_aug()
        .arg("reconstruct")
        .arg(scene)
        .args([
            "--config",
            cfg.to_str().unwrap(),
            "--quiet",
            "--set",
            set,
            "--out",
        ])
        .arg(out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "{err}");
    let m = serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap());
    (err, m.unwrap())
}

/// A run whose SDF never crosses zero (a sphere init far below one marching-cubes cell and no
/// visual-hull start, one step) ends with an error that names the cause, and no `metrics.json`:
/// a folder with nothing to score is not a finished run.
#[test]
fn an_empty_mesh_is_an_error_naming_the_cause() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = common::tiny::write_config(
        tmp.path(),
        1,
        "[model.field.sdf]\nsphere_init_radius = 0.001\n",
    );
    let out = tmp.path().join("run");
    // The sphere init alone: the preset's visual-hull start would give a surface.
    let o = common::tiny::neus_aug()
        .arg("reconstruct")
        .arg(common::tiny::scene())
        .args(["--config", cfg.to_str().unwrap(), "--quiet", "--out"])
        .arg(&out)
        .args(["--set", "train.init.kind=\"sphere\""])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("the mesh is empty") && err.contains("never crosses zero"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.join("metrics.json").exists());
}

/// The seen floor is a diagnostic: a scene folder whose `gt_mesh.ply` cannot be read (here, not
/// a PLY) still gets its run, its Chamfer figure and its floor, with a warning and no seen
/// floor; with a held-out view, its held-out PSNR too, with a second warning and no normal
/// error (the one figure there that needs the true mesh).
#[test]
fn an_unreadable_true_mesh_costs_the_seen_floor_not_the_run() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("scene");
    let src = common::tiny::scene();
    for sub in ["", "image", "mask", "Points/stl", "ObsMask"] {
        std::fs::create_dir_all(scene.join(sub)).unwrap();
        for e in std::fs::read_dir(src.join(sub)).unwrap() {
            let e = e.unwrap();
            if e.file_type().unwrap().is_file() {
                std::fs::copy(e.path(), scene.join(sub).join(e.file_name())).unwrap();
            }
        }
    }
    std::fs::write(scene.join("gt_mesh.ply"), "not a ply\n").unwrap();
    let cfg = common::tiny::write_config(tmp.path(), 24, "");
    let (err, m) = reconstruct_tiny(&scene, &cfg, &tmp.path().join("run"), "data.holdout=1");
    assert!(err.contains("warning: no seen floor"), "{err}");
    assert!(err.contains("warning: no held-out normal error"), "{err}");
    // Each warning names the file once.
    assert_eq!(err.matches("gt_mesh.ply").count(), 2, "{err}");
    assert!(m["chamfer"]["chamfer_sum"].as_f64().unwrap().is_finite());
    assert!(m["floor_mm"].as_f64().unwrap() > 0.0, "{m:#}");
    assert!(m["floor_seen"].is_null(), "{m:#}");
    assert!(m["psnr_heldout"].as_f64().unwrap().is_finite(), "{m:#}");
    assert!(m["normal_error_deg"].is_null(), "{m:#}");
}

/// `meta.json` holds the true mesh's genus (largest component, Euler characteristic) and the
/// Chamfer floor, and the floor is what the DTU protocol gives on the written files.
#[test]
fn meta_json_holds_the_true_genus_and_the_floor() {
    let tmp = tempfile::tempdir().unwrap();
    for (name, genus) in [("blob", 0), ("torus", 1), ("double-torus", 2)] {
        let mut desc = sim::builtin(name).unwrap();
        desc.rig.views = 6;
        desc.rig.resolution = [40, 30];
        desc.render.spp = 1;
        desc.gt.spacing_mm = 1.0;
        desc.gt.obs_res_mm = 4.0;
        let dir = tmp.path().join(name);
        let report = sim::generate(&desc, &dir, &Default::default()).unwrap();
        let meta: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("meta.json")).unwrap()).unwrap();
        assert_eq!(meta["mesh_genus"].as_i64(), Some(genus), "{name}");
        assert_eq!(meta["mesh_components"].as_u64(), Some(1), "{name}");
        assert_eq!(report.mesh_genus, genus);
        let floor = meta["floor"]["chamfer_sum"].as_f64().unwrap();
        let (acc, comp) = (
            meta["floor"]["mean_d2s"].as_f64().unwrap(),
            meta["floor"]["mean_s2d"].as_f64().unwrap(),
        );
        // The true mesh against points sampled from it every 1 mm: a fraction of a millimetre.
        assert!(
            floor.is_finite() && floor > 0.0 && floor < 1.5,
            "{name}: {floor}"
        );
        assert_eq!(floor, acc + comp);
        // The same protocol on the files written gives the same figure, bit for bit.
        let gt = dtu_eval::protocol::GroundTruth::load(&dir, desc.scan).unwrap();
        let mesh = dtu_eval::ply::read_mesh(&dir.join("gt_mesh.ply")).unwrap();
        let again = sim::chamfer_floor(&mesh, &gt).unwrap();
        assert_eq!(again.chamfer_sum, floor, "{name}");
        // And a reconstruction reads it back.
        let truth = sim::SceneTruth::read(&dir);
        assert_eq!(truth.genus, Some(genus));
        assert_eq!(truth.floor.map(|f| f.chamfer_sum), Some(floor));
        assert_eq!(truth.scan, Some(desc.scan));
    }
    assert_eq!(
        sim::SceneTruth::read(tmp.path()),
        sim::SceneTruth::default(),
        "a folder without meta.json knows nothing"
    );
    // A true mesh with open or non-manifold edges has no genus to judge against (the Stanford
    // dragon's 108 edges shared by four faces give an Euler "genus" of 23).
    let odd = tmp.path().join("odd");
    std::fs::create_dir_all(&odd).unwrap();
    for (closed, want) in [(false, None), (true, Some(23))] {
        let meta =
            serde_json::json!({"scan": 100, "mesh_genus": 23, "mesh_closed_oriented": closed});
        std::fs::write(odd.join("meta.json"), meta.to_string()).unwrap();
        assert_eq!(sim::SceneTruth::read(&odd).genus, want, "closed {closed}");
    }
}
