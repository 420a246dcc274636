//! The tiny version of the round trip through the real COLMAP, small enough for CI:
//! `scripts/colmap_roundtrip.sh` on 16 views of the built-in `blob` (400×300, four samples per
//! pixel) with the true intrinsics held fixed, COLMAP's CPU SIFT, exhaustive matching and mapper,
//! `import colmap` of the binary and the text model (the script refuses if they differ; the
//! region of interest is the importer's default, `--roi-from auto`), a
//! 300-step reconstruction of the COLMAP-posed and of the true-camera scene, the Umeyama
//! similarity of the camera centres back into the true frame, and the DTU Chamfer of both.
//!
//! It fails when COLMAP registers too few views, when the imported cameras disagree with the true
//! ones beyond a similarity (a convention slip in the importer moves the centres by tens of mm),
//! or when the COLMAP-posed mesh scores worse than 1.3× the true-camera one (aligned by the whole
//! poses; 2× aligned by the centres alone, which COLMAP's run-to-run noise moves more). The
//! full-size run is the script itself (README, "Round trip through the real COLMAP").
//!
//! Needs `colmap` on PATH: the script installs Debian's package when run as root (`.ci/run` does
//! it up front); otherwise it stops, naming the package, and this test fails with its message.
//! Cost on 2 cores: about 15 s in all (COLMAP and both reconstructions; CI run of 2026-11-28).

use std::path::Path;
use std::process::Command;

/// A reconstruction of 300 steps on a small hash grid: coarse, but enough for a camera error to
/// show in the Chamfer distance (true cameras give 1.8 mm on this scene at four samples per pixel,
/// floor 0.5 mm).
const TINY_CONFIG: &str = r#"
preset = "fast"
[data]
holdout = 1
render_downscale = 2
[train]
iterations = 300
checkpoint_every = 1000
[train.lr]
warmup_steps = 0
constant_steps = 150
[model.field.hash_grid]
n_levels = 8
log2_hashmap_size = 14
base_resolution = 8.0
per_level_scale = 1.5
[model.render]
num_samples_per_ray = 64
train_num_rays = 256
max_train_num_rays = 1024
shards = 2
cos_anneal_end = 300
[model.render.occupancy]
resolution = 32
[mesh]
coarse_res = 32
fine_res = 64
"#;

fn number(summary: &serde_json::Value, key: &str) -> f64 {
    summary[key]
        .as_f64()
        .unwrap_or_else(|| panic!("summary has no number '{key}': {summary}"))
}

#[test]
fn colmap_round_trip_on_a_tiny_scene_stays_within_the_bound() {
    let tmp = tempfile::tempdir().unwrap();
    let config = tmp.path().join("tiny.toml");
    std::fs::write(&config, TINY_CONFIG).unwrap();
    let work = tmp.path().join("rt");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/colmap_roundtrip.sh");
    let out = Command::new("bash")
        .arg(&script)
        .arg(&work)
        // Four samples per pixel: COLMAP's cameras land closer on antialiased images (centre
        // residual 2.1–2.6 mm rms against 2.5–3.0 with one); with one, the poses ratio below
        // reached 1.32 (see there).
        .args(["--views", "16", "--spp", "4", "--gt-spacing", "1.0"])
        .args(["--intrinsics", "known"])
        // The script's own bound is on the centres alignment; see the ratio checks below.
        .args(["--bound", "2.0"])
        .arg("--config")
        .arg(&config)
        .env("NEUS_AUG", env!("CARGO_BIN_EXE_neus-aug"))
        .env("RAYON_NUM_THREADS", "2")
        .output()
        .expect("bash runs the round-trip script");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.code() == Some(0),
        "the round trip failed or exceeded its bound (exit {:?}):\n{text}",
        out.status.code()
    );
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(work.join("summary-known-auto.json"))
            .unwrap_or_else(|e| panic!("no summary ({e}):\n{text}")),
    )
    .unwrap();
    eprintln!("round-trip summary: {summary}");
    assert_eq!(summary["views"], 16, "{summary}");
    assert!(
        number(&summary, "registered") >= 14.0,
        "COLMAP registered too few views: {summary}"
    );
    // The true K was held fixed, so the imported focal length is the true one.
    let (fc, ft) = (number(&summary, "fx_colmap"), number(&summary, "fx_true"));
    assert!((fc / ft - 1.0).abs() < 1e-6, "{summary}");
    // Cameras ~550 mm from the object, 0.5 px reprojection error: a few mm of centre residual
    // after the similarity (2.8 mm rms when this test was written); a wrong axis or a transposed
    // rotation in the importer gives tens to hundreds.
    assert!(
        number(&summary, "centre_residual_rms_mm") < 8.0,
        "COLMAP's cameras are not the true ones up to a similarity: {summary}"
    );
    // The default region of interest holds the whole object (the points' sphere left 48 % of
    // this scene's true surface outside).
    let outside = number(&summary, "gt_outside_roi");
    assert!(
        outside < 0.01,
        "{:.1} % of the true surface lies outside the imported region of interest: {summary}",
        100.0 * outside
    );
    // Both meshes must be real reconstructions, not two equally bad ones.
    let true_mm = number(&summary, "chamfer_true_mm");
    assert!(
        true_mm.is_finite() && true_mm < 4.0,
        "the true-camera run failed: {summary}"
    );
    // COLMAP's poses change from run to run on the same images: in its `util/random.h` a
    // thread whose generator is unset seeds it with `SetPRNGSeed()`'s default, a random seed,
    // whatever `--random_seed` says (and one thread per stage did not make the runs repeat).
    // This tiny scene's 300 steps turn that into Chamfer noise, and the better the recipe makes
    // the true-camera run, the larger the share COLMAP's pose error takes of the ratio. Runs on
    // one machine, the true-camera run fixed (it is deterministic: 1.610 mm here and in CI), only
    // COLMAP and the COLMAP-posed run repeated (2026-11-28, AMD EPYC Zen 5):
    // - one sample per pixel: poses ratio 1.13–1.27 over 7 runs, 1.32 in a CI run (failed);
    //   centres ratio 1.16–1.42;
    // - four samples per pixel (what this test runs; true cameras 1.795 mm): poses ratio
    //   0.955–1.126 over 16 runs, centres ratio 1.215–1.682;
    // - 800×600 or 24 views did worse (poses ratio 1.15–1.35 and 1.23–1.43)
    //   (`results/colmap/tiny-noise-2026-11-28`).
    // The bound, 1.3, is judged on the poses ratio, which uses the viewing directions
    // too. The centres ratio, the issue's own definition and the full-size run's (README), swings
    // with the rotation a shallow cap of 16 centres pins poorly (in one run here the centres
    // fit turned 0.18° from the poses fit: 1.5 mm at the object's 490 mm); an importer slip
    // moves the centres by tens of mm and fails the residual check above, so the centres ratio
    // only has to stay below 2.
    let (ratio, ratio_poses) = (number(&summary, "ratio"), number(&summary, "ratio_poses"));
    assert!(
        ratio_poses.is_finite() && ratio_poses <= 1.3,
        "COLMAP / true Chamfer, aligned by the poses, {ratio_poses} > 1.3: {summary}"
    );
    assert!(
        ratio.is_finite() && ratio <= 2.0,
        "COLMAP / true Chamfer, aligned by the centres, {ratio} > 2: {summary}"
    );
    assert_eq!(summary["within_bound"], true, "{summary}");
    // The points fit maps COLMAP's sparse points onto the same tracks triangulated with the
    // true cameras: with the true K held fixed the two structures differ by COLMAP's
    // reprojection error (a fraction of a pixel, well under a millimetre at ~500 mm), and
    // aligned by it the mesh is judged on its shape rather than on the cameras' layout.
    let (points_res, ratio_points) = (
        number(&summary, "points_residual_median_mm"),
        number(&summary, "ratio_points"),
    );
    assert!(
        points_res.is_finite() && points_res < 1.0,
        "COLMAP's sparse points are not the true cameras' up to a similarity: {summary}"
    );
    assert!(
        ratio_points.is_finite() && ratio_points <= 1.3,
        "COLMAP / true Chamfer, aligned by the sparse points, {ratio_points} > 1.3: {summary}"
    );

    // COLMAP is installed now (the script saw to it): check the importer's undistortion against
    // COLMAP's own undistorter on the same distorted image.
    undistortion_matches_colmaps_image_undistorter(tmp.path());
}

/// `colmap image_undistorter` on a textured 160×120 image of an OPENCV camera, then
/// `neus_aug::import::undistort::undistort_rgb` of the same image into the PINHOLE camera COLMAP
/// chose: the two must agree to within interpolation error, and far better than the distorted
/// image itself does (so the check would catch a wrong sign or a swapped coefficient).
fn undistortion_matches_colmaps_image_undistorter(tmp: &Path) {
    use neus_aug::import::{colmap, undistort, Distortion};
    use neus_aug::scene::RgbImage;
    let dir = tmp.join("undistort");
    let (images, model, out) = (dir.join("images"), dir.join("model"), dir.join("out"));
    for d in [&images, &model] {
        std::fs::create_dir_all(d).unwrap();
    }
    let (w, h) = (160usize, 120usize);
    let mut src = RgbImage::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f32 / 9.0, y as f32 / 7.0);
            let p = (y * w + x) * 3;
            src.data[p] = 0.5 + 0.4 * fx.sin() * fy.cos();
            src.data[p + 1] = 0.5 + 0.4 * (0.7 * fx + 0.3 * fy).sin();
            src.data[p + 2] = 0.5 + 0.4 * (0.2 * fx - 0.9 * fy).cos();
        }
    }
    src.save(&images.join("img.png")).unwrap();
    let dist = Distortion {
        k1: -0.18,
        k2: 0.03,
        p1: 0.002,
        p2: -0.001,
    };
    let (f, fy, cx, cy) = (150.0, 152.0, 80.5, 59.5);
    std::fs::write(
        model.join("cameras.txt"),
        format!(
            "1 OPENCV {w} {h} {f} {fy} {cx} {cy} {} {} {} {}\n",
            dist.k1, dist.k2, dist.p1, dist.p2
        ),
    )
    .unwrap();
    std::fs::write(model.join("images.txt"), "1 1 0 0 0 0 0 0 1 img.png\n\n").unwrap();
    std::fs::write(model.join("points3D.txt"), "").unwrap();
    let run = Command::new("colmap")
        .arg("image_undistorter")
        .arg("--image_path")
        .arg(&images)
        .arg("--input_path")
        .arg(&model)
        .arg("--output_path")
        .arg(&out)
        .args(["--output_type", "COLMAP"])
        .env("QT_QPA_PLATFORM", "offscreen")
        .output()
        .expect("colmap runs");
    assert!(
        run.status.success(),
        "colmap image_undistorter failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let (undist_model, _) = colmap::read_model(&out.join("sparse")).unwrap();
    let cam = undist_model.cameras.values().next().unwrap();
    assert_eq!(cam.model, "PINHOLE", "{cam:?}");
    let (k_dst, d) = colmap::intrinsics(cam, Path::new("cameras")).unwrap();
    assert!(d.is_zero());
    let theirs = RgbImage::load(&out.join("images/img.png")).unwrap();
    let k_src = nalgebra::Matrix3::new(f, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0);
    let (wd, hd) = (cam.width as usize, cam.height as usize);
    let ours = undistort::undistort_rgb(&src, &k_src, &dist, &k_dst, wd, hd);
    let plain = undistort::undistort_rgb(&src, &k_src, &Distortion::default(), &k_dst, wd, hd);
    // Mean absolute difference over interior pixels both images filled.
    let mad = |a: &RgbImage| {
        let (mut sum, mut n) = (0.0f64, 0usize);
        for y in 3..hd - 3 {
            for x in 3..wd - 3 {
                let (p, q) = (a.get(x, y), theirs.get(x, y));
                if p.iter().chain(&q).all(|&v| v > 0.02) {
                    sum += (0..3).map(|c| (p[c] - q[c]).abs() as f64).sum::<f64>() / 3.0;
                    n += 1;
                }
            }
        }
        assert!(n > wd * hd / 2, "too few comparable pixels: {n}");
        sum / n as f64
    };
    let (ours_mad, plain_mad) = (mad(&ours), mad(&plain));
    eprintln!(
        "undistortion against colmap image_undistorter ({wd}x{hd}): mean |diff| {ours_mad:.4}, \
         without undistorting {plain_mad:.4}"
    );
    assert!(ours_mad < 0.01, "ours {ours_mad}, plain {plain_mad}");
    assert!(
        plain_mad > 5.0 * ours_mad,
        "ours {ours_mad}, plain {plain_mad}"
    );
}
