//! The DTU protocol end to end on synthetic ground truth, plain mode against brute force, and
//! every kind of bad input.

mod common;

use common::*;
use dtu_eval::cli::{run, EvalArgs};
use dtu_eval::error::error_chain;
use dtu_eval::nn::nearest_distances_brute;
use dtu_eval::protocol::{evaluate_mesh, GroundTruth};
use dtu_eval::report::{Details, DtuParams, Report};
use dtu_eval::{EvalError, TriMesh};
use std::path::{Path, PathBuf};

const SCAN: u32 = 7;

/// The error of a failed evaluation with its whole `source()` chain.
trait ErrText {
    fn err_text(self) -> String;
}

impl<T: std::fmt::Debug> ErrText for Result<T, EvalError> {
    fn err_text(self) -> String {
        error_chain(&self.expect_err("expected an error"))
    }
}

fn args(mesh: &Path) -> EvalArgs {
    EvalArgs::new(mesh)
}

#[test]
fn eval_args_new_has_the_protocol_defaults() {
    let a = EvalArgs::new("m.ply");
    assert_eq!(a.mesh, Path::new("m.ply"));
    assert_eq!(
        (a.density, a.patch_size, a.vis_threshold),
        (0.2, 60.0, 10.0)
    );
    assert_eq!(a.max_samples, dtu_eval::protocol::DEFAULT_MAX_SAMPLES);
    assert!(a.scan.is_none() && a.reference.is_none() && a.max_dist.is_none());
    assert_eq!(a.seed, 0);
}

fn dtu_args(mesh: &Path, root: &Path) -> EvalArgs {
    EvalArgs {
        scan: Some(SCAN),
        gt_root: Some(root.into()),
        ..args(mesh)
    }
}

fn write_mesh(dir: &Path, name: &str, m: &TriMesh) -> PathBuf {
    let p = dir.join(name);
    dtu_eval::ply::write_mesh(&p, m).unwrap();
    p
}

#[test]
fn sphere_offset_by_half_a_millimetre_scores_half_a_millimetre() {
    let dir = tempfile::tempdir().unwrap();
    write_gt(dir.path(), SCAN, 200_000);
    let mesh = write_mesh(dir.path(), "m.ply", &test_mesh(0.5, 80, 160));
    let a = EvalArgs {
        json: Some(dir.path().join("r.json")),
        ..dtu_args(&mesh, dir.path())
    };
    let r = run(&a).unwrap();
    // GT spacing ~0.1 mm, so nearest GT distances are within a few µm of the 0.5 mm offset;
    // GT -> mesh also sees the 0.2 mm spacing of the downsampled mesh points.
    assert!((r.mean_d2s - 0.5).abs() < 0.01, "{}", r.summary());
    assert!(r.mean_s2d > 0.49 && r.mean_s2d < 0.56, "{}", r.summary());
    assert_eq!(r.overall, (r.mean_d2s + r.mean_s2d) / 2.0);
    assert_eq!(r.chamfer_sum, r.mean_d2s + r.mean_s2d);
    let Details::Dtu { counts: c, .. } = &r.details else {
        panic!("not a DTU report")
    };
    assert!(c.sampled > c.downsampled && c.downsampled > c.in_box);
    assert!(c.in_box > c.in_obs && c.in_obs > 0, "{c:?}");
    assert!(c.gt_points > c.gt_above_plane && c.gt_above_plane > 0);
    // The far floater is outside the box; everything observed is near the GT sphere.
    assert_eq!(c.d2s_below_max, c.in_obs);
    assert_eq!(c.s2d_below_max, c.gt_above_plane);
    // The JSON written is the report returned.
    let text = std::fs::read_to_string(dir.path().join("r.json")).unwrap();
    let back: Report = serde_json::from_str(&text).unwrap();
    assert_eq!(back, r);
    for key in [
        "\"mean_d2s\"",
        "\"mean_s2d\"",
        "\"overall\"",
        "\"chamfer_sum\"",
        "\"mode\": \"dtu\"",
    ] {
        assert!(text.contains(key), "{key} missing from {text}");
    }
}

#[test]
fn mesh_points_as_ground_truth_give_zero_accuracy_and_completeness_below_the_radius() {
    // GT = the mesh's own samples: every downsampled point is a GT point (d2s = 0 exactly), and
    // every GT point lies within the downsampling radius of a kept point (s2d <= 0.2).
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    write_gt(root, SCAN, 1000);
    let mesh = uv_sphere(CENTRE, RADIUS, 40, 80);
    let samples = dtu_eval::sample::sample_mesh(&mesh, 0.2);
    let paths = dtu_eval::gt::GtPaths::new(root, SCAN);
    dtu_eval::ply::write_points(&paths.points, &samples, None).unwrap();
    let gt = GroundTruth::load(root, SCAN).unwrap();
    let e = evaluate_mesh(&mesh, &gt, &DtuParams::default(), 3).unwrap();
    assert_eq!(e.mean_d2s, 0.0);
    assert!(e.d2s.iter().all(|&d| d == 0.0));
    let worst = e.s2d.iter().copied().fold(0.0, f64::max);
    assert!(worst <= 0.2 && worst > 0.05, "worst s2d {worst}");
    assert!(e.mean_s2d > 0.0 && e.mean_s2d < 0.2);
}

/// The mean of the distances `< max` in order, as the protocol's step 6 sums them.
fn mean_in_order(d: &[f64], max: f64) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0u64);
    for &v in d {
        if v < max {
            sum += v;
            n += 1;
        }
    }
    sum / n as f64
}

#[test]
fn distances_beyond_max_dist_are_not_searched_and_the_rest_equal_brute_force() {
    // A sphere 4 mm off the ground truth with a 2.5 mm cut: many distances on either side of it.
    let dir = tempfile::tempdir().unwrap();
    write_gt(dir.path(), SCAN, 8000);
    let gt = GroundTruth::load(dir.path(), SCAN).unwrap();
    let c = [CENTRE[0] + 4.0, CENTRE[1], CENTRE[2]];
    let mesh = uv_sphere(c, RADIUS, 30, 60);
    let params = DtuParams {
        max_dist: 2.5,
        ..DtuParams::default()
    };
    let mut e = evaluate_mesh(&mesh, &gt, &params, 0).unwrap();
    let data_in = dtu_eval::downsample::select(&e.data_down, &e.in_box);
    let data_in_obs = dtu_eval::downsample::select(&e.data_down, &e.in_obs);
    let gt_above = dtu_eval::downsample::select(&gt.points, &e.above);
    let d2s = nearest_distances_brute(&gt.points, &data_in_obs);
    let s2d = nearest_distances_brute(&data_in, &gt_above);
    for (name, fast, brute) in [("d2s", &e.d2s, &d2s), ("s2d", &e.s2d, &s2d)] {
        assert_eq!(fast.len(), brute.len(), "{name}");
        let beyond = brute.iter().filter(|&&d| d >= params.max_dist).count();
        assert!(
            beyond > brute.len() / 10 && beyond < brute.len() * 9 / 10,
            "{name}: {beyond} of {} beyond the cut",
            brute.len()
        );
        for (i, (&f, &b)) in fast.iter().zip(brute).enumerate() {
            if b < params.max_dist {
                assert_eq!(f, b, "{name}[{i}]: below the cut, the exact distance");
            } else {
                assert_eq!(
                    f,
                    f64::INFINITY,
                    "{name}[{i}] = {b}: beyond the cut, not searched"
                );
            }
        }
    }
    assert_eq!(e.mean_d2s, mean_in_order(&d2s, params.max_dist));
    assert_eq!(e.mean_s2d, mean_in_order(&s2d, params.max_dist));
    // Filled in on request (what --dump-dir writes): every distance, exact.
    e.exact_outliers(&gt).unwrap();
    assert_eq!(e.d2s, d2s);
    assert_eq!(e.s2d, s2d);
}

#[test]
fn same_seed_same_figures_other_seed_close_figures() {
    let dir = tempfile::tempdir().unwrap();
    write_gt(dir.path(), SCAN, 50_000);
    let mesh = test_mesh(0.3, 40, 80);
    let gt = GroundTruth::load(dir.path(), SCAN).unwrap();
    let p = DtuParams::default();
    let a = evaluate_mesh(&mesh, &gt, &p, 1).unwrap();
    let b = evaluate_mesh(&mesh, &gt, &p, 1).unwrap();
    assert_eq!(
        (a.mean_d2s, a.mean_s2d, &a.counts),
        (b.mean_d2s, b.mean_s2d, &b.counts)
    );
    assert_eq!(a.data_down, b.data_down);
    let c = evaluate_mesh(&mesh, &gt, &p, 2).unwrap();
    assert_ne!(a.data_down, c.data_down);
    assert!((a.mean_d2s - c.mean_d2s).abs() < 0.01 * a.mean_d2s);
}

#[test]
fn plain_mode_equals_brute_force() {
    use rand::{Rng, SeedableRng};
    let dir = tempfile::tempdir().unwrap();
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(9);
    let mut cloud = |n: usize, off: f32| -> Vec<[f32; 3]> {
        (0..n)
            .map(|_| std::array::from_fn(|k| 300.0 * k as f32 + off + 10.0 * rng.random::<f32>()))
            .collect()
    };
    let a = cloud(3000, 0.0);
    let b = cloud(2500, 2.0);
    let pa = dir.path().join("a.ply");
    let pb = dir.path().join("b.ply");
    dtu_eval::ply::write_points(&pa, &a, None).unwrap();
    dtu_eval::ply::write_points(&pb, &b, None).unwrap();
    let base = EvalArgs {
        reference: Some(pb.clone()),
        ..args(&pa)
    };
    let mean = |v: &[f64], max: f64| {
        let s: Vec<f64> = v.iter().copied().filter(|&d| d < max).collect();
        s.iter().sum::<f64>() / s.len() as f64
    };
    let d2s = nearest_distances_brute(&b, &a);
    let s2d = nearest_distances_brute(&a, &b);
    let r = run(&base).unwrap();
    assert_eq!(r.mean_d2s, mean(&d2s, f64::INFINITY));
    assert_eq!(r.mean_s2d, mean(&s2d, f64::INFINITY));
    let r = run(&EvalArgs {
        max_dist: Some(2.5),
        ..base.clone()
    })
    .unwrap();
    assert_eq!(r.mean_d2s, mean(&d2s, 2.5));
    assert_eq!(r.mean_s2d, mean(&s2d, 2.5));
    let Details::Plain { counts, .. } = &r.details else {
        panic!()
    };
    assert_eq!(
        counts.d2s_below_max,
        d2s.iter().filter(|&&d| d < 2.5).count() as u64
    );
    assert!(counts.d2s_below_max < 3000);
    // Downsampling both sets thins them and changes the figures only a little.
    let r2 = run(&EvalArgs {
        downsample: Some(0.5),
        ..base
    })
    .unwrap();
    let Details::Plain { counts, .. } = &r2.details else {
        panic!()
    };
    assert!(
        counts.data_used < 3000 && counts.ref_used < 2500,
        "{counts:?}"
    );
}

#[test]
fn vis_clouds_have_one_colour_per_point() {
    let dir = tempfile::tempdir().unwrap();
    write_gt(dir.path(), SCAN, 20_000);
    let mesh = write_mesh(dir.path(), "m.ply", &test_mesh(0.5, 30, 60));
    let vis = dir.path().join("vis");
    let r = run(&EvalArgs {
        vis_dir: Some(vis.clone()),
        ..dtu_args(&mesh, dir.path())
    })
    .unwrap();
    let Details::Dtu { counts, .. } = &r.details else {
        panic!()
    };
    let d2s = dtu_eval::ply::read_points(&vis.join("vis_007_d2s.ply")).unwrap();
    let s2d = dtu_eval::ply::read_points(&vis.join("vis_007_s2d.ply")).unwrap();
    assert_eq!(d2s.len() as u64, counts.downsampled);
    assert_eq!(s2d.len() as u64, counts.gt_points);
    let header = std::fs::read(vis.join("vis_007_d2s.ply")).unwrap();
    assert!(String::from_utf8_lossy(&header[..300]).contains("property uchar red"));
}

// ---- bad input: each a test -------------------------------------------------------------

fn dtu_error(mesh: &TriMesh) -> String {
    let dir = tempfile::tempdir().unwrap();
    write_gt(dir.path(), SCAN, 5000);
    let p = write_mesh(dir.path(), "bad.ply", mesh);
    run(&dtu_args(&p, dir.path())).err_text()
}

#[test]
fn empty_mesh_is_an_error() {
    let e = dtu_error(&TriMesh::default());
    assert!(e.contains("bad.ply") && e.contains("no vertices"), "{e}");
}

#[test]
fn nan_vertex_is_an_error_naming_the_vertex() {
    let mut m = uv_sphere(CENTRE, RADIUS, 8, 16);
    m.vertices[5][1] = f32::NAN;
    let e = dtu_error(&m);
    assert!(e.contains("bad.ply") && e.contains("vertex 5"), "{e}");
}

#[test]
fn face_past_the_vertices_is_an_error_naming_the_face() {
    let mut m = uv_sphere(CENTRE, RADIUS, 8, 16);
    let n = m.vertices.len() as u32;
    m.faces[3] = [0, 1, n + 10];
    let e = dtu_error(&m);
    assert!(
        e.contains("face 3") && e.contains(&format!("vertex {}", n + 10)),
        "{e}"
    );
    // The library entry point checks meshes it is handed directly, too.
    let dir = tempfile::tempdir().unwrap();
    write_gt(dir.path(), SCAN, 1000);
    let gt = GroundTruth::load(dir.path(), SCAN).unwrap();
    let err = evaluate_mesh(&m, &gt, &DtuParams::default(), 0).unwrap_err();
    assert!(matches!(err, EvalError::BadMesh { .. }), "{err}");
}

#[test]
fn missing_ground_truth_files_are_all_named() {
    let dir = tempfile::tempdir().unwrap();
    write_gt(dir.path(), SCAN, 1000);
    let paths = dtu_eval::gt::GtPaths::new(dir.path(), SCAN);
    std::fs::remove_file(&paths.points).unwrap();
    std::fs::remove_file(&paths.plane).unwrap();
    let mesh = write_mesh(dir.path(), "m.ply", &test_mesh(0.5, 8, 16));
    let e = run(&dtu_args(&mesh, dir.path())).err_text();
    assert!(
        e.contains("stl007_total.ply") && e.contains("Plane7.mat"),
        "{e}"
    );
    assert!(
        !e.contains("missing ObsMask") && e.contains("scan 7"),
        "{e}"
    );
    // A wrong root entirely.
    let e = run(&dtu_args(&mesh, &dir.path().join("nowhere"))).err_text();
    assert!(
        e.contains("nowhere") && e.contains("ObsMask7_10.mat"),
        "{e}"
    );
}

#[test]
fn mesh_in_normalised_space_points_to_scale_mat() {
    // The same sphere as NeuS would extract it before mapping back: radius ~0.8 at the origin.
    let e = dtu_error(&uv_sphere([0.0, 0.1, -0.05], 0.8, 30, 60));
    assert!(e.contains("normalised") && e.contains("scale_mat"), "{e}");
    assert!(e.contains("X_world = s·X_norm + c"), "{e}");
}

#[test]
fn world_scale_mesh_far_from_the_box_is_told_to_check_the_frame() {
    let far = [CENTRE[0] + 800.0, CENTRE[1], CENTRE[2]];
    let e = dtu_error(&uv_sphere(far, 50.0, 30, 60));
    assert!(e.contains("same scan") && !e.contains("scale_mat"), "{e}");
}

#[test]
fn mesh_only_in_unobserved_space_is_an_error() {
    // Below the observed half of the box (but inside the box and its patch).
    let low = [CENTRE[0], CENTRE[1], CENTRE[2] - RADIUS];
    let e = dtu_error(&uv_sphere(low, 2.0, 20, 40));
    assert!(e.contains("observed voxel"), "{e}");
}

#[test]
fn sets_farther_apart_than_max_dist_are_an_error_not_nan() {
    let dir = tempfile::tempdir().unwrap();
    let pa = dir.path().join("a.ply");
    let pb = dir.path().join("b.ply");
    dtu_eval::ply::write_points(&pa, &[[0.0; 3], [1.0, 0.0, 0.0]], None).unwrap();
    dtu_eval::ply::write_points(&pb, &[[0.0, 0.0, 50.0]], None).unwrap();
    let e = run(&EvalArgs {
        reference: Some(pb),
        max_dist: Some(20.0),
        ..args(&pa)
    })
    .err_text();
    assert!(
        e.contains("max_dist = 20") && e.contains("smallest 50.000"),
        "{e}"
    );
}

#[test]
fn bad_parameters_and_argument_mixes_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    write_gt(dir.path(), SCAN, 1000);
    let mesh = write_mesh(dir.path(), "m.ply", &test_mesh(0.5, 8, 16));
    let e = run(&EvalArgs {
        density: 0.0,
        ..dtu_args(&mesh, dir.path())
    })
    .err_text();
    assert!(e.contains("density = 0"), "{e}");
    let e = run(&EvalArgs {
        max_dist: Some(f64::NAN),
        ..dtu_args(&mesh, dir.path())
    })
    .err_text();
    assert!(e.contains("max_dist"), "{e}");
    let e = run(&EvalArgs {
        reference: Some(mesh.clone()),
        ..dtu_args(&mesh, dir.path())
    })
    .err_text();
    assert!(e.contains("--ref"), "{e}");
    let e = run(&args(&mesh)).err_text();
    assert!(e.contains("--scan"), "{e}");
    // A mesh scaled to metres-as-micrometres would explode the sample count.
    let mut huge = test_mesh(0.5, 8, 16);
    huge.scale_translate(1000.0, [0.0; 3]);
    let p = write_mesh(dir.path(), "huge.ply", &huge);
    let e = run(&EvalArgs {
        max_samples: 1_000_000,
        ..dtu_args(&p, dir.path())
    })
    .err_text();
    assert!(e.contains("wrong unit"), "{e}");
}

#[test]
fn binary_fails_with_a_message_and_nonzero_status() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = write_mesh(dir.path(), "m.ply", &test_mesh(0.5, 8, 16));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_dtu-eval"))
        .args([
            "--mesh",
            mesh.to_str().unwrap(),
            "--scan",
            "24",
            "--gt-root",
        ])
        .arg(dir.path().join("no_gt"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no_gt") && err.contains("stl024_total.ply"),
        "{err}"
    );
}

// ---- stage semantics on hand-made points -------------------------------------------------

#[test]
fn observation_filter_rounds_half_to_even_and_bounds_the_box_as_dtu() {
    use dtu_eval::protocol::observation_filter;
    let (in_box, in_obs) = observation_filter(&probe_vertices(), &obs_mask(), 60.0);
    assert_eq!(in_box, [true, true, true, true, true, false, true]);
    assert_eq!(in_obs, [true, true, false, true, false, false, false]);
}

#[test]
fn plane_and_outlier_cut_are_strict() {
    use dtu_eval::gt::Plane;
    use dtu_eval::protocol::{above_plane, mean_below};
    // z > 2 is above.
    let p = Plane([0.0, 0.0, 1.0, -2.0]);
    let pts = [[0.0, 0.0, 2.0], [5.0, 5.0, 2.5], [0.0, 0.0, -1.0]];
    assert_eq!(above_plane(&pts, &p), [false, true, false]);
    let (m, n) = mean_below(&[1.0, 20.0, 3.0, 25.0], 20.0, "test").unwrap();
    assert_eq!((m, n), (2.0, 2));
    assert!(mean_below(&[20.0], 20.0, "test").is_err());
}
