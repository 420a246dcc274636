//! Front-to-back compositing of one ray (Max 1995; NeuS eq. 13; nerfacc
//! `render_weight_from_alpha` + `accumulate_along_rays` as used by instant-nsr-pl):
//!
//! `T_0 = 1`, `w_i = α_i·T_i`, `T_{i+1} = T_i·(1 − α_i)`;
//! colour `C = Σ w_i c_i + bg·(1 − O)` with opacity `O = Σ w_i`, depth `D = Σ w_i t_i`,
//! normal `N = normalize(Σ w_i n_i)` (output only; no loss uses it).
//!
//! The backward never divides by `1 − α` (all-ones alphas are fine): with `q_i = ∂L/∂w_i` and the
//! suffix sums `S_m = 0`, `S_i = α_i q_i + (1 − α_i) S_{i+1}`, it is `∂L/∂α_i = T_i (q_i − S_{i+1})`.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use crate::field::Real;

/// Composited values of one ray.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Composite<T> {
    /// Colour including the background, `[3]`.
    pub rgb: [T; 3],
    /// `Σ w_i` in `[0,1]`.
    pub opacity: T,
    /// `Σ w_i t_i` (normalised units along the ray; not divided by the opacity).
    pub depth: T,
    /// `normalize(Σ w_i n_i)`; zero when the sum is zero.
    pub normal: [T; 3],
}

/// Forward compositing. `alpha [m]`, `rgb [m][3]`, `t [m]` (midpoints), `normal [m][3]`.
pub fn composite_forward<T: Real>(
    alpha: &[T],
    rgb: &[[T; 3]],
    t: &[T],
    normal: &[[T; 3]],
    bg: [T; 3],
) -> Composite<T> {
    let mut out = Composite::default();
    let mut trans = T::ONE;
    let mut nsum = [T::ZERO; 3];
    for i in 0..alpha.len() {
        let w = alpha[i] * trans;
        for k in 0..3 {
            out.rgb[k] += w * rgb[i][k];
            nsum[k] += w * normal[i][k];
        }
        out.opacity += w;
        out.depth += w * t[i];
        trans *= T::ONE - alpha[i];
    }
    for k in 0..3 {
        out.rgb[k] += bg[k] * (T::ONE - out.opacity);
    }
    let len = (nsum[0] * nsum[0] + nsum[1] * nsum[1] + nsum[2] * nsum[2]).sqrt();
    let len = len.maxv(T::from_f64(1e-12));
    out.normal = [nsum[0] / len, nsum[1] / len, nsum[2] / len];
    out
}

/// Backward of [`composite_forward`] for the loss terms on colour and opacity (and depth):
/// given `g_rgb = ∂L/∂C`, `g_opacity`, `g_depth`, writes `d_alpha [m]` and `d_rgb [m][3]`.
#[allow(clippy::too_many_arguments)]
pub fn composite_backward<T: Real>(
    alpha: &[T],
    rgb: &[[T; 3]],
    t: &[T],
    bg: [T; 3],
    g_rgb: [T; 3],
    g_opacity: T,
    g_depth: T,
    d_alpha: &mut [T],
    d_rgb: &mut [[T; 3]],
) {
    let m = alpha.len();
    // q_i = ∂L/∂w_i, with C = bg + Σ w_i (c_i − bg).
    let q = |i: usize| {
        let mut s = g_opacity + g_depth * t[i];
        for k in 0..3 {
            s += g_rgb[k] * (rgb[i][k] - bg[k]);
        }
        s
    };
    // Forward transmittances.
    let mut trans = T::ONE;
    for i in 0..m {
        let w = alpha[i] * trans;
        for k in 0..3 {
            d_rgb[i][k] = w * g_rgb[k];
        }
        d_alpha[i] = trans; // temporarily T_i
        trans *= T::ONE - alpha[i];
    }
    let mut suffix = T::ZERO;
    for i in (0..m).rev() {
        let qi = q(i);
        let ti = d_alpha[i];
        d_alpha[i] = ti * (qi - suffix);
        suffix = alpha[i] * qi + (T::ONE - alpha[i]) * suffix;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn loss(a: &[f64], c: &[[f64; 3]], t: &[f64], bg: [f64; 3], g: [f64; 5]) -> f64 {
        let n = vec![[0.0, 0.0, 1.0]; a.len()];
        let o = composite_forward(a, c, t, &n, bg);
        g[0] * o.rgb[0] + g[1] * o.rgb[1] + g[2] * o.rgb[2] + g[3] * o.opacity + g[4] * o.depth
    }

    #[test]
    fn backward_matches_central_differences() {
        let bg = [1.0, 0.5, 0.2];
        let g = [0.3, -1.2, 0.7, 0.9, -0.4];
        let mut fails = Vec::new();
        for alphas in [
            vec![0.1, 0.5, 0.3, 0.9, 0.2],
            vec![1.0, 1.0, 1.0],
            vec![0.0, 0.0],
            vec![0.999, 0.4],
        ] {
            let m = alphas.len();
            let c: Vec<[f64; 3]> = (0..m)
                .map(|i| [0.1 * i as f64, 0.5, 1.0 - 0.2 * i as f64])
                .collect();
            let t: Vec<f64> = (0..m).map(|i| 0.5 + 0.1 * i as f64).collect();
            let mut da = vec![0.0; m];
            let mut dc = vec![[0.0; 3]; m];
            composite_backward(
                &alphas,
                &c,
                &t,
                bg,
                [g[0], g[1], g[2]],
                g[3],
                g[4],
                &mut da,
                &mut dc,
            );
            assert!(da.iter().all(|v| v.is_finite()));
            let h = 1e-6;
            for i in 0..m {
                let mut ap = alphas.clone();
                ap[i] += h;
                let mut am = alphas.clone();
                am[i] -= h;
                let fd = (loss(&ap, &c, &t, bg, g) - loss(&am, &c, &t, bg, g)) / (2.0 * h);
                if (fd - da[i]).abs() > 1e-7 + 1e-6 * fd.abs() {
                    fails.push(format!(
                        "alphas {alphas:?} d_alpha[{i}]: {} vs fd {fd}",
                        da[i]
                    ));
                }
                for k in 0..3 {
                    let mut cp = c.clone();
                    cp[i][k] += h;
                    let mut cm = c.clone();
                    cm[i][k] -= h;
                    let fd =
                        (loss(&alphas, &cp, &t, bg, g) - loss(&alphas, &cm, &t, bg, g)) / (2.0 * h);
                    if (fd - dc[i][k]).abs() > 1e-7 + 1e-6 * fd.abs() {
                        fails.push(format!(
                            "alphas {alphas:?} d_rgb[{i}][{k}]: {} vs fd {fd}",
                            dc[i][k]
                        ));
                    }
                }
            }
        }
        assert!(fails.is_empty(), "{}", fails.join("\n"));
    }

    #[test]
    fn limits() {
        let n = [[0.0, 0.0, 2.0]; 3];
        // All alphas 1: the first sample takes everything.
        let o = composite_forward(
            &[1.0, 1.0, 1.0],
            &[[0.2, 0.4, 0.6], [1.0; 3], [1.0; 3]],
            &[1.0, 2.0, 3.0],
            &n,
            [1.0; 3],
        );
        assert_eq!(o.rgb, [0.2, 0.4, 0.6]);
        assert_eq!(o.opacity, 1.0);
        assert_eq!(o.depth, 1.0);
        assert_eq!(o.normal, [0.0, 0.0, 1.0]);
        // No samples: background, zero opacity, zero (finite) normal.
        let e = composite_forward::<f64>(&[], &[], &[], &[], [0.3, 0.2, 0.1]);
        assert_eq!(e.rgb, [0.3, 0.2, 0.1]);
        assert_eq!(e.opacity, 0.0);
        assert_eq!(e.normal, [0.0; 3]);
    }
}
