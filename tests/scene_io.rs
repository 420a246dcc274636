//! The DTU-layout loader: round trip of cameras through `cameras_sphere.npz`, pixel-centre rays,
//! and a clear error for each kind of bad input.

mod common;

use common::{test_normalization, write_random_scene};
use nalgebra::Vector3;
use neus_aug::scene::{npz, LoadOptions, Scene, SceneError};
use rand::{Rng, SeedableRng};
use std::path::Path;

fn load(dir: &Path) -> Result<Scene, SceneError> {
    Scene::load(dir, &LoadOptions::default())
}

#[test]
fn cameras_round_trip_through_npz_with_a_non_trivial_scale_mat() {
    let dir = tempfile::tempdir().unwrap();
    let world = write_random_scene(dir.path(), 12, 2024, 64, 48);
    let scene = load(dir.path()).unwrap();
    assert_eq!(scene.views.len(), 12);
    assert_eq!(scene.normalization, test_normalization());
    assert!(scene.scale_mats_consistent);
    let norm = scene.normalization;
    let c = Vector3::from(norm.center);
    let mut worst = 0.0_f64;
    let mut failures = Vec::new();
    for (view, cam) in scene.views.iter().zip(&world) {
        let expect = cam.normalized(norm.scale, &c);
        let got = &view.camera;
        let k_err = (got.k - expect.k).abs().max() / expect.k.abs().max();
        let r_err = (got.r - expect.r).abs().max();
        let c_err = (got.center - expect.center).norm() / expect.center.norm();
        let e = k_err.max(r_err).max(c_err);
        worst = worst.max(e);
        if e > 1e-9 {
            failures.push(format!(
                "view {}: K {k_err:e}, R {r_err:e}, C {c_err:e}",
                view.index
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "relative errors above 1e-9:\n{}",
        failures.join("\n")
    );
    assert!(worst < 1e-9);

    // A ray through a pixel centre, in normalised space, projects back onto that pixel; the same
    // ray mapped to world mm projects through the original world camera onto the same pixel.
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
    for (view, cam) in scene.views.iter().zip(&world) {
        for _ in 0..20 {
            let (x, y) = (rng.random_range(0..64), rng.random_range(0..48));
            let (u, v) = (x as f64 + 0.5, y as f64 + 0.5);
            let (o, d) = view.camera.ray(u, v);
            let p = o + d * rng.random_range(0.5..4.0);
            let (pu, pv, _) = view.camera.project(&p).unwrap();
            assert!((pu - u).abs() < 1e-6 && (pv - v).abs() < 1e-6);
            let pw = Vector3::from(norm.to_world([p.x, p.y, p.z]));
            let (wu, wv, _) = cam.project(&pw).unwrap();
            assert!(
                (wu - u).abs() < 1e-6 && (wv - v).abs() < 1e-6,
                "{wu},{wv} vs {u},{v}"
            );
        }
    }
}

#[test]
fn images_sort_numerically_whatever_the_padding() {
    let dir = tempfile::tempdir().unwrap();
    write_random_scene(dir.path(), 11, 1, 16, 12);
    // Rename 000000.png .. 000010.png to 0.png .. 10.png: lexicographic order would put 10 before 2.
    for i in 0..11 {
        std::fs::rename(
            dir.path().join(format!("image/{i:06}.png")),
            dir.path().join(format!("image/{i}.png")),
        )
        .unwrap();
    }
    let scene = load(dir.path()).unwrap();
    let names: Vec<String> = scene
        .views
        .iter()
        .map(|v| {
            v.image_path
                .file_name()
                .unwrap()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    assert_eq!(names[2], "2.png");
    assert_eq!(names[10], "10.png");
    // Image i's third channel encodes i % 7: the pairing of images and cameras follows the order.
    for v in &scene.views {
        let b = v.image.get(0, 0)[2];
        assert!((b - (v.index % 7) as f32 / 7.0).abs() < 1.0 / 255.0);
    }
}

#[test]
fn downscaling_averages_pixels_and_scales_intrinsics() {
    let dir = tempfile::tempdir().unwrap();
    write_random_scene(dir.path(), 2, 3, 64, 48);
    let full = load(dir.path()).unwrap();
    let half = Scene::load(
        dir.path(),
        &LoadOptions {
            downscale: 4,
            masks: true,
        },
    )
    .unwrap();
    let (f, h) = (&full.views[0], &half.views[0]);
    assert_eq!((h.image.width, h.image.height), (16, 12));
    let mut mean = [0.0f32; 3];
    for dy in 0..4 {
        for dx in 0..4 {
            let p = f.image.get(4 * 3 + dx, 4 * 2 + dy);
            for c in 0..3 {
                mean[c] += p[c] / 16.0;
            }
        }
    }
    let got = h.image.get(3, 2);
    for c in 0..3 {
        assert!((got[c] - mean[c]).abs() < 1e-6);
    }
    assert!((h.camera.k[(0, 0)] * 4.0 - f.camera.k[(0, 0)]).abs() < 1e-9);
    assert!(Scene::load(
        dir.path(),
        &LoadOptions {
            downscale: 100,
            masks: true
        }
    )
    .is_err());
}

fn err_of(dir: &Path) -> String {
    let e = load(dir).expect_err("loading must fail");
    format!("{e}")
}

#[test]
fn missing_camera_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    write_random_scene(dir.path(), 2, 1, 16, 12);
    std::fs::remove_file(dir.path().join("cameras_sphere.npz")).unwrap();
    let e = err_of(dir.path());
    assert!(
        e.contains("cameras_sphere.npz") && e.contains("missing"),
        "{e}"
    );
}

#[test]
fn image_without_world_mat_names_the_key_and_the_image() {
    let dir = tempfile::tempdir().unwrap();
    write_random_scene(dir.path(), 3, 1, 16, 12);
    let path = dir.path().join("cameras_sphere.npz");
    let arrays = npz::read(&path).unwrap();
    let kept: Vec<_> = arrays
        .into_iter()
        .filter(|(k, _)| k != "world_mat_2")
        .map(|(k, a)| (k, a.shape, a.data))
        .collect();
    npz::write(&path, &kept).unwrap();
    let e = err_of(dir.path());
    assert!(
        e.contains("'world_mat_2'") && e.contains("000002.png"),
        "{e}"
    );
}

#[test]
fn mask_of_another_size_is_named() {
    let dir = tempfile::tempdir().unwrap();
    write_random_scene(dir.path(), 2, 1, 16, 12);
    neus_aug::scene::GrayImage::new(8, 8)
        .save(&dir.path().join("mask/001.png"))
        .unwrap();
    let e = err_of(dir.path());
    assert!(
        e.contains("001.png") && e.contains("8×8") && e.contains("16×12"),
        "{e}"
    );
}

#[test]
fn corrupt_png_is_named() {
    let dir = tempfile::tempdir().unwrap();
    write_random_scene(dir.path(), 2, 1, 16, 12);
    let p = dir.path().join("image/000001.png");
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    let e = err_of(dir.path());
    assert!(e.contains("000001.png"), "{e}");
}

fn replace_world_mat(dir: &Path, key: &str, f: impl Fn(&mut [f64])) {
    let path = dir.join("cameras_sphere.npz");
    let arrays = npz::read(&path).unwrap();
    let arrays: Vec<_> = arrays
        .into_iter()
        .map(|(k, mut a)| {
            if k == key {
                f(&mut a.data);
            }
            (k, a.shape, a.data)
        })
        .collect();
    npz::write(&path, &arrays).unwrap();
}

#[test]
fn singular_projection_matrix_is_named() {
    let dir = tempfile::tempdir().unwrap();
    write_random_scene(dir.path(), 2, 1, 16, 12);
    // Make row 2 of the 3×3 block a copy of row 0: rank 2.
    replace_world_mat(dir.path(), "world_mat_1", |m| {
        for c in 0..3 {
            m[8 + c] = m[c];
        }
    });
    let e = err_of(dir.path());
    assert!(e.contains("'world_mat_1'") && e.contains("singular"), "{e}");
}

#[test]
fn nan_projection_matrix_is_named() {
    let dir = tempfile::tempdir().unwrap();
    write_random_scene(dir.path(), 2, 1, 16, 12);
    replace_world_mat(dir.path(), "world_mat_0", |m| m[5] = f64::NAN);
    let e = err_of(dir.path());
    assert!(
        e.contains("'world_mat_0'") && e.contains("non-finite"),
        "{e}"
    );
}

#[test]
fn empty_image_folder_is_named() {
    let dir = tempfile::tempdir().unwrap();
    write_random_scene(dir.path(), 2, 1, 16, 12);
    for i in 0..2 {
        std::fs::remove_file(dir.path().join(format!("image/{i:06}.png"))).unwrap();
    }
    let e = err_of(dir.path());
    assert!(e.contains("no PNG images") && e.contains("image"), "{e}");
    let e = err_of(&dir.path().join("does-not-exist"));
    assert!(e.contains("does-not-exist"), "{e}");
}

#[test]
fn mask_count_mismatch_is_named() {
    let dir = tempfile::tempdir().unwrap();
    write_random_scene(dir.path(), 3, 1, 16, 12);
    std::fs::remove_file(dir.path().join("mask/002.png")).unwrap();
    let e = err_of(dir.path());
    assert!(e.contains("2 masks") && e.contains("3 images"), "{e}");
}
