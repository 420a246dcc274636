//! Real spherical harmonics of degree 4 (bands 0–3, 16 coefficients) of a unit direction, as in
//! tiny-cuda-nn's `SphericalHarmonics` encoding with `degree: 4` (instant-nsr-pl
//! `dir_encoding_config`; tcnn maps its `[0,1]` input back to `[-1,1]`, so the net effect is the SH
//! of the direction itself). Constants are the standard real-SH normalisations
//! (e.g. Sloan, "Stupid Spherical Harmonics Tricks", 2008), with tcnn's sign convention.
//!
//! Directions are not trained, but the backward (gradient with respect to the direction) is
//! provided and checked so the encoding can sit anywhere in a differentiable pipeline.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::Real;

/// Number of coefficients (`4²`).
pub const SH_DIM: usize = 16;

const C0: f64 = 0.282_094_791_773_878_14;
const C1: f64 = 0.488_602_511_902_919_9;
const C2A: f64 = 1.092_548_430_592_079_2;
const C2B: f64 = 0.946_174_695_757_56;
const C2C: f64 = 0.315_391_565_252_52;
const C2D: f64 = 0.546_274_215_296_039_6;
const C3A: f64 = 0.590_043_589_926_643_5;
const C3B: f64 = 2.890_611_442_640_554;
const C3C: f64 = 0.457_045_799_464_465_7;
const C3D: f64 = 0.373_176_332_590_115_4;
const C3E: f64 = 1.445_305_721_320_277;

/// `out[16]` ← SH basis at direction `d = (x, y, z)` (unit length expected, not enforced).
#[inline]
pub fn sh4<T: Real>(d: [T; 3], out: &mut [T]) {
    let c = |v: f64| T::from_f64(v);
    let [x, y, z] = d;
    let (xx, yy, zz) = (x * x, y * y, z * z);
    out[0] = c(C0);
    out[1] = -c(C1) * y;
    out[2] = c(C1) * z;
    out[3] = -c(C1) * x;
    out[4] = c(C2A) * x * y;
    out[5] = -c(C2A) * y * z;
    out[6] = c(C2B) * zz - c(C2C);
    out[7] = -c(C2A) * x * z;
    out[8] = c(C2D) * (xx - yy);
    out[9] = c(C3A) * y * (yy - c(3.0) * xx);
    out[10] = c(C3B) * x * y * z;
    out[11] = c(C3C) * y * (T::ONE - c(5.0) * zz);
    out[12] = c(C3D) * z * (c(5.0) * zz - c(3.0));
    out[13] = c(C3C) * x * (T::ONE - c(5.0) * zz);
    out[14] = c(C3E) * z * (xx - yy);
    out[15] = c(C3A) * x * (c(3.0) * yy - xx);
}

/// Gradient of `Σ_k d_out[k]·sh4(d)[k]` with respect to `d`.
#[inline]
pub fn sh4_backward<T: Real>(d: [T; 3], d_out: &[T]) -> [T; 3] {
    let c = |v: f64| T::from_f64(v);
    let [x, y, z] = d;
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let g = d_out;
    let mut gx = T::ZERO;
    let mut gy = T::ZERO;
    let mut gz = T::ZERO;
    gy += -c(C1) * g[1];
    gz += c(C1) * g[2];
    gx += -c(C1) * g[3];
    gx += c(C2A) * y * g[4];
    gy += c(C2A) * x * g[4];
    gy += -c(C2A) * z * g[5];
    gz += -c(C2A) * y * g[5];
    gz += c(2.0 * C2B) * z * g[6];
    gx += -c(C2A) * z * g[7];
    gz += -c(C2A) * x * g[7];
    gx += c(2.0 * C2D) * x * g[8];
    gy += -c(2.0 * C2D) * y * g[8];
    gx += -c(6.0 * C3A) * x * y * g[9];
    gy += c(3.0 * C3A) * (yy - xx) * g[9];
    gx += c(C3B) * y * z * g[10];
    gy += c(C3B) * x * z * g[10];
    gz += c(C3B) * x * y * g[10];
    gy += c(C3C) * (T::ONE - c(5.0) * zz) * g[11];
    gz += -c(10.0 * C3C) * y * z * g[11];
    gz += c(C3D) * (c(15.0) * zz - c(3.0)) * g[12];
    gx += c(C3C) * (T::ONE - c(5.0) * zz) * g[13];
    gz += -c(10.0 * C3C) * x * z * g[13];
    gx += c(2.0 * C3E) * x * z * g[14];
    gy += -c(2.0 * C3E) * y * z * g[14];
    gz += c(C3E) * (xx - yy) * g[14];
    gx += c(3.0 * C3A) * (yy - xx) * g[15];
    gy += c(6.0 * C3A) * x * y * g[15];
    [gx, gy, gz]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 16 functions are orthonormal on the sphere: check by quadrature on a Fibonacci grid.
    #[test]
    fn sh_is_orthonormal() {
        let n = 20000;
        let mut gram = [[0.0f64; SH_DIM]; SH_DIM];
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let mut v = [0.0; SH_DIM];
        for i in 0..n {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            sh4([r * phi.cos(), r * phi.sin(), z], &mut v);
            for a in 0..SH_DIM {
                for b in 0..SH_DIM {
                    gram[a][b] += v[a] * v[b] * 4.0 * std::f64::consts::PI / n as f64;
                }
            }
        }
        let mut fails = Vec::new();
        for a in 0..SH_DIM {
            for b in 0..SH_DIM {
                let want = if a == b { 1.0 } else { 0.0 };
                if (gram[a][b] - want).abs() > 2e-3 {
                    fails.push(format!("<Y{a},Y{b}> = {}", gram[a][b]));
                }
            }
        }
        assert!(fails.is_empty(), "{}", fails.join("\n"));
    }

    #[test]
    fn sh_backward_matches_central_differences() {
        let w: Vec<f64> = (0..SH_DIM)
            .map(|k| ((k * 37 % 11) as f64 - 5.0) / 3.0)
            .collect();
        let f = |d: [f64; 3]| {
            let mut o = [0.0; SH_DIM];
            sh4(d, &mut o);
            o.iter().zip(&w).map(|(a, b)| a * b).sum::<f64>()
        };
        let mut fails = Vec::new();
        for d in [
            [0.3, -0.4, 0.866],
            [1.0, 0.0, 0.0],
            [-0.2, 0.9, -0.1],
            [0.0, 0.0, -1.0],
        ] {
            let g = sh4_backward(d, &w);
            for k in 0..3 {
                let h = 1e-6;
                let mut dp = d;
                dp[k] += h;
                let mut dm = d;
                dm[k] -= h;
                let fd = (f(dp) - f(dm)) / (2.0 * h);
                if (fd - g[k]).abs() > 1e-7 + 1e-6 * fd.abs() {
                    fails.push(format!("dir {d:?} axis {k}: analytic {} fd {fd}", g[k]));
                }
            }
        }
        assert!(fails.is_empty(), "{}", fails.join("\n"));
    }
}
