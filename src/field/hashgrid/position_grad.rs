//! The hash encoding's gradient with respect to the input position: what a loss on the encoding
//! says about where the point should move. Needed where the positions themselves are learned,
//! as in pose refinement (BARF, Lin et al. 2021, §3; nerfstudio's camera optimizer): the sample
//! positions depend on the camera, and the camera's gradient flows through them.
//!
//! The encoding is trilinear in each cell, so the gradient is that of the interpolation weights,
//! `∂w_i/∂f_d = ±∏_{e≠d} w_{i,e}`, times `∂f_d/∂x_d = scale_l / (2r)`; it is piecewise
//! constant along an axis between cell faces and jumps across them (the encoding is only C⁰).

use super::{corner_of, HashGrid};
use crate::field::Real;

impl HashGrid {
    /// Vector–Jacobian product of [`HashGrid::encode`] with respect to `x`: `Σ_j d_out[j] ·
    /// ∂out[j]/∂x`, for `d_out` of length [`HashGrid::output_dim`] and `x ∈ [-r, r]³` in the
    /// normalised frame. Levels at or beyond `active` add nothing (their output is zero); the
    /// `include_xyz` prefix `x/r` adds `d_out[..3]/r`. Units: `d_out` per unit of encoding,
    /// the result per unit of normalised length.
    pub fn encode_input_vjp<T: Real>(
        &self,
        table: &[T],
        x: [T; 3],
        radius: T,
        active: usize,
        d_out: &[T],
    ) -> [T; 3] {
        let mut g = [T::ZERO; 3];
        let xd = self.xyz_dim();
        if self.include_xyz {
            for d in 0..3 {
                g[d] += d_out[d] / radius;
            }
        }
        let u = Self::to_unit(x, radius);
        let du_dx = T::ONE / (radius + radius);
        let f = self.n_features;
        for (l, lvl) in self.levels.iter().enumerate().take(active) {
            let (cell, frac) = Self::locate(lvl, u);
            let w = [
                [T::ONE - frac[0], frac[0]],
                [T::ONE - frac[1], frac[1]],
                [T::ONE - frac[2], frac[2]],
            ];
            let dl = &d_out[xd + l * f..xd + (l + 1) * f];
            let mut gl = [T::ZERO; 3];
            for c in 0..8 {
                let e = self.entry(lvl, corner_of(cell, c)) * f;
                // The corner's value seen by the loss: Σ_k d_out[l, k] · table[corner, k].
                let mut v = T::ZERO;
                for k in 0..f {
                    v += dl[k] * table[e + k];
                }
                let bits = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
                for d in 0..3 {
                    let (a, b) = ((d + 1) % 3, (d + 2) % 3);
                    let sign = if bits[d] == 1 { T::ONE } else { -T::ONE };
                    gl[d] += sign * w[a][bits[a]] * w[b][bits[b]] * v;
                }
            }
            let s = T::from_f64(lvl.scale) * du_dx;
            for d in 0..3 {
                g[d] += gl[d] * s;
            }
        }
        g
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::small;
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// Central differences of the slow reference encoding, in f64, at random points away from
    /// cell faces (where the encoding is smooth), for every prefix of active levels, with and
    /// without the xyz prefix.
    #[test]
    fn input_vjp_matches_finite_differences_of_the_reference() {
        for include_xyz in [false, true] {
            let mut cfg = small();
            cfg.include_xyz = include_xyz;
            let g = HashGrid::new(&cfg);
            let mut rng = Pcg64Mcg::seed_from_u64(11);
            let table: Vec<f64> = (0..g.n_params())
                .map(|_| rng.random_range(-1.0..1.0))
                .collect();
            let r = 0.8;
            let h = 1e-7;
            let mut checked = 0;
            for trial in 0..300 {
                let active = 1 + trial % g.levels.len();
                let x: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.79..0.79));
                // Skip points within 2h of a face on any active level: the difference would
                // straddle the kink.
                let near_face = g.levels[..active].iter().any(|lvl| {
                    x.iter().any(|&v| {
                        let pos = lvl.scale * (v + r) / (2.0 * r) + 0.5;
                        let fr = pos - pos.floor();
                        fr.min(1.0 - fr) < 4.0 * h * lvl.scale / (2.0 * r)
                    })
                });
                if near_face {
                    continue;
                }
                let d_out: Vec<f64> = (0..g.output_dim())
                    .map(|_| rng.random_range(-1.0..1.0))
                    .collect();
                let got = g.encode_input_vjp(&table, x, r, active, &d_out);
                for d in 0..3 {
                    let mut xp = x;
                    let mut xm = x;
                    xp[d] += h;
                    xm[d] -= h;
                    let fp = g.encode_naive(&table, xp, r, active);
                    let fm = g.encode_naive(&table, xm, r, active);
                    let fd: f64 = (0..fp.len())
                        .map(|j| d_out[j] * (fp[j] - fm[j]) / (2.0 * h))
                        .sum();
                    let tol = 1e-6 * (1.0 + fd.abs());
                    assert!(
                        (got[d] - fd).abs() < tol,
                        "xyz {include_xyz}, active {active}, axis {d}: {} vs {fd}",
                        got[d]
                    );
                }
                checked += 1;
            }
            assert!(checked > 250, "only {checked} points checked");
        }
    }

    /// Levels that are not active contribute nothing, and f32 agrees with f64.
    #[test]
    fn inactive_levels_add_nothing_and_f32_agrees() {
        let g = HashGrid::new(&small());
        let mut rng = Pcg64Mcg::seed_from_u64(3);
        let table: Vec<f64> = (0..g.n_params())
            .map(|_| rng.random_range(-1.0..1.0))
            .collect();
        let x = [0.1, -0.2, 0.3];
        let mut d_out = vec![0.0; g.output_dim()];
        // Only the last level's features carry a loss gradient.
        let last = g.levels.len() - 1;
        d_out[g.xyz_dim() + last * g.n_features] = 1.0;
        assert_eq!(g.encode_input_vjp(&table, x, 1.0, last, &d_out), [0.0; 3]);
        let full = g.encode_input_vjp(&table, x, 1.0, last + 1, &d_out);
        assert!(full.iter().any(|v| v.abs() > 1e-3), "{full:?}");
        let t32: Vec<f32> = table.iter().map(|&v| v as f32).collect();
        let d32: Vec<f32> = d_out.iter().map(|&v| v as f32).collect();
        let x32 = [0.1f32, -0.2, 0.3];
        let g32 = g.encode_input_vjp(&t32, x32, 1.0, last + 1, &d32);
        for d in 0..3 {
            assert!((g32[d] as f64 - full[d]).abs() < 1e-3 * (1.0 + full[d].abs()));
        }
    }
}
