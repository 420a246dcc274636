//! Unit tests of [`super`]: the schedule, the gauge, the state's rows, the chained gradient
//! against finite differences, the rays' marking and the corrected cameras.
use super::*;

#[test]
fn the_learning_rate_decays_from_lr_to_lr_end_and_stops_after_until() {
    let gated = PoseRefineConfig {
        start: 0.1,
        until: 0.5,
        gate: 0.05,
        ..Default::default()
    };
    // The gate listens over [start, start + gate); the schedule starts after it.
    assert_eq!(gated.lr_at(149, 1000), 0.0);
    assert!(gated.lr_at(151, 1000) > 0.98e-4);
    assert!(gated.within(100, 1000) && !gated.within(99, 1000) && !gated.within(500, 1000));
    let c = PoseRefineConfig { gate: 0.0, ..gated };
    assert_eq!(c.lr_at(99, 1000), 0.0);
    assert_eq!(c.lr_at(100, 1000), 1e-4);
    assert!((c.lr_at(300, 1000) - 1e-5).abs() < 1e-15);
    assert!(c.lr_at(499, 1000) > 1e-6);
    assert_eq!(c.lr_at(500, 1000), 0.0);
    assert!(c.invalid().is_none());
    for bad in [
        PoseRefineConfig {
            lr: 0.0,
            ..c.clone()
        },
        PoseRefineConfig {
            lr_end: f64::NAN,
            ..c.clone()
        },
        PoseRefineConfig {
            until: 0.0,
            ..c.clone()
        },
        PoseRefineConfig {
            weight: -1.0,
            ..c.clone()
        },
    ] {
        assert!(bad.invalid().is_some(), "{bad:?}");
    }
}

/// A pure similarity of the whole scene is removed entirely; corrections with no common
/// part are left alone; a mix keeps exactly its own part.
#[test]
fn the_common_similarity_is_removed_and_nothing_else() {
    use crate::scene::camera::tests::orbit;
    let cams = orbit(12, 0.5, |i| 1.0 + (i % 3) as f64 * 0.4);
    let c2w: Vec<Matrix3<f64>> = cams.iter().map(|c| c.r.transpose()).collect();
    let ctr: Vec<Vector3<f64>> = cams.iter().map(|c| c.center).collect();
    let (theta, delta, sigma) = (
        Vector3::new(0.01, -0.02, 0.005),
        Vector3::new(0.1, 0.0, -0.05),
        0.02,
    );
    let common: Vec<PoseCorrection> = c2w
        .iter()
        .zip(&ctr)
        .map(|(c, x)| PoseCorrection {
            omega: c.transpose() * theta,
            t: c.transpose() * (theta.cross(x) + delta + x * sigma),
        })
        .collect();
    let mut p = common.clone();
    remove_gauge(&c2w, &ctr, &mut p);
    for q in &p {
        assert!(q.omega.norm() < 1e-12 && q.t.norm() < 1e-12, "{q:?}");
    }
    // Own parts: the residual of a least-squares fit is orthogonal to the common motions,
    // so removing the gauge from (own residual + common) leaves the residual.
    let mut own: Vec<PoseCorrection> = (0..12)
        .map(|i| PoseCorrection {
            omega: Vector3::new((i as f64).sin(), (i as f64 * 1.7).cos(), 0.3) * 0.01,
            t: Vector3::new(0.02, (i as f64 * 0.9).sin() * 0.03, -0.01),
        })
        .collect();
    remove_gauge(&c2w, &ctr, &mut own);
    let mut mixed: Vec<PoseCorrection> = own
        .iter()
        .zip(&common)
        .map(|(a, b)| PoseCorrection {
            omega: a.omega + b.omega,
            t: a.t + b.t,
        })
        .collect();
    remove_gauge(&c2w, &ctr, &mut mixed);
    for (a, b) in own.iter().zip(&mixed) {
        assert!((a.omega - b.omega).norm() < 1e-12 && (a.t - b.t).norm() < 1e-12);
    }
    assert!(
        own.iter().any(|q| q.omega.norm() > 1e-3),
        "the own part survives"
    );
    // One view: its correction is all gauge (the object can move instead), removed.
    let mut one = vec![own[3]];
    remove_gauge(&c2w[..1], &ctr[..1], &mut one);
    assert!(
        one[0].omega.norm() < 1e-9 && one[0].t.norm() < 1e-9,
        "{one:?}"
    );
}

#[test]
fn the_state_round_trips_through_rows_and_refuses_bad_ones() {
    let mut s = PoseState::new(3, 2);
    s.corrections[1].omega = Vector3::new(0.1, -0.2, 0.3);
    s.corrections[2].t = Vector3::new(1.0, 2.0, -3.0);
    s.m[0][4] = 0.5;
    s.v[2][5] = 0.25;
    s.focal[1] = [0.05, -0.01, 0.002];
    s.t = 17;
    let (rows, focal) = (s.to_rows(), s.focal_rows());
    assert_eq!((rows.len(), focal.len()), (54, 6));
    assert_eq!(PoseState::from_rows(&rows, &focal, 17), Some(s.clone()));
    assert!(PoseState::from_rows(&rows[..53], &focal, 17).is_none());
    assert!(PoseState::from_rows(&rows, &focal[..5], 17).is_none());
    let mut no_focal = s;
    no_focal.focal.clear();
    assert_eq!(PoseState::from_rows(&rows, &[], 17), Some(no_focal));
    let mut bad = rows.clone();
    bad[3] = f64::NAN;
    assert!(PoseState::from_rows(&bad, &focal, 17).is_none());
    bad = rows.clone();
    bad[17] = -1.0;
    assert!(PoseState::from_rows(&bad, &focal, 17).is_none());
    let mut bad_focal = focal.clone();
    bad_focal[5] = -1.0;
    assert!(PoseState::from_rows(&rows, &bad_focal, 17).is_none());
    bad_focal[5] = f64::INFINITY;
    assert!(PoseState::from_rows(&rows, &bad_focal, 17).is_none());
}

/// The refiner's gradient of `(ω, t)` and of the focal's `φ`, chained through the
/// correction `d' = C R(ω) F_φ(Cᵀd)`, against central differences in f64 of a linear loss
/// `⟨a, o'⟩ + ⟨b, d'⟩` of the corrected rays (whose gradient the cells then hold).
#[test]
fn the_refiners_chained_gradient_matches_finite_differences() {
    use crate::scene::camera::{centred_intrinsics, look_at};
    use std::sync::atomic::Ordering;
    let cam = look_at(
        Vector3::new(1.0, -2.0, 1.5),
        Vector3::new(0.1, 0.0, -0.1),
        Vector3::z(),
        centred_intrinsics(120.0, 64, 48),
        64,
        48,
    );
    let cfg = PoseRefineConfig {
        enabled: true,
        focal: true,
        ..Default::default()
    };
    let mut refiner = PoseRefiner::new(&cfg, std::slice::from_ref(&cam));
    let mut s = PoseState::new(1, 1);
    s.corrections[0] = PoseCorrection {
        omega: Vector3::new(0.02, -0.05, 0.03),
        t: Vector3::new(0.01, 0.02, -0.03),
    };
    s.focal[0][0] = -0.07;
    let (a, b) = (Vector3::new(0.3, -0.7, 0.2), Vector3::new(-0.4, 0.5, 0.9));
    let (o, d) = cam.ray(5.5, 40.5);
    let f32s = |v: Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
    let (mut os, mut ds) = ([f32s(o)], [f32s(d)]);
    refiner.correct(&s, &[0], &mut os, &mut ds, (0, 1));
    for (k, x) in a.iter().chain(b.iter()).enumerate() {
        refiner.cells[0][k].store(f64::to_bits(*x), Ordering::Relaxed);
    }
    assert!(refiner.gradients(&s, &[0]));
    // The loss in f64 from the ray the refiner kept (the f32 one).
    let (o, d) = (
        Vector3::from(refiner.origins[0].map(f64::from)),
        Vector3::from(refiner.dirs[0].map(f64::from)),
    );
    let c = cam.r.transpose();
    let loss = |q: &PoseState| {
        let local = apply_focal(q.focal[0][0], &(c.transpose() * d));
        let (o2, d2) = q.corrections[0].apply(&c, &o, &(c * local));
        a.dot(&o2) + b.dot(&d2)
    };
    let h = 1e-6;
    for k in 0..7 {
        let (mut qp, mut qm) = (s.clone(), s.clone());
        let nudge = |q: &mut PoseState, e: f64| match k {
            0..3 => q.corrections[0].omega[k] += e,
            3..6 => q.corrections[0].t[k - 3] += e,
            _ => q.focal[0][0] += e,
        };
        nudge(&mut qp, h);
        nudge(&mut qm, -h);
        let fd = (loss(&qp) - loss(&qm)) / (2.0 * h);
        let an = if k < 6 {
            refiner.grads[0][k]
        } else {
            refiner.focal_grads[0]
        };
        assert!(
            (an - fd).abs() < 1e-8 * (1.0 + fd.abs()),
            "{k}: {an} vs {fd}"
        );
        assert!(fd.abs() > 1e-4, "{k}: the check must see a gradient");
    }
    // A non-finite ray gradient is reported.
    refiner.cells[0][4].store(f64::NAN.to_bits(), Ordering::Relaxed);
    assert!(!refiner.gradients(&s, &[0]));
}

/// `correct` asks for one ray in `ray_every`, and for none while the learning rate is 0.
#[test]
fn correct_marks_the_rays_whose_gradient_is_wanted() {
    use std::sync::atomic::Ordering;
    let cams = crate::scene::camera::tests::orbit(2, 1.0, |_| 1.0);
    let cfg = PoseRefineConfig {
        enabled: true,
        ray_every: 3,
        ..Default::default()
    };
    let mut refiner = PoseRefiner::new(&cfg, &cams);
    let s = PoseState::new(2, 0);
    let views = [0u32, 1, 0, 1, 1, 0, 0];
    let (mut os, mut ds) = (vec![[0.0f32; 3]; 7], vec![[0.0f32, 0.0, 1.0]; 7]);
    let skipped = |r: &PoseRefiner| -> Vec<bool> {
        r.cells()
            .iter()
            .map(|c| c[0].load(Ordering::Relaxed) == crate::render::RAY_GRAD_SKIP)
            .collect()
    };
    refiner.correct(&s, &views, &mut os, &mut ds, (50, 100));
    let want: Vec<bool> = (0..7).map(|i| i % 3 != 0).collect();
    assert_eq!(skipped(&refiner), want);
    refiner.correct(&s, &views, &mut os, &mut ds, (5, 100));
    assert_eq!(skipped(&refiner), vec![true; 7], "before start");
    assert!(PoseRefineConfig {
        ray_every: 0,
        ..cfg
    }
    .invalid()
    .is_some_and(|(k, _, _)| k == "train.pose_refine.ray_every"));
}

/// A corrected camera casts the corrected rays: its centre is `o + C·t` and its ray through
/// a pixel is the ray the refiner casts in training for the uncorrected camera's ray through
/// the same pixel: rotated, and with the focal learned, narrowed by the focal scale.
#[test]
fn the_corrected_camera_casts_the_corrected_rays() {
    use crate::scene::camera::{centred_intrinsics, look_at};
    let cam = look_at(
        Vector3::new(1.0, 2.0, 3.0),
        Vector3::zeros(),
        Vector3::z(),
        centred_intrinsics(300.0, 64, 48),
        64,
        48,
    );
    let p = PoseCorrection {
        omega: Vector3::new(0.01, -0.02, 0.03),
        t: Vector3::new(0.05, 0.01, -0.02),
    };
    for (focal, phi) in [(false, 0.0), (true, 0.0), (true, 0.08)] {
        let cfg = PoseRefineConfig {
            enabled: true,
            focal,
            ..Default::default()
        };
        let mut refiner = PoseRefiner::new(&cfg, std::slice::from_ref(&cam));
        let mut s = PoseState::new(1, refiner.n_focal());
        assert_eq!(s.focal.len(), usize::from(focal));
        s.corrections[0] = p;
        if focal {
            s.focal[0][0] = phi;
        }
        let fixed = s.corrected(std::slice::from_ref(&cam)).remove(0);
        assert!((fixed.k[(0, 0)] - 300.0 * phi.exp()).abs() < 1e-9);
        for (u, v) in [(10.5, 30.5), (63.0, 0.5), (32.0, 24.0)] {
            let (o, d) = cam.ray(u, v);
            let mut os = [[o.x as f32, o.y as f32, o.z as f32]];
            let mut ds = [[d.x as f32, d.y as f32, d.z as f32]];
            refiner.correct(&s, &[0], &mut os, &mut ds, (0, 1));
            let (o3, d3) = fixed.ray(u, v);
            let (o2, d2) = (os[0].map(f64::from), ds[0].map(f64::from));
            let (o2, d2) = (Vector3::from(o2), Vector3::from(d2));
            assert!((o2 - o3).norm() < 1e-6, "{o2} {o3}");
            assert!((d2 - d3).norm() < 1e-6, "focal {focal} φ {phi}: {d2} {d3}");
            if !focal {
                let (o4, d4) = p.apply(&cam.r.transpose(), &o, &d);
                assert!((o4 - o3).norm() < 1e-12 && (d4 - d3).norm() < 1e-12);
            }
        }
    }
}
