use super::*;
use crate::scene::camera::tests::random_camera;
use rand::SeedableRng;

fn sample_model() -> ColmapModel {
    let mut cameras = BTreeMap::new();
    cameras.insert(
        3,
        ColmapCamera {
            id: 3,
            model: "PINHOLE".into(),
            width: 64,
            height: 48,
            params: vec![70.5, 71.25, 32.0, 23.5],
        },
    );
    cameras.insert(
        7,
        ColmapCamera {
            id: 7,
            model: "OPENCV".into(),
            width: 64,
            height: 48,
            params: vec![70.0, 70.0, 31.0, 24.0, 0.01, -0.002, 0.0, 0.0],
        },
    );
    ColmapModel {
        cameras,
        images: vec![
            ColmapImage {
                id: 12,
                qvec: [0.5, 0.5, -0.5, 0.5],
                tvec: [0.1, -0.2, 3.0],
                camera_id: 3,
                name: "b.png".into(),
                points2d: vec![(1.5, 2.25, 4), (3.0, 4.0, -1)],
            },
            ColmapImage {
                id: 5,
                qvec: [1.0, 0.0, 0.0, 0.0],
                tvec: [0.0, 0.0, 2.0],
                camera_id: 7,
                name: "a.png".into(),
                points2d: vec![],
            },
        ],
        points: vec![ColmapPoint {
            id: 4,
            xyz: [0.1, 1.0 / 3.0, -2.5e-7],
            rgb: [10, 200, 255],
            error: 0.25,
            track: vec![(12, 0), (5, 3)],
        }],
    }
}

#[test]
fn text_and_binary_forms_round_trip_exactly() {
    let model = sample_model();
    let dir = tempfile::tempdir().unwrap();
    let (t, b) = (dir.path().join("t"), dir.path().join("b"));
    write_text(&model, &t).unwrap();
    write_binary(&model, &b).unwrap();
    let (from_text, ft) = read_model(&t).unwrap();
    let (from_bin, fb) = read_model(&b).unwrap();
    assert_eq!((ft, fb), (ModelFormat::Text, ModelFormat::Binary));
    assert_eq!(from_text, model);
    assert_eq!(from_bin, model);
}

#[test]
fn quaternion_and_rotation_invert_each_other() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(9);
    for _ in 0..100 {
        let r = random_camera(&mut rng).r;
        let q = quaternion(&r);
        assert!(q[0] >= 0.0);
        assert!((rotation(q).unwrap() - r).abs().max() < 1e-14);
    }
    // COLMAP's example: qw = 1 is the identity; a 90° turn about z maps x to y.
    assert_eq!(rotation([1.0, 0.0, 0.0, 0.0]).unwrap(), Matrix3::identity());
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let rz = rotation([h, 0.0, 0.0, h]).unwrap();
    assert!((rz * Vector3::x() - Vector3::y()).norm() < 1e-15);
    assert!(rotation([0.0; 4]).is_none());
    assert!(rotation([f64::NAN, 0.0, 0.0, 1.0]).is_none());
}

#[test]
fn pinhole_models_give_k_and_distorted_ones_their_coefficients() {
    let file = Path::new("cameras.txt");
    let cam = |model: &str, params: Vec<f64>| ColmapCamera {
        id: 2,
        model: model.into(),
        width: 10,
        height: 10,
        params,
    };
    let (k, d) = intrinsics(&cam("SIMPLE_PINHOLE", vec![50.0, 5.0, 4.5]), file).unwrap();
    assert_eq!(
        k,
        Matrix3::new(50.0, 0.0, 5.0, 0.0, 50.0, 4.5, 0.0, 0.0, 1.0)
    );
    assert!(d.is_zero());
    let (k, _) = intrinsics(&cam("PINHOLE", vec![50.0, 52.0, 5.0, 4.5]), file).unwrap();
    assert_eq!((k[(0, 0)], k[(1, 1)]), (50.0, 52.0));
    // Distorted models with zero distortion are pinholes.
    let (k, d) = intrinsics(&cam("RADIAL", vec![50.0, 5.0, 4.5, 0.0, 0.0]), file).unwrap();
    assert_eq!(k[(1, 1)], 50.0);
    assert!(d.is_zero());
    // Each model's coefficients land in the OpenCV model's slots (COLMAP models.h).
    let (_, d) = intrinsics(&cam("SIMPLE_RADIAL", vec![50.0, 5.0, 4.5, 0.1]), file).unwrap();
    assert_eq!((d.k1, d.k2, d.p1, d.p2), (0.1, 0.0, 0.0, 0.0));
    let (_, d) = intrinsics(&cam("RADIAL", vec![50.0, 5.0, 4.5, 0.1, -0.02]), file).unwrap();
    assert_eq!((d.k1, d.k2, d.p1, d.p2), (0.1, -0.02, 0.0, 0.0));
    let opencv = vec![50.0, 51.0, 5.0, 4.5, 0.1, -0.02, 1e-4, -2e-4];
    let (k, d) = intrinsics(&cam("OPENCV", opencv), file).unwrap();
    assert_eq!(k[(1, 1)], 51.0);
    assert_eq!((d.k1, d.k2, d.p1, d.p2), (0.1, -0.02, 1e-4, -2e-4));
    let err = intrinsics(&cam("SIMPLE_RADIAL", vec![50.0, 5.0, 4.5, f64::NAN]), file)
        .unwrap_err()
        .to_string();
    assert!(err.contains("distortion"), "{err}");
    let err = intrinsics(&cam("OPENCV_FISHEYE", vec![0.0; 8]), file)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("OPENCV_FISHEYE") && err.contains("PINHOLE"),
        "{err}"
    );
    let err = intrinsics(&cam("WEIRD", vec![]), file)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("WEIRD") && err.contains("cameras.txt"),
        "{err}"
    );
    let err = intrinsics(&cam("PINHOLE", vec![1.0]), file)
        .unwrap_err()
        .to_string();
    assert!(err.contains("expected 4"), "{err}");
}

#[test]
fn malformed_files_name_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_text(&sample_model(), d).unwrap();
    std::fs::write(d.join("points3D.txt"), "# c\n1 0 0 0 1 2 3 0.5 7\n").unwrap();
    let err = read_model(d).unwrap_err().to_string();
    assert!(
        err.contains("points3D.txt") && err.contains("line 2"),
        "{err}"
    );
    std::fs::remove_file(d.join("points3D.txt")).unwrap();
    let err = read_model(d).unwrap_err().to_string();
    assert!(
        err.contains("points3D.txt") && err.contains("missing"),
        "{err}"
    );
    // A truncated binary file.
    let b = d.join("bin");
    write_binary(&sample_model(), &b).unwrap();
    let bytes = std::fs::read(b.join("images.bin")).unwrap();
    std::fs::write(b.join("images.bin"), &bytes[..bytes.len() - 5]).unwrap();
    let err = read_model(&b).unwrap_err().to_string();
    assert!(
        err.contains("images.bin") && err.contains("truncated"),
        "{err}"
    );
    // An unknown model id in binary form.
    let mut cams = std::fs::read(b.join("cameras.bin")).unwrap();
    cams[12..16].copy_from_slice(&42i32.to_le_bytes());
    std::fs::write(b.join("cameras.bin"), &cams).unwrap();
    let err = read_model(&b).unwrap_err().to_string();
    assert!(
        err.contains("cameras.bin") && err.contains("model id 42"),
        "{err}"
    );
    assert!(read_model(&d.join("nowhere"))
        .unwrap_err()
        .to_string()
        .contains("cameras.txt"));
}
