//! The DTU-like camera rig: frames, intrinsics, the 49-view spherical cap, and `scale_mat`.
//!
//! Frames (one place for them):
//! - **Rig frame** (where meshes are built, rays traced and lights given): origin at the object's
//!   bounding-box centre, `+z` up (away from the ground plane), cameras on the `−y` side, mm.
//! - **World frame** (what the scene folder stores, DTU-like): `X_world = c + R_wr · X_rig` with
//!   `c = object.center_mm` and the fixed rotation [`R_WORLD_FROM_RIG`], which sends rig `+z` (up)
//!   to world `−y` and the cameras' side (rig `−y`) to world `−z`. So, as in DTU, the cameras sit
//!   near the world origin looking down `+z` at an object a few hundred mm away, with "up" along
//!   `−y` (the OpenCV camera's image-up).
//!
//! Intrinsics: DTU's cameras at 1600×1200 share fx ≈ 2892.33, fy ≈ 2883.18, cx ≈ 823.205,
//! cy ≈ 619.071 px (the `K` that the DTU `cameras_sphere.npz` of IDR/NeuS decompose to, skew
//! ≈ −3e-4 dropped; MVS pipelines use the same numbers "for all DTU datasets"). They are scaled to
//! the requested size with continuous pixel coordinates (`u' = u · W'/1600`, `v' = v · H'/1200`),
//! which keeps the pixel-centre convention of [`crate::scene::camera`].
//!
//! Layout: `rows = ceil(sqrt(n))` rings of elevation evenly spread over `elevation_deg`, the
//! views split as evenly as possible over rows, each row's azimuths evenly spread over
//! `azimuth_deg`, visited in serpentine order like DTU's robot arm. 49 views give DTU's 7 × 7.
//!
//! Normalisation (`scale_mat`): centre = the bounding-box centre of the mesh vertices, radius =
//! their largest distance from it, as Totoro97/NeuS
//! `preprocess_custom_data/colmap_preprocess/gen_cameras.py` computes it from the points of
//! interest, times `rig.scale_margin` (1.1) so the surface stays inside the unit sphere.

use super::desc::RigSpec;
use crate::scene::{Camera, Normalization};
use nalgebra::{Matrix3, Vector3};

/// DTU intrinsics at 1600×1200: `(fx, fy, cx, cy)` (see the module doc).
pub const DTU_INTRINSICS: (f64, f64, f64, f64) = (2892.33, 2883.18, 823.205, 619.071);
/// The image size DTU's intrinsics refer to.
pub const DTU_SIZE: (f64, f64) = (1600.0, 1200.0);

/// The rotation from rig to world axes: columns are the rig axes in world coordinates
/// (`x → x`, `y → z`, `z → −y`), a proper rotation with exact entries.
pub const R_WORLD_FROM_RIG: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]];

/// The rigid map between the rig frame and the world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// World position of the rig origin (mm).
    pub center: Vector3<f64>,
    /// `R_wr`: world-from-rig rotation.
    pub rotation: Matrix3<f64>,
}

impl Frame {
    /// The frame with the rig origin at `center` (world mm).
    pub fn new(center: [f64; 3]) -> Self {
        let m = R_WORLD_FROM_RIG;
        Self {
            center: Vector3::from(center),
            rotation: Matrix3::new(
                m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2],
            ),
        }
    }
    /// Rig point → world point.
    pub fn to_world(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.center + self.rotation * p
    }
    /// World point → rig point.
    pub fn to_rig(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation.transpose() * (p - self.center)
    }
    /// World up (the rig's `+z`), a unit vector.
    pub fn up_world(&self) -> Vector3<f64> {
        self.rotation.column(2).into_owned()
    }
}

/// DTU intrinsics scaled to `width × height` (see the module doc).
pub fn intrinsics(width: u32, height: u32) -> Matrix3<f64> {
    let (fx, fy, cx, cy) = DTU_INTRINSICS;
    let sx = width as f64 / DTU_SIZE.0;
    let sy = height as f64 / DTU_SIZE.1;
    Matrix3::new(fx * sx, 0.0, cx * sx, 0.0, fy * sy, cy * sy, 0.0, 0.0, 1.0)
}

pub use crate::scene::camera::{centred_intrinsics, look_at};

/// `(azimuth, elevation)` in degrees of each view, in capture order (see the module doc).
pub fn view_angles(spec: &RigSpec) -> Vec<(f64, f64)> {
    let n = spec.views;
    let rows = (n as f64).sqrt().ceil().max(1.0) as usize;
    let lerp = |range: [f64; 2], i: usize, count: usize| {
        if count <= 1 {
            0.5 * (range[0] + range[1])
        } else {
            range[0] + (range[1] - range[0]) * i as f64 / (count - 1) as f64
        }
    };
    let mut out = Vec::with_capacity(n);
    for row in 0..rows {
        let in_row = n / rows + usize::from(row < n % rows);
        let el = lerp(spec.elevation_deg, row, rows);
        for j in 0..in_row {
            // Serpentine: even rows left to right, odd rows back.
            let jj = if row % 2 == 0 { j } else { in_row - 1 - j };
            out.push((lerp(spec.azimuth_deg, jj, in_row), el));
        }
    }
    out
}

/// The distance at which a sphere of `radius` about the optical target fits the image of `k`
/// (`width × height`) with an 8 % margin: `1.08 · radius / sin(half the narrowest field of view
/// measured from the principal point)`.
pub fn fit_distance(radius: f64, k: &Matrix3<f64>, width: u32, height: u32) -> f64 {
    let (fx, fy, cx, cy) = (k[(0, 0)], k[(1, 1)], k[(0, 2)], k[(1, 2)]);
    let half = [
        (cx / fx).atan(),
        ((width as f64 - cx) / fx).atan(),
        (cy / fy).atan(),
        ((height as f64 - cy) / fy).atan(),
    ]
    .into_iter()
    .fold(f64::INFINITY, f64::min);
    1.08 * radius / half.sin()
}

/// The world-frame cameras of the rig, looking at the rig origin, at `distance` mm.
pub fn cameras(spec: &RigSpec, frame: &Frame, distance: f64) -> Vec<Camera> {
    let [w, h] = spec.resolution;
    let k = intrinsics(w, h);
    let target = frame.center;
    let up = frame.up_world();
    view_angles(spec)
        .into_iter()
        .map(|(az, el)| {
            let (az, el) = (az.to_radians(), el.to_radians());
            // Rig frame: azimuth 0 is the −y direction, positive azimuth towards +x.
            let dir = Vector3::new(el.cos() * az.sin(), -el.cos() * az.cos(), el.sin());
            let eye = frame.to_world(&(dir * distance));
            look_at(eye, target, up, k, w, h)
        })
        .collect()
}

/// `scale_mat` from world-frame vertices: bounding-box centre, largest distance times `margin`.
pub fn normalization(vertices_world: &[[f32; 3]], margin: f64) -> Normalization {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for v in vertices_world {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k] as f64);
            hi[k] = hi[k].max(v[k] as f64);
        }
    }
    let center: [f64; 3] = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
    let radius = vertices_world
        .iter()
        .map(|v| {
            (0..3)
                .map(|k| (v[k] as f64 - center[k]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max);
    Normalization {
        scale: radius * margin,
        center,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_a_proper_rotation_with_up_along_minus_y() {
        let f = Frame::new([1.0, 2.0, 3.0]);
        assert!((f.rotation.determinant() - 1.0).abs() < 1e-15);
        assert_eq!(f.up_world(), Vector3::new(0.0, -1.0, 0.0));
        let p = Vector3::new(0.3, -7.0, 2.5);
        assert!((f.to_rig(&f.to_world(&p)) - p).norm() < 1e-12);
        // The cameras' side (rig −y) is world −z: towards the world origin.
        assert_eq!(
            f.to_world(&Vector3::new(0.0, -1.0, 0.0)) - f.center,
            Vector3::new(0.0, 0.0, -1.0)
        );
    }

    #[test]
    fn dtu_layout_is_seven_by_seven_and_covers_the_ranges() {
        let spec = RigSpec::default();
        let a = view_angles(&spec);
        assert_eq!(a.len(), 49);
        let els: std::collections::BTreeSet<i64> =
            a.iter().map(|&(_, e)| (e * 1e6) as i64).collect();
        assert_eq!(els.len(), 7);
        let min_az = a.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
        let max_el = a.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
        assert_eq!((min_az, max_el), (-45.0, 60.0));
        // Serpentine: the second row starts where the first ended.
        assert_eq!(a[6].0, 45.0);
        assert_eq!(a[7].0, 45.0);
        for n in [1, 2, 3, 5, 10, 64] {
            let s = RigSpec {
                views: n,
                ..RigSpec::default()
            };
            assert_eq!(view_angles(&s).len(), n);
        }
    }

    #[test]
    fn cameras_look_at_the_object_and_see_its_bounding_sphere() {
        let spec = RigSpec::default();
        let frame = Frame::new([-18.0, 42.5, 395.0]);
        let k = intrinsics(400, 300);
        assert!((k[(0, 0)] - 723.08).abs() < 0.01);
        let d = fit_distance(100.0, &k, 400, 300);
        assert!(d > 500.0 && d < 650.0, "{d}");
        for cam in cameras(&spec, &frame, d) {
            assert!((cam.r.determinant() - 1.0).abs() < 1e-12);
            // The object centre projects at the principal point.
            let (u, v, depth) = cam.project(&frame.center).unwrap();
            assert!((u - k[(0, 2)]).abs() < 1e-9 && (v - k[(1, 2)]).abs() < 1e-9);
            assert!((depth - d).abs() < 1e-9);
            // Points on the bounding sphere project inside the image.
            for dir in [Vector3::x(), Vector3::y(), Vector3::z(), -Vector3::x()] {
                let (u, v, _) = cam.project(&(frame.center + dir * 100.0)).unwrap();
                assert!(u > 0.0 && u < 400.0 && v > 0.0 && v < 300.0, "{u} {v}");
            }
            // World up projects upwards in the image (smaller v).
            let (_, v_up, _) = cam.project(&(frame.center + frame.up_world())).unwrap();
            assert!(v_up < k[(1, 2)]);
        }
    }

    #[test]
    fn normalization_is_bbox_centre_and_max_radius_times_margin() {
        let v = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.0, 0.0]];
        let n = normalization(&v, 1.5);
        assert_eq!(n.center, [1.0, 0.5, 0.0]);
        assert!((n.scale - 1.5 * (1.0f64 + 0.25).sqrt()).abs() < 1e-12);
    }
}
