//! Known pose errors, for measuring pose refinement (`train.pose_refine`): `synth
//! --perturb-poses DEG,DIST[,FOCAL]` moves every camera of a rendered scene by exactly `DEG`
//! degrees about a random axis through its centre and `DIST` world units in a random direction
//! (and scales every focal length by `1 + FOCAL/100`, as a self-calibration error would), keeps
//! the true cameras as `cameras_sphere_true.npz`, and writes the perturbed ones as the scene's
//! `cameras_sphere.npz` (the images stay those of the true cameras). [`pose_error`] measures a
//! camera against the truth the way BARF reports it (Lin et al. 2021, §4: rotation angle and
//! translation distance, here without a global alignment, as the ground truth fixes the frame).

use super::export::{read_scene_cameras, read_world_cameras};
use super::ImportError;
use crate::scene::dtu::{write_cameras, Normalization, CAMERA_FILE};
use crate::scene::{npz, Camera};
use crate::train::pose::exp_so3;
use nalgebra::{Matrix4, Vector3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use std::path::Path;

/// The true cameras beside the perturbed ones.
pub const TRUE_CAMERA_FILE: &str = "cameras_sphere_true.npz";

/// How far a camera is from the truth.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PoseError {
    /// Angle of `R_est·R_trueᵀ`, degrees.
    pub rotation_deg: f64,
    /// `|C_est − C_true|`, in the cameras' units.
    pub centre: f64,
}

/// The error of `est` against `truth`.
pub fn pose_error(truth: &Camera, est: &Camera) -> PoseError {
    let d = est.r * truth.r.transpose();
    let c = ((d.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
    PoseError {
        rotation_deg: c.acos().to_degrees(),
        centre: (est.center - truth.center).norm(),
    }
}

/// How far apart two cameras put the same points in the image: the mean distance in pixels
/// between the projections of `points` (world) by `truth` and by `est`, over the points in
/// front of both cameras. Rotation and a sideways move of the centre nearly trade off for a
/// distant camera; this is the error the images see.
pub fn reprojection_px(truth: &Camera, est: &Camera, points: &[Vector3<f64>]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for x in points {
        if let (Some((u0, v0, _)), Some((u1, v1, _))) = (truth.project(x), est.project(x)) {
            sum += ((u1 - u0).powi(2) + (v1 - v0).powi(2)).sqrt();
            n += 1;
        }
    }
    if n == 0 {
        f64::NAN
    } else {
        sum / n as f64
    }
}

/// The mean error over pairs of cameras.
pub fn mean_pose_error(truth: &[&Camera], est: &[&Camera]) -> PoseError {
    let n = truth.len().max(1) as f64;
    let mut m = PoseError::default();
    for (t, e) in truth.iter().zip(est) {
        let p = pose_error(t, e);
        m.rotation_deg += p.rotation_deg / n;
        m.centre += p.centre / n;
    }
    m
}

/// A uniformly random unit vector.
fn unit(rng: &mut Pcg64Mcg) -> Vector3<f64> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let n = v.norm();
        if n > 1e-3 && n <= 1.0 {
            return v / n;
        }
    }
}

/// A known error of every camera (see the module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Perturbation {
    /// Rotation about a random axis through the centre, degrees.
    pub degrees: f64,
    /// Move of the centre in a random direction, world units.
    pub dist: f64,
    /// Focal lengths (and skew) scaled by `1 + focal_pct/100`.
    pub focal_pct: f64,
}

/// Every camera turned by exactly `p.degrees` about a random axis through its centre, its
/// centre moved by exactly `p.dist` in a random direction (seeded), and its focal lengths
/// scaled by `1 + p.focal_pct/100`.
pub fn perturb(cameras: &[Camera], p: &Perturbation, seed: u64) -> Vec<Camera> {
    let mut rng = Pcg64Mcg::seed_from_u64(seed ^ 0x706f_7365);
    let phi = (1.0 + p.focal_pct / 100.0).ln();
    cameras
        .iter()
        .map(|c| {
            let w = unit(&mut rng) * p.degrees.to_radians();
            let t = unit(&mut rng) * p.dist;
            Camera {
                r: exp_so3(&w) * c.r,
                center: c.center + t,
                ..crate::train::pose_refine::with_focal_scale(c, phi)
            }
        })
        .collect()
}

/// Perturbs the cameras of the scene folder `scene` (see the module doc). Refused when the
/// scene already holds [`TRUE_CAMERA_FILE`] (it was perturbed once), when the angle or
/// distance is negative or not finite, or when the focal change is not in (−50, 100] %.
/// Returns the mean pose error written.
pub fn perturb_scene(scene: &Path, p: &Perturbation, seed: u64) -> Result<PoseError, ImportError> {
    let Perturbation {
        degrees,
        dist,
        focal_pct,
    } = *p;
    if !(degrees.is_finite() && degrees >= 0.0 && dist.is_finite() && dist >= 0.0) {
        return Err(ImportError::Export(format!(
            "a pose perturbation of {degrees}° and {dist} must be finite and ≥ 0"
        )));
    }
    if !(focal_pct > -50.0 && focal_pct <= 100.0) {
        return Err(ImportError::Export(format!(
            "a focal perturbation of {focal_pct} % must be in (−50, 100]"
        )));
    }
    let truth_path = scene.join(TRUE_CAMERA_FILE);
    if truth_path.exists() {
        return Err(ImportError::Export(format!(
            "{} exists: the scene's poses were perturbed already",
            truth_path.display()
        )));
    }
    let sc = read_scene_cameras(scene)?;
    let cam_path = scene.join(CAMERA_FILE);
    let arrays = npz::read(&cam_path).map_err(crate::scene::SceneError::from)?;
    let scale = arrays
        .get("scale_mat_0")
        .filter(|a| a.shape == [4, 4])
        .ok_or_else(|| ImportError::Parse {
            file: cam_path.clone(),
            message: "'scale_mat_0' is missing or not 4×4".into(),
        })?;
    let m = Matrix4::from_fn(|r, c| scale.data[r * 4 + c]);
    let norm = Normalization::from_scale_mat(&m).map_err(|message| ImportError::Parse {
        file: cam_path.clone(),
        message: format!("'scale_mat_0' {message}"),
    })?;
    let moved = perturb(&sc.cameras, p, seed);
    std::fs::copy(&cam_path, &truth_path).map_err(super::io_err(&truth_path))?;
    let refs: Vec<&Camera> = moved.iter().collect();
    write_cameras(scene, &refs, &norm).map_err(|e| ImportError::Export(e.to_string()))?;
    let truth: Vec<&Camera> = sc.cameras.iter().collect();
    Ok(mean_pose_error(&truth, &refs))
}

/// The true cameras of a perturbed scene (`None` when it has no [`TRUE_CAMERA_FILE`]), world
/// frame, in `world_mat_i` order.
pub fn read_true_cameras(
    scene: &Path,
    sizes: &[(u32, u32)],
) -> Result<Option<Vec<Camera>>, ImportError> {
    let path = scene.join(TRUE_CAMERA_FILE);
    if !path.is_file() {
        return Ok(None);
    }
    read_world_cameras(&path, sizes).map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::camera::tests::orbit;

    #[test]
    fn a_perturbation_has_exactly_the_asked_size() {
        let cams = orbit(8, 1.0, |_| 1.0);
        let size = Perturbation {
            degrees: 0.5,
            dist: 3.0,
            focal_pct: 0.0,
        };
        let moved = perturb(&cams, &size, 7);
        for (t, e) in cams.iter().zip(&moved) {
            let p = pose_error(t, e);
            assert!((p.rotation_deg - 0.5).abs() < 1e-9, "{p:?}");
            assert!((p.centre - 3.0).abs() < 1e-9, "{p:?}");
            assert_eq!(t.k, e.k);
        }
        assert_eq!(perturb(&cams, &size, 7), moved, "seeded");
        assert_ne!(perturb(&cams, &size, 8), moved);
        // A focal change scales fx, fy (and skew) and nothing else; the poses are those of
        // the same seed without it.
        let longer = perturb(
            &cams,
            &Perturbation {
                focal_pct: 10.0,
                ..size
            },
            7,
        );
        for (a, b) in moved.iter().zip(&longer) {
            assert_eq!((a.r, a.center), (b.r, b.center));
            assert!((b.k[(0, 0)] / a.k[(0, 0)] - 1.1).abs() < 1e-12);
            assert!((b.k[(1, 1)] / a.k[(1, 1)] - 1.1).abs() < 1e-12);
            assert_eq!((a.k[(0, 2)], a.k[(1, 2)]), (b.k[(0, 2)], b.k[(1, 2)]));
        }
        assert_eq!(pose_error(&cams[0], &cams[0]), PoseError::default());
        let pts = [Vector3::zeros(), Vector3::new(0.3, -0.2, 0.1)];
        assert_eq!(reprojection_px(&cams[0], &cams[0], &pts), 0.0);
        // A quarter of a degree of yaw at f = 200 px moves a point on the axis by 200·tan(0.25°).
        let yawed = Camera {
            r: exp_so3(&Vector3::new(0.0, 0.25f64.to_radians(), 0.0)) * cams[0].r,
            ..cams[0].clone()
        };
        let px = reprojection_px(&cams[0], &yawed, &pts[..1]);
        assert!(
            (px - 200.0 * 0.25f64.to_radians().tan()).abs() < 1e-9,
            "{px}"
        );
    }
}
