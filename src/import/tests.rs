use super::*;
use crate::scene::camera::tests::random_camera;
use rand::SeedableRng;

#[test]
fn roi_from_points_ignores_stray_points_and_two_view_points() {
    // 400 points on a sphere of radius 2 about (10, -5, 3), seen by 4 images; 10 far outliers
    // seen by 4 images (trimmed by the percentiles); 50 two-view points far away (ignored).
    let c = [10.0, -5.0, 3.0];
    let mut pts = Vec::new();
    for i in 0..400 {
        let t = i as f64 * 0.618_034 * std::f64::consts::TAU;
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / 400.0;
        let r = (1.0 - z * z).sqrt();
        pts.push((
            [
                c[0] + 2.0 * r * t.cos(),
                c[1] + 2.0 * r * t.sin(),
                c[2] + 2.0 * z,
            ],
            4,
        ));
    }
    for i in 0..5 {
        pts.push(([1e3 + i as f64, 0.0, 0.0], 4));
    }
    for i in 0..50 {
        pts.push(([-300.0, i as f64, 7.0], 2));
    }
    let choice = roi_from_points(&pts, &[Vector3::new(10.0, -5.0, 30.0)]).unwrap();
    for (got, want) in choice.roi.center.iter().zip(c) {
        assert!((got - want).abs() < 0.1, "{:?}", choice.roi);
    }
    assert!(
        choice.roi.radius > 2.0 && choice.roi.radius < 2.4,
        "{:?}",
        choice.roi
    );
    // A camera at distance 1.5 forces the radius below it.
    let near = roi_from_points(&pts, &[Vector3::new(11.5, -5.0, 3.0)]).unwrap();
    assert!((near.roi.radius - 0.9 * 1.5).abs() < 0.1, "{:?}", near.roi);
    assert!(near.method.contains("shrunk"));
}

#[test]
fn roi_from_cameras_finds_the_common_look_at_point() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
    let target = Vector3::new(0.3, -0.2, 0.1);
    let cams: Vec<Camera> = (0..12)
        .map(|_| {
            let mut cam = random_camera(&mut rng);
            // Re-aim: rows of R = camera axes in world coordinates, z toward the target.
            let z = (target - cam.center).normalize();
            let x = z.cross(&Vector3::new(0.0, 0.0, 1.0)).normalize();
            let y = z.cross(&x);
            cam.r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
            cam
        })
        .collect();
    let choice = roi_from_cameras(&cams).unwrap();
    assert!((Vector3::from(choice.roi.center) - target).norm() < 1e-9);
    for cam in &cams {
        assert!((cam.center - target).norm() > choice.roi.radius);
    }
    // One camera alone: the axes cannot meet.
    assert!(matches!(
        roi_from_cameras(&cams[..1]),
        Err(ImportError::Roi(_))
    ));
}

/// A camera at `center` aimed at `target` (OpenCV axes: rows of R are the camera axes in
/// world coordinates), 400×300 pixels, focal 700 px.
fn aimed_camera(center: Vector3<f64>, target: Vector3<f64>) -> Camera {
    let z = (target - center).normalize();
    let x = z.cross(&Vector3::new(0.0, 0.0, 1.0)).normalize();
    let y = z.cross(&x);
    Camera {
        k: Matrix3::new(700.0, 0.0, 200.0, 0.0, 700.0, 150.0, 0.0, 0.0, 1.0),
        r: Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]),
        center,
        width: 400,
        height: 300,
    }
}

/// 12 cameras 12 units from `target`, 20–60° above its horizontal plane over a 90° arc, as the
/// simulator's rig (DTU's is alike).
fn orbit(target: Vector3<f64>) -> Vec<Camera> {
    (0..12)
        .map(|i| {
            let az = (-45.0 + 90.0 * (i % 4) as f64 / 3.0f64).to_radians();
            let el = (20.0 + 20.0 * (i / 4) as f64).to_radians();
            let dir = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
            aimed_camera(target + 12.0 * dir, target)
        })
        .collect()
}

/// Points on the part of the unit sphere about `target` that faces the orbit (the side its
/// cameras see), all seen by 5 images.
fn visible_cap(target: Vector3<f64>) -> Vec<([f64; 3], usize)> {
    (0..2000)
        .filter_map(|i| {
            let t = i as f64 * 0.618_034 * std::f64::consts::TAU;
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / 2000.0;
            let r = (1.0 - z * z).sqrt();
            let n = Vector3::new(r * t.cos(), r * t.sin(), z);
            (n.x + n.z > 0.3).then(|| ((target + n).into(), 5))
        })
        .collect()
}

#[test]
fn roi_auto_takes_the_orbit_centre_where_the_points_cover_one_side() {
    let target = Vector3::new(2.0, -1.0, 0.5);
    let cams = orbit(target);
    let cap = visible_cap(target);
    // The far side of the object, which no camera sees and no point covers.
    let far = target - Vector3::new(1.0, 0.0, 1.0).normalize();
    let inside =
        |c: &RoiChoice, q: Vector3<f64>| (q - Vector3::from(c.roi.center)).norm() <= c.roi.radius;
    let by_points =
        roi_from_points(&cap, &cams.iter().map(|c| c.center).collect::<Vec<_>>()).unwrap();
    assert!(
        !inside(&by_points, far),
        "the points' sphere cuts the far side: {by_points:?}"
    );
    let auto = roi_auto(&cap, &cams).unwrap();
    assert!(
        (Vector3::from(auto.roi.center) - target).norm() < 1e-9,
        "{auto:?}"
    );
    assert!(inside(&auto, far) && auto.roi.radius >= 1.4, "{auto:?}");
    // The radius follows the points (1.5 x their 98th-percentile distance, ~1.5), not the
    // far larger sphere every camera sees whole.
    let by_cameras = roi_from_cameras(&cams).unwrap();
    assert!(by_cameras.roi.radius > 2.0, "{by_cameras:?}");
    assert!(
        auto.roi.radius <= 1.5 + 1e-9 && auto.method.starts_with("auto, an orbit"),
        "{auto:?}"
    );
    for c in &cams {
        assert!((c.center - target).norm() > auto.roi.radius);
    }

    // A table of points around the object, out to 6 units: the sphere stops where the
    // cameras' views do, instead of swelling to the table.
    let mut with_table = cap.clone();
    for i in 0..3000 {
        let a = i as f64 * 0.618_034 * std::f64::consts::TAU;
        let rho = 6.0 * ((i as f64 + 0.5) / 3000.0).sqrt();
        with_table.push((
            [
                target.x + rho * a.cos(),
                target.y + rho * a.sin(),
                target.z - 1.0,
            ],
            4,
        ));
    }
    let auto = roi_auto(&with_table, &cams).unwrap();
    assert!(
        (auto.roi.radius - by_cameras.roi.radius).abs() < 1e-12,
        "{auto:?}"
    );
    assert!(auto.method.contains("every camera sees whole"), "{auto:?}");
}

#[test]
fn roi_auto_falls_back_to_the_points_when_the_capture_is_no_orbit() {
    let target = Vector3::new(0.0, 0.0, 0.0);
    let cap = visible_cap(target);
    let centers = |cams: &[Camera]| cams.iter().map(|c| c.center).collect::<Vec<_>>();
    // Forward-facing: parallel optical axes never meet.
    let forward: Vec<Camera> = (0..6)
        .map(|i| {
            let c = Vector3::new(i as f64 - 2.5, -10.0, 0.3);
            aimed_camera(c, c + Vector3::new(0.0, 1.0, 0.0))
        })
        .collect();
    // Cameras aimed at a point 20 units away from the points (they photographed something
    // else), and cameras on a ring around the points aimed outwards (their axes meet behind
    // them).
    let elsewhere: Vec<Camera> = orbit(Vector3::new(20.0, 0.0, 0.0));
    let outward: Vec<Camera> = orbit(target)
        .into_iter()
        .map(|c| aimed_camera(c.center, 2.0 * c.center - target))
        .collect();
    for (what, cams) in [
        ("forward", forward),
        ("elsewhere", elsewhere),
        ("outward", outward),
    ] {
        let auto = roi_auto(&cap, &cams).unwrap();
        let by_points = roi_from_points(&cap, &centers(&cams)).unwrap();
        assert_eq!(auto.roi.center, by_points.roi.center, "{what}: {auto:?}");
        assert_eq!(auto.roi.radius, by_points.roi.radius, "{what}");
        assert!(auto.method.contains("(auto: "), "{what}: {}", auto.method);
    }
}

#[test]
fn vec3_flag_parses_and_rejects() {
    assert_eq!(parse_vec3("1, -2.5,3e2").unwrap(), [1.0, -2.5, 300.0]);
    assert!(parse_vec3("1,2").is_err());
    assert!(parse_vec3("1,2,x").is_err());
    assert!(parse_vec3("1,2,nan").is_err());
}

#[test]
fn masks_are_found_by_colmap_name_by_stem_and_by_number() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("a.jpg.png"), b"").unwrap();
    std::fs::write(d.join("b.png"), b"").unwrap();
    std::fs::write(d.join("007.png"), b"").unwrap();
    assert_eq!(find_mask(d, "a.jpg"), Some(d.join("a.jpg.png")));
    assert_eq!(find_mask(d, "b.jpg"), Some(d.join("b.png")));
    assert_eq!(find_mask(d, "000007.png"), Some(d.join("007.png")));
    assert_eq!(find_mask(d, "000008.png"), None);
}
