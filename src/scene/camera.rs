//! Pinhole cameras in the OpenCV convention, projection-matrix decomposition, rays.
//!
//! Conventions (one place for them; Totoro97/NeuS `models/dataset.py`, lioryariv/idr
//! `DATA_CONVENTION.md`):
//! - Camera frame: x right, y down, z forward (OpenCV, as IDR and NeuS use it).
//! - A world point `X` projects to `λ·[u, v, 1]ᵀ = K·R·(X − C)`, with `K` upper triangular,
//!   positive focal lengths and `K[2,2] = 1`, `R` the world-to-camera rotation (`det R = +1`)
//!   and `C` the camera centre. The camera-to-world pose is `c2w = [Rᵀ | C]`.
//! - Pixel `(x, y)` covers `[x, x+1) × [y, y+1)`, so its centre is at `(x + 0.5, y + 0.5)`
//!   (instant-nsr-pl `datasets/utils.py` `get_ray_directions(use_pixel_centers=True)`; note that
//!   Totoro97/NeuS samples at integer coordinates instead).
//! - Which space a [`Camera`] lives in is the owner's business: a loaded
//!   [`Scene`](super::Scene) holds cameras in the normalised space (object inside the unit
//!   sphere), because NeuS decomposes `P = world_mat · scale_mat`.

use nalgebra::{Matrix3, Matrix3x4, Matrix4, Vector3};

/// Why a projection matrix cannot be a camera.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CameraError {
    /// An entry is NaN or infinite.
    #[error("projection matrix has a non-finite entry")]
    NonFinite,
    /// The left 3×3 block is (numerically) singular: no camera centre or rotation exists.
    #[error("projection matrix is singular (|det M| / |M|³ = {0:.3e})")]
    Singular(f64),
    /// The image size is zero.
    #[error("image size {0}×{1} is empty")]
    EmptyImage(u32, u32),
}

/// A pinhole camera: intrinsics, pose and image size. Units: pixels for `k`, the owning space's
/// length unit for `center`.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Intrinsics `K` (pixels): `[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`, `fx, fy > 0`.
    pub k: Matrix3<f64>,
    /// World-to-camera rotation `R` (`x_cam = R·(X − C)`), `det R = +1`.
    pub r: Matrix3<f64>,
    /// Camera centre `C`.
    pub center: Vector3<f64>,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// RQ decomposition of a 3×3 matrix with positive determinant: `m = k·r` with `k` upper
/// triangular with a positive diagonal and `r` a rotation (`det r = +1`).
///
/// Method: QR of `(J·m)ᵀ` with the exchange matrix `J`, then `k = J·Uᵀ·J`, `r = J·Qᵀ`, then flip
/// signs so the diagonal of `k` is positive (Hartley & Zisserman, *Multiple View Geometry*, 2nd
/// ed., A4.1.1).
fn rq(m: &Matrix3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
    let j = Matrix3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0);
    let qr = (j * m).transpose().qr();
    let (q, u) = (qr.q(), qr.r());
    let mut k = j * u.transpose() * j;
    let mut r = j * q.transpose();
    for i in 0..3 {
        if k[(i, i)] < 0.0 {
            // K·D and D·R with D = diag(±1): the product is unchanged.
            k.column_mut(i).neg_mut();
            r.row_mut(i).neg_mut();
        }
    }
    (k, r)
}

impl Camera {
    /// Decomposes a 3×4 projection matrix `P ~ K·[R | −R·C]` (any scale, either sign), as
    /// `cv2.decomposeProjectionMatrix` does for NeuS (`models/dataset.py` `load_K_Rt_from_P`):
    /// `K` is divided by `K[2,2]`, focal lengths come out positive and `det R = +1`.
    pub fn from_projection(
        p: &Matrix3x4<f64>,
        width: u32,
        height: u32,
    ) -> Result<Self, CameraError> {
        if width == 0 || height == 0 {
            return Err(CameraError::EmptyImage(width, height));
        }
        if p.iter().any(|v| !v.is_finite()) {
            return Err(CameraError::NonFinite);
        }
        let mut m: Matrix3<f64> = p.fixed_view::<3, 3>(0, 0).into_owned();
        let norm = m.norm();
        let det = m.determinant();
        let conditioning = if norm > 0.0 {
            det.abs() / norm.powi(3)
        } else {
            0.0
        };
        // `is_nan` catches 0/0 from an all-zero block.
        if conditioning.is_nan() || conditioning <= 1e-12 {
            return Err(CameraError::Singular(conditioning));
        }
        // P is defined up to scale: a negative determinant means the matrix was scaled by a
        // negative number, which flips nothing geometrically.
        if det < 0.0 {
            m = -m;
        }
        let p4: Vector3<f64> = p.column(3).into_owned();
        let center = -(p
            .fixed_view::<3, 3>(0, 0)
            .into_owned()
            .try_inverse()
            .ok_or(CameraError::Singular(conditioning))?
            * p4);
        let (mut k, r) = rq(&m);
        k /= k[(2, 2)];
        Ok(Self {
            k,
            r,
            center,
            width,
            height,
        })
    }

    /// The 3×4 projection matrix `K·[R | −R·C]`.
    pub fn projection(&self) -> Matrix3x4<f64> {
        let t = -(self.r * self.center);
        let mut rt = Matrix3x4::zeros();
        rt.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.r);
        rt.set_column(3, &t);
        self.k * rt
    }

    /// The 4×4 camera-to-world pose `[[Rᵀ, C], [0, 0, 0, 1]]` (OpenCV axes).
    pub fn c2w(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&self.r.transpose());
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.center);
        m
    }

    /// Projects a point to continuous pixel coordinates `(u, v)` and its depth along the optical
    /// axis. `None` for points at or behind the camera plane.
    pub fn project(&self, x: &Vector3<f64>) -> Option<(f64, f64, f64)> {
        let xc = self.r * (x - self.center);
        if xc.z <= 0.0 {
            return None;
        }
        let h = self.k * xc;
        Some((h.x / h.z, h.y / h.z, xc.z))
    }

    /// The ray through continuous pixel coordinates `(u, v)`: origin `C` and unit direction.
    /// The centre of pixel `(x, y)` is `(x + 0.5, y + 0.5)`.
    pub fn ray(&self, u: f64, v: f64) -> (Vector3<f64>, Vector3<f64>) {
        let d_cam = self
            .k
            .try_inverse()
            .expect("K is upper triangular with a positive diagonal")
            * Vector3::new(u, v, 1.0);
        (self.center, (self.r.transpose() * d_cam).normalize())
    }

    /// This camera seen from a space related by `X = s·X' + c` (e.g. world → normalised with the
    /// scene's `scale_mat`): the centre becomes `(C − c)/s`; `K` and `R` are unchanged.
    pub fn normalized(&self, scale: f64, offset: &Vector3<f64>) -> Self {
        Self {
            center: (self.center - offset) / scale,
            ..self.clone()
        }
    }

    /// The inverse of [`Camera::normalized`]: centre `s·C + c`.
    pub fn denormalized(&self, scale: f64, offset: &Vector3<f64>) -> Self {
        Self {
            center: self.center * scale + offset,
            ..self.clone()
        }
    }

    /// The inverse of [`Camera::downscaled`]: `K = diag(f, f, 1)·K'`, for an image of
    /// `width × height` pixels (the original size, which the downscale's floor lost).
    pub fn upscaled(&self, factor: u32, width: u32, height: u32) -> Self {
        let f = factor as f64;
        let mut k = self.k;
        for c in 0..3 {
            k[(0, c)] *= f;
            k[(1, c)] *= f;
        }
        Self {
            k,
            width,
            height,
            ..self.clone()
        }
    }

    /// Horizontal and vertical fields of view in degrees.
    pub fn fov_degrees(&self) -> (f64, f64) {
        let fx = self.k[(0, 0)];
        let fy = self.k[(1, 1)];
        (
            2.0 * (self.width as f64 / (2.0 * fx)).atan().to_degrees(),
            2.0 * (self.height as f64 / (2.0 * fy)).atan().to_degrees(),
        )
    }

    /// The same camera for an image downscaled by an integer `factor`: continuous pixel
    /// coordinates divide by `factor` (pixel-centre convention preserved exactly), so
    /// `K' = diag(1/f, 1/f, 1)·K`; the size is `floor(size / factor)`.
    pub fn downscaled(&self, factor: u32) -> Self {
        let f = factor as f64;
        let mut k = self.k;
        for c in 0..3 {
            k[(0, c)] /= f;
            k[(1, c)] /= f;
        }
        Self {
            k,
            width: self.width / factor,
            height: self.height / factor,
            ..self.clone()
        }
    }
}

/// A pinhole's intrinsics with focal length `f` pixels on both axes and the principal point at
/// the centre of a `width × height` image (test rigs).
pub fn centred_intrinsics(f: f64, width: u32, height: u32) -> Matrix3<f64> {
    let (cx, cy) = (width as f64 / 2.0, height as f64 / 2.0);
    Matrix3::new(f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0)
}

/// A camera at `eye` looking at `target` with `up` pointing to the image's top (OpenCV axes:
/// x right, y down, z forward; `x = z × up`, `y = z × x`).
pub fn look_at(
    eye: Vector3<f64>,
    target: Vector3<f64>,
    up: Vector3<f64>,
    k: Matrix3<f64>,
    width: u32,
    height: u32,
) -> Camera {
    let z = (target - eye).normalize();
    let x = z.cross(&up).normalize();
    let y = z.cross(&x);
    Camera {
        k,
        r: Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]),
        center: eye,
        width,
        height,
    }
}

/// The pixel `(x, y)` whose square holds the projection of `x` (the camera's frame of
/// reference), `None` when the point is behind the camera or outside its image.
pub fn pixel_of(cam: &Camera, x: &Vector3<f64>) -> Option<(usize, usize)> {
    let (u, v, _) = cam.project(x)?;
    (u >= 0.0 && v >= 0.0 && u < cam.width as f64 && v < cam.height as f64)
        .then(|| (u.floor() as usize, v.floor() as usize))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use nalgebra::{Rotation3, Unit};
    use rand::{Rng, SeedableRng};

    /// `n` 64×48 cameras (f = 200 px) on a circle of radius 3 about the z axis, `step` radians
    /// apart, at height `lift(i)`, looking at the origin.
    pub(crate) fn orbit(n: usize, step: f64, lift: impl Fn(usize) -> f64) -> Vec<Camera> {
        (0..n)
            .map(|i| {
                let a = i as f64 * step;
                look_at(
                    Vector3::new(a.cos() * 3.0, a.sin() * 3.0, lift(i)),
                    Vector3::zeros(),
                    Vector3::z(),
                    centred_intrinsics(200.0, 64, 48),
                    64,
                    48,
                )
            })
            .collect()
    }

    /// A random camera looking roughly at the origin from distance 2-4 (normalised-like space).
    pub(crate) fn random_camera(rng: &mut impl Rng) -> Camera {
        let axis = Unit::new_normalize(Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ));
        let r = Rotation3::from_axis_angle(&axis, rng.random_range(-3.0..3.0)).into_inner();
        let k = Matrix3::new(
            rng.random_range(300.0..3000.0),
            rng.random_range(-2.0..2.0),
            rng.random_range(100.0..900.0),
            0.0,
            rng.random_range(300.0..3000.0),
            rng.random_range(100.0..700.0),
            0.0,
            0.0,
            1.0,
        );
        let center = Vector3::new(
            rng.random_range(-4.0..4.0),
            rng.random_range(-4.0..4.0),
            rng.random_range(-4.0..4.0),
        );
        Camera {
            k,
            r,
            center,
            width: 1000,
            height: 800,
        }
    }

    fn rel(a: f64, b: f64, scale: f64) -> f64 {
        (a - b).abs() / scale.max(1e-300)
    }

    #[test]
    fn decomposition_inverts_projection_for_any_scale_and_sign() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        for trial in 0..200 {
            let cam = random_camera(&mut rng);
            let scale = if trial % 2 == 0 { 3.7 } else { -0.02 };
            let back = Camera::from_projection(&(cam.projection() * scale), 1000, 800).unwrap();
            let mut worst: f64 = 0.0;
            for i in 0..3 {
                for j in 0..3 {
                    worst = worst.max(rel(back.k[(i, j)], cam.k[(i, j)], cam.k.norm()));
                    worst = worst.max((back.r[(i, j)] - cam.r[(i, j)]).abs());
                }
                worst = worst.max(rel(back.center[i], cam.center[i], cam.center.norm()));
            }
            assert!(worst < 1e-10, "trial {trial}: relative error {worst:e}");
            assert!((back.r.determinant() - 1.0).abs() < 1e-12);
            assert!(back.k[(0, 0)] > 0.0 && back.k[(1, 1)] > 0.0 && back.k[(2, 2)] == 1.0);
        }
    }

    #[test]
    fn pixel_centre_ray_projects_back_to_the_pixel() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(11);
        for _ in 0..100 {
            let cam = random_camera(&mut rng);
            let (x, y) = (
                rng.random_range(0..cam.width),
                rng.random_range(0..cam.height),
            );
            let (u, v) = (x as f64 + 0.5, y as f64 + 0.5);
            let (o, d) = cam.ray(u, v);
            assert!((d.norm() - 1.0).abs() < 1e-12);
            let (pu, pv, depth) = cam.project(&(o + d * rng.random_range(0.1..10.0))).unwrap();
            assert!(depth > 0.0);
            assert!(
                (pu - u).abs() < 1e-6 && (pv - v).abs() < 1e-6,
                "{pu},{pv} vs {u},{v}"
            );
        }
    }

    #[test]
    fn singular_and_non_finite_matrices_are_rejected() {
        let mut p = Matrix3x4::zeros();
        p[(0, 0)] = 1.0;
        p[(1, 1)] = 1.0;
        assert!(matches!(
            Camera::from_projection(&p, 10, 10),
            Err(CameraError::Singular(_))
        ));
        let mut q = Matrix3x4::identity();
        q[(1, 3)] = f64::NAN;
        assert_eq!(
            Camera::from_projection(&q, 10, 10),
            Err(CameraError::NonFinite)
        );
        assert_eq!(
            Camera::from_projection(&Matrix3x4::identity(), 0, 10),
            Err(CameraError::EmptyImage(0, 10))
        );
    }

    #[test]
    fn downscaling_keeps_pixel_centres() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
        let cam = random_camera(&mut rng);
        let small = cam.downscaled(4);
        assert_eq!((small.width, small.height), (250, 200));
        // The centre of a 4×4 block of fine pixels is the centre of the coarse pixel.
        let (_, d_fine) = cam.ray(4.0 * 10.0 + 2.0, 4.0 * 20.0 + 2.0);
        let (_, d_coarse) = small.ray(10.5, 20.5);
        assert!((d_fine - d_coarse).norm() < 1e-12);
        // Upscaling undoes it, the original size given back.
        let back = small.upscaled(4, cam.width, cam.height);
        assert!((back.k - cam.k).norm() < 1e-12 * cam.k.norm());
        assert_eq!((back.width, back.height), (cam.width, cam.height));
    }
}
