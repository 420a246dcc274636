//! Helpers shared by the integration tests: small random scenes in the DTU layout.
#![allow(dead_code)]

pub mod study;
pub mod tiny;

use nalgebra::{Matrix3, Vector3};
use neus_aug::scene::{write_scene, Camera, GrayImage, Normalization, RgbImage, ViewOut};
use rand::{Rng, SeedableRng};
use std::path::Path;

/// A camera at `center` looking at `target` (OpenCV axes: y down), with intrinsics `k`.
pub fn look_at(
    center: Vector3<f64>,
    target: Vector3<f64>,
    k: Matrix3<f64>,
    w: u32,
    h: u32,
) -> Camera {
    let z = (target - center).normalize();
    let up = if z.z.abs() > 0.9 {
        Vector3::x()
    } else {
        Vector3::z()
    };
    let x = z.cross(&-up).normalize();
    let y = z.cross(&x);
    let r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    Camera {
        k,
        r,
        center,
        width: w,
        height: h,
    }
}

/// The normalisation used by the random scenes: a DTU-like scale and an off-origin centre.
pub fn test_normalization() -> Normalization {
    Normalization {
        scale: 237.5,
        center: [12.5, -31.0, 604.25],
    }
}

/// Random world-space (mm) cameras around the normalisation's centre, 2–3 normalised units away,
/// with random intrinsics (skew included).
pub fn random_world_cameras(n: usize, seed: u64, w: u32, h: u32) -> Vec<Camera> {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    let norm = test_normalization();
    let c = Vector3::from(norm.center);
    (0..n)
        .map(|_| {
            let dir = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize();
            let dist = rng.random_range(2.0..3.0) * norm.scale;
            let f = rng.random_range(0.9..1.4) * w as f64;
            let k = Matrix3::new(
                f,
                rng.random_range(-0.5..0.5),
                w as f64 / 2.0 + rng.random_range(-3.0..3.0),
                0.0,
                f * rng.random_range(0.98..1.02),
                h as f64 / 2.0 + rng.random_range(-3.0..3.0),
                0.0,
                0.0,
                1.0,
            );
            let jitter = Vector3::new(
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
                0.0,
            );
            look_at(c + dir * dist, c + jitter, k, w, h)
        })
        .collect()
}

/// Writes a small scene (random cameras, gradient images, disc masks) and returns its world
/// cameras.
pub fn write_random_scene(dir: &Path, n: usize, seed: u64, w: u32, h: u32) -> Vec<Camera> {
    let cams = random_world_cameras(n, seed, w, h);
    let images: Vec<RgbImage> = (0..n)
        .map(|i| {
            RgbImage::from_fn(w as usize, h as usize, |x, y| {
                [
                    x as f32 / w as f32,
                    y as f32 / h as f32,
                    (i % 7) as f32 / 7.0,
                ]
            })
        })
        .collect();
    let masks: Vec<GrayImage> = (0..n)
        .map(|_| {
            let mut m = GrayImage::new(w as usize, h as usize);
            for y in 0..h as usize {
                for x in 0..w as usize {
                    let (dx, dy) = (x as f32 - w as f32 / 2.0, y as f32 - h as f32 / 2.0);
                    m.data[y * w as usize + x] = if dx * dx + dy * dy < (h as f32 / 3.0).powi(2) {
                        1.0
                    } else {
                        0.0
                    };
                }
            }
            m
        })
        .collect();
    let views: Vec<ViewOut> = (0..n)
        .map(|i| ViewOut {
            image: &images[i],
            mask: Some(&masks[i]),
            camera: &cams[i],
        })
        .collect();
    write_scene(dir, &views, &test_normalization()).unwrap();
    cams
}
