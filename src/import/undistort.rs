//! Undistortion of COLMAP's distorted pinhole-like cameras (SIMPLE_RADIAL, RADIAL, OPENCV) into
//! pinhole images, so that neus-aug's pinhole rays see what the lens saw.
//!
//! Convention (COLMAP `src/colmap/sensor/models.h`, `OpenCVCameraModel::Distortion`; SIMPLE_RADIAL
//! and RADIAL are its special cases `k2 = p1 = p2 = 0` and `p1 = p2 = 0`): a point at normalised
//! undistorted image coordinates `(u, v) = ((x − cx)/fx, (y − cy)/fy)` is seen at
//! `(u + du, v + dv)` with `r² = u² + v²`, `radial = k1·r² + k2·r⁴` and
//! `du = u·radial + 2·p1·u·v + p2·(r² + 2u²)`, `dv = v·radial + 2·p2·u·v + p1·(r² + 2v²)`.
//! Pixel coordinates put the centre of pixel `(i, j)` at `(i + 0.5, j + 0.5)`, as COLMAP's and
//! [`crate::scene::Camera`]'s.
//!
//! The importer keeps the source's `K` and image size for the undistorted pinhole camera
//! (a choice, documented: COLMAP's `image_undistorter` rescales instead so that no output pixel
//! is blank). Output pixels whose distorted position falls outside the source image are black
//! in the image and 0 (background) in the mask. Images are resampled bilinearly, masks by the
//! nearest pixel (a mask stays binary). `tests/colmap_roundtrip.rs` checks the resampling
//! against `colmap image_undistorter`'s output, mapped into the camera that tool chose.

use crate::scene::{GrayImage, RgbImage};
use nalgebra::Matrix3;
use serde::Serialize;

/// The distortion coefficients of COLMAP's OpenCV model (module doc); all zero = none.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Distortion {
    /// Radial, r².
    pub k1: f64,
    /// Radial, r⁴.
    pub k2: f64,
    /// Tangential.
    pub p1: f64,
    /// Tangential.
    pub p2: f64,
}

impl Distortion {
    /// Whether every coefficient is zero (a plain pinhole).
    pub fn is_zero(&self) -> bool {
        [self.k1, self.k2, self.p1, self.p2]
            .iter()
            .all(|&c| c == 0.0)
    }

    /// The smallest normalised radius `r ∈ (0, r_max]` at which the radial part of the model,
    /// `r·(1 + k1·r² + k2·r⁴)`, stops growing, if there is one: where its derivative
    /// `1 + 3·k1·r² + 5·k2·r⁴` (a quadratic in `r²`, 1 at the centre) first reaches 0. Past that
    /// radius the lens model folds back: two undistorted radii map to one distorted one, so an
    /// image undistorted with it repeats parts of the view in rings. (Tangential terms are left
    /// out: they are small in any usable calibration.)
    pub fn radial_fold(&self, r_max: f64) -> Option<f64> {
        let (a, b) = (5.0 * self.k2, 3.0 * self.k1);
        // Roots of a·s² + b·s + 1 = 0, s = r²; the stable pair q/a and 1/q.
        let roots: Vec<f64> = if a == 0.0 {
            if b < 0.0 {
                vec![-1.0 / b]
            } else {
                vec![]
            }
        } else {
            let disc = b * b - 4.0 * a;
            if disc < 0.0 {
                vec![]
            } else {
                let q = -0.5 * (b + b.signum() * disc.sqrt());
                let q = if q == 0.0 { -0.5 * disc.sqrt() } else { q };
                vec![q / a, 1.0 / q]
            }
        };
        roots
            .into_iter()
            .filter(|s| s.is_finite() && *s > 0.0)
            .map(f64::sqrt)
            .filter(|&r| r <= r_max)
            .reduce(f64::min)
    }

    /// Where a point at normalised undistorted coordinates `(u, v)` appears in the distorted
    /// image, in normalised coordinates (module doc).
    pub fn apply(&self, u: f64, v: f64) -> (f64, f64) {
        let (u2, v2, uv) = (u * u, v * v, u * v);
        let r2 = u2 + v2;
        let radial = self.k1 * r2 + self.k2 * r2 * r2;
        let du = u * radial + 2.0 * self.p1 * uv + self.p2 * (r2 + 2.0 * u2);
        let dv = v * radial + 2.0 * self.p2 * uv + self.p1 * (r2 + 2.0 * v2);
        (u + du, v + dv)
    }
}

/// For each pixel of a `width × height` pinhole image with intrinsics `k_dst`, its centre's
/// position (continuous pixel coordinates, pixel `(i, j)` centred at `(i + 0.5, j + 0.5)`) in
/// the distorted source image of intrinsics `k_src`; row-major.
fn source_positions(
    k_src: &Matrix3<f64>,
    dist: &Distortion,
    k_dst: &Matrix3<f64>,
    width: usize,
    height: usize,
) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(width * height);
    for j in 0..height {
        for i in 0..width {
            let u = (i as f64 + 0.5 - k_dst[(0, 2)]) / k_dst[(0, 0)];
            let v = (j as f64 + 0.5 - k_dst[(1, 2)]) / k_dst[(1, 1)];
            let (ud, vd) = dist.apply(u, v);
            out.push((
                k_src[(0, 0)] * ud + k_src[(0, 2)],
                k_src[(1, 1)] * vd + k_src[(1, 2)],
            ));
        }
    }
    out
}

/// `src` (taken through intrinsics `k_src` and distortion `dist`) resampled bilinearly into a
/// `width × height` pinhole image of intrinsics `k_dst`; pixels whose source position lies
/// outside `src` (beyond its outermost pixel centres) are black.
pub fn undistort_rgb(
    src: &RgbImage,
    k_src: &Matrix3<f64>,
    dist: &Distortion,
    k_dst: &Matrix3<f64>,
    width: usize,
    height: usize,
) -> RgbImage {
    let mut out = RgbImage::new(width, height);
    let (w, h) = (src.width as f64, src.height as f64);
    for (p, (x, y)) in source_positions(k_src, dist, k_dst, width, height)
        .into_iter()
        .enumerate()
    {
        // Continuous position in pixel-index units (pixel i's centre at i).
        let (fx, fy) = (x - 0.5, y - 0.5);
        if !(fx >= 0.0 && fy >= 0.0 && fx <= w - 1.0 && fy <= h - 1.0) {
            continue;
        }
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(src.width - 1), (y0 + 1).min(src.height - 1));
        let (ax, ay) = ((fx - x0 as f64) as f32, (fy - y0 as f64) as f32);
        let (a, b, c, d) = (
            src.get(x0, y0),
            src.get(x1, y0),
            src.get(x0, y1),
            src.get(x1, y1),
        );
        for ch in 0..3 {
            let top = a[ch] + ax * (b[ch] - a[ch]);
            let bottom = c[ch] + ax * (d[ch] - c[ch]);
            out.data[p * 3 + ch] = top + ay * (bottom - top);
        }
    }
    out
}

/// `src` resampled like [`undistort_rgb`] but by the nearest pixel (a binary mask stays binary);
/// 0 outside `src`.
pub fn undistort_mask(
    src: &GrayImage,
    k_src: &Matrix3<f64>,
    dist: &Distortion,
    k_dst: &Matrix3<f64>,
    width: usize,
    height: usize,
) -> GrayImage {
    let mut out = GrayImage::new(width, height);
    for (p, (x, y)) in source_positions(k_src, dist, k_dst, width, height)
        .into_iter()
        .enumerate()
    {
        if x >= 0.0 && y >= 0.0 && x < src.width as f64 && y < src.height as f64 {
            out.data[p] = src.get(x as usize, y as usize);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn k() -> Matrix3<f64> {
        Matrix3::new(80.0, 0.0, 32.0, 0.0, 82.0, 24.5, 0.0, 0.0, 1.0)
    }

    #[test]
    fn zero_distortion_is_the_identity() {
        let mut src = RgbImage::new(64, 48);
        for (i, v) in src.data.iter_mut().enumerate() {
            *v = ((i * 37) % 101) as f32 / 100.0;
        }
        let out = undistort_rgb(&src, &k(), &Distortion::default(), &k(), 64, 48);
        let worst = out
            .data
            .iter()
            .zip(&src.data)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-5, "largest change {worst}");
        assert!(Distortion::default().is_zero());
    }

    #[test]
    fn the_radial_fold_is_where_the_radius_stops_growing() {
        let d = |k1: f64, k2: f64| Distortion {
            k1,
            k2,
            ..Default::default()
        };
        // k1 < 0 alone: 1 + 3·k1·r² = 0 at r = 1/sqrt(-3·k1).
        let r = d(-50.0, 0.0).radial_fold(1.0).unwrap();
        assert!((r - 1.0 / 150f64.sqrt()).abs() < 1e-15, "{r}");
        assert_eq!(d(-50.0, 0.0).radial_fold(0.5 * r), None, "beyond the image");
        assert_eq!(d(0.1, 0.0).radial_fold(10.0), None);
        assert_eq!(d(0.0, 0.0).radial_fold(10.0), None);
        // k2 > 0 with a small negative k1 never folds (discriminant < 0); k2 < 0 always does.
        assert_eq!(d(-0.1, 0.05).radial_fold(100.0), None);
        let r = d(0.0, -0.2).radial_fold(10.0).unwrap();
        assert!((1.0 + 5.0 * -0.2 * r.powi(4)).abs() < 1e-12, "{r}");
        // The root found is the first: the model's radius grows up to it and shrinks just after.
        let m = d(-0.6, 0.1);
        let r = m.radial_fold(10.0).unwrap();
        let radial = |r: f64| m.apply(r, 0.0).0;
        assert!(
            radial(r - 1e-4) < radial(r) && radial(r + 1e-4) < radial(r),
            "{r}"
        );
        for i in 1..100 {
            let s = r * i as f64 / 100.0;
            assert!(radial(s - 1e-6) < radial(s), "not increasing at {s}");
        }
    }

    #[test]
    fn a_point_lands_where_the_distortion_sends_it() {
        // A white dot drawn where the OpenCV model sends the undistorted point (u, v) = (0.2,
        // -0.1) comes back at (u, v) in the undistorted image.
        let dist = Distortion {
            k1: -0.2,
            k2: 0.05,
            p1: 0.01,
            p2: -0.005,
        };
        let (u, v) = (0.2, -0.1);
        let (ud, vd) = dist.apply(u, v);
        let kk = k();
        let (xd, yd) = (kk[(0, 0)] * ud + kk[(0, 2)], kk[(1, 1)] * vd + kk[(1, 2)]);
        let mut src = GrayImage::new(64, 48);
        src.data[yd as usize * 64 + xd as usize] = 1.0;
        let out = undistort_mask(&src, &kk, &dist, &kk, 64, 48);
        let (xu, yu) = (kk[(0, 0)] * u + kk[(0, 2)], kk[(1, 1)] * v + kk[(1, 2)]);
        let lit: Vec<(usize, usize)> = (0..48 * 64)
            .filter(|&p| out.data[p] > 0.5)
            .map(|p| (p % 64, p / 64))
            .collect();
        assert!(!lit.is_empty());
        for (x, y) in lit {
            assert!(
                (x as f64 + 0.5 - xu).abs() < 1.5 && (y as f64 + 0.5 - yu).abs() < 1.5,
                "({x}, {y}) against ({xu}, {yu})"
            );
        }
        // With k1 > 0 the corners of the undistorted image come from beyond the source's edge:
        // they stay black (0).
        let barrel = Distortion {
            k1: 0.5,
            ..Default::default()
        };
        let full = GrayImage {
            width: 64,
            height: 48,
            data: vec![1.0; 64 * 48],
        };
        let out = undistort_mask(&full, &kk, &barrel, &kk, 64, 48);
        assert_eq!(out.data[0], 0.0, "a corner maps outside the source");
        assert_eq!(out.data[24 * 64 + 32], 1.0, "the centre maps onto itself");
    }
}
