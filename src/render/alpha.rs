//! The NeuS alpha (Wang et al., "NeuS", NeurIPS 2021, §3.3 discrete opacity), in instant-nsr-pl's
//! form (`models/neus.py`, `NeuSModel.get_alpha`): with `s = inv_s`, the annealed cosine
//!
//! `c = −(relu(0.5 − 0.5·cos)·(1 − a) + relu(−cos)·a)`   (`a` = cos anneal ratio, 0 → 1)
//!
//! the section SDFs `prev = f − c·Δt/2`, `next = f + c·Δt/2`, and
//!
//! `α = clip((σ(s·prev) − σ(s·next) + 1e-5) / (σ(s·prev) + 1e-5), 0, 1)`.
//!
//! This is the **one** alpha implementation: training, rendering and occupancy-grid updates (which
//! use `cos = −1`, giving `f ± Δt/2` exactly as the reference's `occ_eval_fn`) all call it.
//! Sigmoids are evaluated in the overflow-free form, so `s` up to 1e6 gives finite values and
//! finite (possibly zero) derivatives.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use crate::field::{sigmoid, Real};

/// `inv_s = exp(10·v)` clipped to `[1e-6, 1e6]` (instant-nsr-pl `VarianceNetwork.inv_s` and the
/// `.clip(1e-6, 1e6)` in `get_alpha`). Returns `(inv_s, d inv_s / d v)`; the derivative is 0 where
/// the clip is active (PyTorch `clamp` passes gradient only inside the closed interval).
#[inline]
pub fn inv_s_from_variance<T: Real>(v: T) -> (T, T) {
    let s = (T::from_f64(10.0) * v).exp();
    let lo = T::from_f64(1e-6);
    let hi = T::from_f64(1e6);
    if s < lo {
        (lo, T::ZERO)
    } else if s > hi || !s.is_finite() {
        (hi, T::ZERO)
    } else {
        (s, T::from_f64(10.0) * s)
    }
}

/// Partial derivatives of α with respect to its differentiable inputs.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AlphaGrad<T> {
    pub d_sdf: T,
    pub d_cos: T,
    pub d_inv_s: T,
}

/// α of one interval: `sdf` at its midpoint, `cos = dir·normal`, length `dt`, `inv_s`, anneal
/// ratio `anneal ∈ [0,1]`. Returns α and, when `GRAD`, its partial derivatives (zeros otherwise).
#[inline(always)]
pub fn neus_alpha<T: Real, const GRAD: bool>(
    sdf: T,
    cos: T,
    dt: T,
    inv_s: T,
    anneal: T,
) -> (T, AlphaGrad<T>) {
    let half_c = T::from_f64(0.5);
    let eps = T::from_f64(1e-5);
    let r1 = half_c - half_c * cos;
    let r2 = -cos;
    let iter_cos = -(r1.maxv(T::ZERO) * (T::ONE - anneal) + r2.maxv(T::ZERO) * anneal);
    let half = iter_cos * dt * half_c;
    let prev = sdf - half;
    let next = sdf + half;
    let xp = prev * inv_s;
    let xn = next * inv_s;
    let pc = sigmoid(xp);
    let nc = sigmoid(xn);
    let raw = (pc - nc + eps) / (pc + eps);
    let alpha = raw.maxv(T::ZERO).minv(T::ONE);
    if !GRAD {
        return (alpha, AlphaGrad::default());
    }
    // Clip passes the gradient inside the closed interval only.
    if !(raw >= T::ZERO && raw <= T::ONE) {
        return (alpha, AlphaGrad::default());
    }
    let den = pc + eps;
    let d_pc = nc / (den * den); // ∂raw/∂pc  (raw = 1 − nc/(pc+ε))
    let d_nc = -T::ONE / den; // ∂raw/∂nc
    let spc = pc * sigmoid(-xp); // σ'(xp) without cancellation
    let snc = nc * sigmoid(-xn);
    let a = d_pc * spc; // ∂raw/∂xp
    let b = d_nc * snc; // ∂raw/∂xn
    let d_sdf = (a + b) * inv_s;
    let d_half = (b - a) * inv_s;
    let mut d_iter = T::ZERO;
    if r1 > T::ZERO {
        d_iter += half_c * (T::ONE - anneal);
    }
    if r2 > T::ZERO {
        d_iter += anneal;
    }
    let d_cos = d_half * dt * half_c * d_iter;
    let d_inv_s = a * prev + b * next;
    (
        alpha,
        AlphaGrad {
            d_sdf,
            d_cos,
            d_inv_s,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alpha_gradient_matches_central_differences() {
        let mut fails = Vec::new();
        let cases = [
            (0.01, -0.7, 0.01, 50.0, 0.3),
            (-0.02, -0.2, 0.004, 300.0, 1.0),
            (0.1, 0.4, 0.02, 20.0, 0.0),
            (0.0, -1.0, 0.003, 1000.0, 0.5),
            (0.003, 0.9, 0.01, 64.0, 0.7),
        ];
        for &(f, c, dt, s, a) in &cases {
            let (_, g) = neus_alpha::<f64, true>(f, c, dt, s, a);
            let h = 1e-7;
            let num = |df: f64, dc: f64, ds: f64| {
                (neus_alpha::<f64, false>(f + df, c + dc, dt, s + ds * s, a).0
                    - neus_alpha::<f64, false>(f - df, c - dc, dt, s - ds * s, a).0)
                    / 2.0
            };
            let fd_sdf = num(h, 0.0, 0.0) / h;
            let fd_cos = num(0.0, h, 0.0) / h;
            let fd_s = num(0.0, 0.0, h) / (h * s);
            for (name, an, fd) in [
                ("sdf", g.d_sdf, fd_sdf),
                ("cos", g.d_cos, fd_cos),
                ("inv_s", g.d_inv_s, fd_s),
            ] {
                if (an - fd).abs() > 1e-6 + 1e-4 * fd.abs() {
                    fails.push(format!(
                        "{name} at {f},{c},{dt},{s},{a}: analytic {an} fd {fd}"
                    ));
                }
            }
        }
        assert!(fails.is_empty(), "{}", fails.join("\n"));
    }

    #[test]
    fn inv_s_clip_and_derivative() {
        let (s, d) = inv_s_from_variance(0.3f64);
        assert!((s - 3f64.exp()).abs() < 1e-12 && (d - 10.0 * s).abs() < 1e-9);
        assert_eq!(inv_s_from_variance(10.0f32), (1e6, 0.0));
        assert_eq!(inv_s_from_variance(1e30f32), (1e6, 0.0));
        assert_eq!(inv_s_from_variance(-10.0f32), (1e-6, 0.0));
    }

    /// inv_s = 1e6 saturates both sigmoids: values and derivatives stay finite, alpha has the
    /// step-function limits: 1 when the interval crosses the surface, 0 far outside, and 1 deep
    /// inside (both sigmoids 0, so the `+1e-5` terms give `1e-5/1e-5`).
    #[test]
    fn saturated_sigmoids_are_finite_with_correct_limits() {
        for &(f, want) in &[(0.0f32, 1.0f32), (0.5, 0.0), (-0.5, 1.0)] {
            let (a, g) = neus_alpha::<f32, true>(f, -1.0, 0.01, 1e6, 1.0);
            assert!(a.is_finite() && g.d_sdf.is_finite() && g.d_cos.is_finite());
            assert!(g.d_inv_s.is_finite());
            assert!((a - want).abs() < 1e-4, "sdf {f}: alpha {a}, want {want}");
        }
        // Exactly on the surface with s = 1e6 and a tiny interval: still finite.
        let (a, g) = neus_alpha::<f32, true>(0.0, -1.0, 1e-9, 1e6, 1.0);
        assert!(
            a.is_finite() && g.d_sdf.is_finite() && g.d_inv_s.is_finite(),
            "{a} {g:?}"
        );
    }

    /// A grazing ray (cos = 0) with the anneal finished has iter_cos = 0: both sections equal the
    /// midpoint SDF, so α = 1e-5/(σ+1e-5) (tiny, positive) and ∂α/∂cos is finite.
    #[test]
    fn grazing_ray_gives_small_positive_alpha() {
        let (a, g) = neus_alpha::<f64, true>(0.0, 0.0, 0.01, 100.0, 1.0);
        let want = 1e-5 / (0.5 + 1e-5);
        assert!((a - want).abs() < 1e-12, "{a} vs {want}");
        assert!(g.d_cos.is_finite() && g.d_sdf.is_finite());
        // Before annealing, cos = 0 still counts as half facing: iter_cos = -0.5.
        let (a0, _) = neus_alpha::<f64, false>(0.0, 0.0, 0.01, 100.0, 0.0);
        let s = |x: f64| 1.0 / (1.0 + (-x).exp());
        let want0 = (s(0.25) - s(-0.25) + 1e-5) / (s(0.25) + 1e-5);
        assert!((a0 - want0).abs() < 1e-12);
    }
}
