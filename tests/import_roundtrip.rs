//! The importers against the simulator's true cameras: a tiny synthetic scene is exported as a
//! COLMAP model and a transforms.json, imported back, loaded as a scene, and every camera must
//! equal the simulator's in world space (each scene mapped back with its own normalisation: the
//! only similarity an importer may choose). Plus the COLMAP binary form, and bad inputs.

mod common;

use nalgebra::Vector3;
use neus_aug::import::{self, colmap, export, transforms, ImportError, Roi};
use neus_aug::scene::{Camera, LoadOptions, Scene};
use std::path::{Path, PathBuf};

fn load(dir: &Path) -> Scene {
    Scene::load(dir, &LoadOptions::default()).unwrap()
}

/// The scene's cameras in world space (normalisation undone).
fn world_cameras(scene: &Scene) -> Vec<Camera> {
    let n = scene.normalization;
    scene
        .views
        .iter()
        .map(|v| v.camera.denormalized(n.scale, &Vector3::from(n.center)))
        .collect()
}

/// Largest relative difference between two camera lists (K relative to |K|, R absolute, centres
/// relative to the largest centre norm), and equal sizes.
fn camera_difference(a: &[Camera], b: &[Camera]) -> f64 {
    assert_eq!(a.len(), b.len());
    let scale = b.iter().map(|c| c.center.norm()).fold(1e-300, f64::max);
    let mut worst: f64 = 0.0;
    for (x, y) in a.iter().zip(b) {
        assert_eq!((x.width, x.height), (y.width, y.height));
        worst = worst.max((x.k - y.k).abs().max() / y.k.norm());
        worst = worst.max((x.r - y.r).abs().max());
        worst = worst.max((x.center - y.center).norm() / scale);
    }
    worst
}

fn sim() -> (&'static Path, Scene) {
    let dir = common::tiny::scene();
    (dir, load(dir))
}

fn colmap_import(model_dir: &Path, images: &Path, masks: Option<&Path>, out: &Path) -> Scene {
    let opts = colmap::ColmapImport {
        model_dir: model_dir.into(),
        images: images.into(),
        masks: masks.map(PathBuf::from),
        roi: None,
        roi_from: colmap::RoiSource::Points,
    };
    let (views, roi, _) = colmap::import(&opts).unwrap();
    import::write_imported_scene(out, &views, &roi, "colmap", model_dir).unwrap();
    load(out)
}

/// Points of the scene (world) that fall inside the unit sphere after its normalisation.
fn fraction_inside(scene: &Scene, points: &[[f64; 3]]) -> f64 {
    let inside = points
        .iter()
        .filter(|p| Vector3::from(scene.normalization.to_normalized(**p)).norm() <= 1.0)
        .count();
    inside as f64 / points.len() as f64
}

#[test]
fn colmap_export_then_import_gives_back_the_simulator_cameras() {
    let (dir, truth) = sim();
    let tmp = tempfile::tempdir().unwrap();
    let model_dir = export::export_colmap(dir, &tmp.path().join("colmap")).unwrap();
    assert_eq!(model_dir, tmp.path().join("colmap/sparse/0"));
    let out = tmp.path().join("scene");
    let imported = colmap_import(
        &model_dir,
        &dir.join("image"),
        Some(&dir.join("mask")),
        &out,
    );
    let d = camera_difference(&world_cameras(&imported), &world_cameras(&truth));
    assert!(d < 1e-9, "cameras differ by {d:e}");
    // Same pixels and masks, in the same order.
    for (a, b) in imported.views.iter().zip(&truth.views) {
        assert_eq!(a.image, b.image);
        assert_eq!(a.mask, b.mask);
    }
    // The ROI from the sparse points holds them, and every camera is outside it.
    let (model, _) = colmap::read_model(&model_dir).unwrap();
    assert!(model.points.len() >= 200 && model.points.len() <= 300);
    assert!(model.points.iter().all(|p| !p.track.is_empty()));
    let pts: Vec<[f64; 3]> = model.points.iter().map(|p| p.xyz).collect();
    let inside = fraction_inside(&imported, &pts);
    assert!(
        inside >= 0.96,
        "only {inside} of the points inside the unit sphere"
    );
    for v in &imported.views {
        assert!(v.camera.center.norm() > 1.0);
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("import.json")).unwrap()).unwrap();
    assert_eq!(report["views"], truth.views.len());
    assert!(report["roi"]["method"]
        .as_str()
        .unwrap()
        .contains("sparse points"));
}

#[test]
fn transforms_export_then_import_is_exact() {
    let (dir, truth) = sim();
    let tmp = tempfile::tempdir().unwrap();
    let json = export::export_transforms(dir, tmp.path()).unwrap();
    let (views, roi) = transforms::import(&json, None).unwrap();
    let out = tmp.path().join("scene");
    import::write_imported_scene(&out, &views, &roi, "transforms", &json).unwrap();
    let imported = load(&out);
    let d = camera_difference(&world_cameras(&imported), &world_cameras(&truth));
    assert!(d < 1e-9, "cameras differ by {d:e}");
    for (a, b) in imported.views.iter().zip(&truth.views) {
        assert_eq!(a.image, b.image);
        assert_eq!(a.mask, b.mask);
    }
    // The ROI from the camera layout holds most of the true surface.
    let gt = neus_aug::import::export::read_scene_cameras(dir).unwrap();
    assert_eq!(gt.cameras.len(), truth.views.len());
    let mesh = dtu_eval::ply::read_mesh(&dir.join("gt_mesh.ply")).unwrap();
    let pts: Vec<[f64; 3]> = mesh
        .vertices
        .iter()
        .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
        .collect();
    let inside = fraction_inside(&imported, &pts);
    assert!(
        inside >= 0.9,
        "only {inside} of the surface inside the unit sphere"
    );
}

#[test]
fn colmap_text_and_binary_models_give_the_same_scene_bit_for_bit() {
    let (dir, _) = sim();
    let tmp = tempfile::tempdir().unwrap();
    let text_dir = export::export_colmap(dir, &tmp.path().join("colmap")).unwrap();
    let (model, _) = colmap::read_model(&text_dir).unwrap();
    let bin_dir = tmp.path().join("bin");
    colmap::write_binary(&model, &bin_dir).unwrap();
    let (from_bin, format) = colmap::read_model(&bin_dir).unwrap();
    assert_eq!(format, colmap::ModelFormat::Binary);
    assert_eq!(from_bin, model);
    let a = tmp.path().join("a");
    let b = tmp.path().join("b");
    colmap_import(&text_dir, &dir.join("image"), None, &a);
    colmap_import(&bin_dir, &dir.join("image"), None, &b);
    assert!(!a.join("mask").exists());
    let mut files: Vec<PathBuf> = std::fs::read_dir(a.join("image"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.push(a.join("cameras_sphere.npz"));
    assert!(files.len() > 2);
    for f in files {
        let rel = f.strip_prefix(&a).unwrap();
        assert_eq!(
            std::fs::read(&f).unwrap(),
            std::fs::read(b.join(rel)).unwrap(),
            "{}",
            rel.display()
        );
    }
}

fn import_err(model_dir: &Path, images: &Path, roi: Option<Roi>, out: &Path) -> String {
    let opts = colmap::ColmapImport {
        model_dir: model_dir.into(),
        images: images.into(),
        masks: None,
        roi,
        roi_from: colmap::RoiSource::Points,
    };
    let result: Result<_, ImportError> = colmap::import(&opts).and_then(|(views, roi, _)| {
        import::write_imported_scene(out, &views, &roi, "colmap", model_dir)
    });
    result.unwrap_err().to_string()
}

#[test]
fn bad_colmap_inputs_give_errors_naming_the_file_or_model() {
    let (dir, _) = sim();
    let tmp = tempfile::tempdir().unwrap();
    let model_dir = export::export_colmap(dir, &tmp.path().join("colmap")).unwrap();
    let out = tmp.path().join("out");
    let images = dir.join("image");

    // An unknown camera model.
    let cams = model_dir.join("cameras.txt");
    let original = std::fs::read_to_string(&cams).unwrap();
    std::fs::write(&cams, original.replace("PINHOLE", "FISHEYE_9000")).unwrap();
    let err = import_err(&model_dir, &images, None, &out);
    assert!(
        err.contains("FISHEYE_9000") && err.contains("cameras.txt"),
        "{err}"
    );
    // A distorted one imports (undistorted, src/import/undistort.rs); one whose coefficients
    // are not numbers is refused with the camera named.
    let opencv = original.replace("PINHOLE", "OPENCV");
    let opencv: String = opencv
        .lines()
        .map(|l| {
            if l.starts_with('#') {
                l.to_string()
            } else {
                format!("{l} nan 0 0 0")
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(&cams, &opencv).unwrap();
    let err = import_err(&model_dir, &images, None, &out);
    assert!(
        err.contains("distortion") && err.contains("cameras.txt"),
        "{err}"
    );
    // With k1 = 0.05 the scene is written, its images resampled (no longer the source bytes'
    // pixels) and the same size.
    std::fs::write(&cams, opencv.replace(" nan 0 0 0", " 0.05 0 0 0")).unwrap();
    let distorted_out = tmp.path().join("distorted");
    colmap_import(&model_dir, &images, None, &distorted_out);
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(distorted_out.join("import.json")).unwrap())
            .unwrap();
    assert_eq!(record["undistorted"], 8, "{record}");
    let written = neus_aug::scene::RgbImage::load(&distorted_out.join("image/000000.png")).unwrap();
    let source = neus_aug::scene::RgbImage::load(&images.join("000000.png")).unwrap();
    assert_eq!(
        (written.width, written.height),
        (source.width, source.height)
    );
    assert_ne!(
        written.data, source.data,
        "the distorted view was not resampled"
    );
    std::fs::write(&cams, &original).unwrap();

    // A registered image missing from the image folder.
    let partial = tmp.path().join("partial");
    std::fs::create_dir(&partial).unwrap();
    let mut names: Vec<PathBuf> = std::fs::read_dir(&images)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    names.sort();
    for p in &names[1..] {
        std::fs::copy(p, partial.join(p.file_name().unwrap())).unwrap();
    }
    let err = import_err(&model_dir, &partial, None, &out);
    assert!(
        err.contains("000000.png") && err.contains("images.txt"),
        "{err}"
    );

    // A region of interest that holds a camera.
    let truth = load(dir);
    let c = world_cameras(&truth)[2].center;
    let roi = Roi {
        center: [c.x + 1.0, c.y, c.z],
        radius: 5.0,
    };
    let err = import_err(&model_dir, &images, Some(roi), &out);
    assert!(
        err.contains("inside the region of interest") && err.contains("000002.png"),
        "{err}"
    );
    assert!(!out.exists(), "nothing written on error");

    // A missing points3D.txt.
    std::fs::remove_file(model_dir.join("points3D.txt")).unwrap();
    let err = import_err(&model_dir, &images, None, &out);
    assert!(
        err.contains("points3D.txt") && err.contains("missing"),
        "{err}"
    );
    // No model at all.
    let err = import_err(tmp.path(), &images, None, &out);
    assert!(
        err.contains("cameras.txt") && err.contains("cameras.bin"),
        "{err}"
    );
}

#[test]
fn cli_synth_export_then_import_both_formats() {
    let tmp = tempfile::tempdir().unwrap();
    let synth = tmp.path().join("synth");
    let run = |args: &[&str]| {
        let out = common::tiny::neus_aug().args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let s = synth.to_str().unwrap();
    run(&[
        "synth",
        "blob",
        "--views",
        "6",
        "--resolution",
        "40x30",
        "--spp",
        "1",
        "--gt-spacing",
        "2",
        "--quiet",
        "--export",
        "colmap",
        "--export",
        "transforms",
        "--out",
        s,
    ]);
    assert!(synth.join("colmap/sparse/0/images.txt").is_file());
    assert!(synth.join("transforms.json").is_file());
    let truth = world_cameras(&load(&synth));
    // `import colmap` of the exported model into tmp/NAME, with EXTRA flags; (folder, stdout).
    let import_colmap = |name: &str, extra: &[&str]| {
        let out = tmp.path().join(name);
        let (model, images) = (synth.join("colmap/sparse/0"), synth.join("image"));
        let mut args = vec!["import", "colmap", model.to_str().unwrap()];
        args.extend(["--images", images.to_str().unwrap()]);
        args.extend_from_slice(extra);
        args.extend(["--out", out.to_str().unwrap()]);
        let stdout = run(&args);
        (out, stdout)
    };
    let mask_dir = synth.join("mask");
    let (a, stdout) = import_colmap(
        "a",
        &[
            "--masks",
            mask_dir.to_str().unwrap(),
            "--roi-from",
            "points",
        ],
    );
    assert!(stdout.contains("region of interest"), "{stdout}");
    let sa = load(&a);
    // Override the ROI of the transforms import with the one the COLMAP import chose.
    let [x, y, z] = sa.normalization.center;
    let radius = sa.normalization.scale;
    let b = tmp.path().join("b");
    run(&[
        "import",
        "transforms",
        synth.join("transforms.json").to_str().unwrap(),
        "--roi-center",
        &format!("{x},{y},{z}"),
        "--roi-radius",
        &radius.to_string(),
        "--out",
        b.to_str().unwrap(),
    ]);
    let sb = load(&b);
    assert!(sa.views.iter().all(|v| v.mask.is_some()));
    assert!(camera_difference(&world_cameras(&sa), &truth) < 1e-9);
    assert!(camera_difference(&world_cameras(&sb), &truth) < 1e-9);
    assert_eq!(sb.normalization, sa.normalization);
    let inspect = run(&["inspect", a.to_str().unwrap()]);
    assert!(
        inspect.contains("imported     from colmap-text") && inspect.contains("sparse points"),
        "{inspect}"
    );
    // `--roi-from cameras`: the camera-layout region, the one the transforms importer chooses
    // from the same cameras by default (and not the sparse points' one).
    let (c, _) = import_colmap("c", &["--roi-from", "cameras"]);
    let d = tmp.path().join("d");
    run(&[
        "import",
        "transforms",
        synth.join("transforms.json").to_str().unwrap(),
        "--out",
        d.to_str().unwrap(),
    ]);
    let (nc, nd) = (load(&c).normalization, load(&d).normalization);
    let centre_gap = (Vector3::from(nc.center) - Vector3::from(nd.center)).norm();
    assert!(
        (nc.scale - nd.scale).abs() <= 1e-9 * nd.scale && centre_gap <= 1e-9 * nd.scale,
        "colmap --roi-from cameras {nc:?} against transforms {nd:?}"
    );
    assert!(
        (nc.scale - sa.normalization.scale).abs() > 1e-3 * nc.scale,
        "the camera-layout region equals the sparse points' one: {nc:?}"
    );
    let inspect = run(&["inspect", c.to_str().unwrap()]);
    assert!(
        inspect.contains("from the layout of 6 cameras"),
        "{inspect}"
    );
    // The default, `--roi-from auto`: the simulator's rig orbits the object, so the centre is
    // the camera layout's, and the radius at most its.
    let (e, _) = import_colmap("e", &[]);
    let ne = load(&e).normalization;
    let centre_gap = (Vector3::from(ne.center) - Vector3::from(nc.center)).norm();
    assert!(
        centre_gap <= 1e-9 * nc.scale && ne.scale <= nc.scale * (1.0 + 1e-12),
        "auto {ne:?} against cameras {nc:?}"
    );
    let inspect = run(&["inspect", e.to_str().unwrap()]);
    assert!(inspect.contains("auto, an orbit of 6 cameras"), "{inspect}");
    // A bad flag value is refused with its name.
    let out = common::tiny::neus_aug()
        .args([
            "import",
            "transforms",
            "x.json",
            "--roi-center",
            "1,2",
            "--roi-radius",
            "1",
        ])
        .args(["--out", b.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("x,y,z"));
}
