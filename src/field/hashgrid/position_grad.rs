//! The hash encoding's gradient with respect to the input position: what a loss on the encoding
//! says about where the point should move. Needed where the positions themselves are learned,
//! as in pose refinement (BARF, Lin et al. 2021, §3; nerfstudio's camera optimizer): the sample
//! positions depend on the camera, and the camera's gradient flows through them.
//!
//! The encoding is trilinear in each cell, so the gradient is that of the interpolation weights,
//! `∂w_i/∂f_d = ±∏_{e≠d} w_{i,e}`, times `∂f_d/∂x_d = scale_l / (2r)`; it is piecewise
//! constant along an axis between cell faces and jumps across them (the encoding is only C⁰).

use super::level::Level;
use super::stencil::fd_point;
use super::{corner_of, HashGrid};
use crate::field::Real;

/// `(∂/∂f_d)` of a cell's trilinear interpolation of the corner values `v` (corner `c` at
/// offset bit `d` of `c` along axis `d`) at weights `w[d] = [1 − f_d, f_d]`.
#[inline(always)]
fn trilinear_grad<T: Real>(w: &[[T; 2]; 3], v: &[T; 8]) -> [T; 3] {
    let mut g = [T::ZERO; 3];
    for (c, &vc) in v.iter().enumerate() {
        let bits = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
        for d in 0..3 {
            let (a, b) = ((d + 1) % 3, (d + 2) % 3);
            let sign = if bits[d] == 1 { T::ONE } else { -T::ONE };
            g[d] += sign * w[a][bits[a]] * w[b][bits[b]] * vc;
        }
    }
    g
}

/// `Σ_k dl[k]·table[e + k]`: a corner's value as the loss sees it.
#[inline(always)]
fn seen<T: Real>(table: &[T], e: usize, dl: &[T]) -> T {
    let mut v = T::ZERO;
    for (k, &g) in dl.iter().enumerate() {
        v += g * table[e + k];
    }
    v
}

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
            let gl = self.level_vjp(lvl, table, u, &d_out[xd + l * f..xd + (l + 1) * f]);
            let s = T::from_f64(lvl.scale) * du_dx;
            for d in 0..3 {
                g[d] += gl[d] * s;
            }
        }
        g
    }

    /// One level's part of [`Self::encode_input_vjp`] at the unit-cube point `u`, per unit of
    /// the level's cell coordinate; `dl`: the level's slice of `d_out`.
    fn level_vjp<T: Real>(&self, lvl: &Level, table: &[T], u: [T; 3], dl: &[T]) -> [T; 3] {
        let (cell, frac) = Self::locate(lvl, u);
        let w = [
            [T::ONE - frac[0], frac[0]],
            [T::ONE - frac[1], frac[1]],
            [T::ONE - frac[2], frac[2]],
        ];
        let f = self.n_features;
        let v: [T; 8] =
            std::array::from_fn(|c| seen(table, self.entry(lvl, corner_of(cell, c)) * f, dl));
        trilinear_grad(&w, &v)
    }

    /// [`Self::encode_input_vjp`] of the seven points of a finite-difference stencil at once
    /// (the training path; points in [`fd_point`]'s order, point `p`'s `d_out` row at
    /// `rows[p]`, points with `skip[p]` left at zero). Same values up to rounding (tested
    /// against it). A tap shares the centre's cell on the two other axes, and along its own
    /// axis at most one cell apart, so on each level the seven points read the centre cell's 8
    /// corners and, for a tap that leaves the cell, the 4 corners of one more face: 8 + up to
    /// 24 hashed entries per level instead of 56. A level where a tap lies further out (`ε`
    /// above a cell) falls back to the per-point path.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_fd_input_vjp<T: Real>(
        &self,
        table: &[T],
        x: [T; 3],
        taps: [[T; 2]; 3],
        radius: T,
        active: usize,
        d_out: &[T],
        rows: &[usize; 7],
        skip: &[bool; 7],
    ) -> [[T; 3]; 7] {
        let mut g = [[T::ZERO; 3]; 7];
        let xd = self.xyz_dim();
        let f = self.n_features;
        if self.include_xyz {
            for p in (0..7).filter(|&p| !skip[p]) {
                for d in 0..3 {
                    g[p][d] += d_out[rows[p] + d] / radius;
                }
            }
        }
        let inv = T::ONE / (radius + radius);
        let uc = Self::to_unit(x, radius);
        let half = T::from_f64(0.5);
        for (l, lvl) in self.levels.iter().enumerate().take(active) {
            let base = xd + l * f;
            let dl = |p: usize| &d_out[rows[p] + base..rows[p] + base + f];
            let s = T::from_f64(lvl.scale);
            let scale = s * inv;
            let (cell, frac) = Self::locate(lvl, uc);
            let w = [
                [T::ONE - frac[0], frac[0]],
                [T::ONE - frac[1], frac[1]],
                [T::ONE - frac[2], frac[2]],
            ];
            // Each tap's cell offset from the centre's along its axis, and its fraction there.
            let mut dd = [[0i64; 2]; 3];
            let mut ft = [[T::ZERO; 2]; 3];
            let mut ok = true;
            for a in 0..3 {
                for side in 0..2 {
                    let pos = s * ((taps[a][side] + radius) * inv) + half;
                    let fl = pos.floor();
                    ft[a][side] = pos - fl;
                    dd[a][side] = fl.cell_u32() as i64 - cell[a] as i64;
                }
                ok &= matches!(dd[a][0], 0 | 1) && matches!(dd[a][1], 0 | -1);
            }
            if !ok {
                for p in (0..7).filter(|&p| !skip[p]) {
                    let u = Self::to_unit(fd_point(x, taps, p), radius);
                    let gl = self.level_vjp(lvl, table, u, dl(p));
                    for d in 0..3 {
                        g[p][d] += gl[d] * scale;
                    }
                }
                continue;
            }
            let ce: [usize; 8] = std::array::from_fn(|c| self.entry(lvl, corner_of(cell, c)) * f);
            if !skip[0] {
                let v: [T; 8] = std::array::from_fn(|c| seen(table, ce[c], dl(0)));
                let gl = trilinear_grad(&w, &v);
                for d in 0..3 {
                    g[0][d] += gl[d] * scale;
                }
            }
            for a in 0..3 {
                let (b, c2) = ((a + 1) % 3, (a + 2) % 3);
                // Entries of the four faces across axis `a` at offsets −1, 0, 1, 2 from the
                // centre cell (face corner q: bit 0 along b, bit 1 along c2); a tap's cell
                // spans two consecutive ones. Chosen by index, not by branch, so the loads of
                // the taps overlap.
                let mut faces = [[0usize; 4]; 4];
                for (m, face) in faces.iter_mut().enumerate() {
                    for (q, e) in face.iter_mut().enumerate() {
                        let (ob, oc) = (q & 1, q >> 1);
                        *e = if m == 1 || m == 2 {
                            ce[((m - 1) << a) | (ob << b) | (oc << c2)]
                        } else {
                            let mut k = cell;
                            k[a] = cell[a].wrapping_add(m as u32).wrapping_sub(1);
                            k[b] = cell[b].wrapping_add(ob as u32);
                            k[c2] = cell[c2].wrapping_add(oc as u32);
                            self.entry(lvl, k) * f
                        };
                    }
                }
                for side in 0..2 {
                    let p = 1 + 2 * a + side;
                    if skip[p] {
                        continue;
                    }
                    let m0 = (dd[a][side] + 1) as usize;
                    let v: [T; 8] = std::array::from_fn(|c| {
                        let i = (c >> a) & 1;
                        let q = ((c >> b) & 1) | (((c >> c2) & 1) << 1);
                        seen(table, faces[m0 + i][q], dl(p))
                    });
                    let mut wt = w;
                    wt[a] = [T::ONE - ft[a][side], ft[a][side]];
                    let gl = trilinear_grad(&wt, &v);
                    for d in 0..3 {
                        g[p][d] += gl[d] * scale;
                    }
                }
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

    /// The stencil path against the per-point reference, in f64 and f32: taps inside the
    /// centre cell, one cell away on the fine levels, several cells away (the fallback), a tap
    /// clamped onto the centre (`taps[a][side] == x[a]`, as at the box's faces), skipped points,
    /// every prefix of active levels, with and without the xyz prefix.
    #[test]
    fn the_stencil_input_vjp_matches_the_per_point_reference() {
        for include_xyz in [false, true] {
            let mut cfg = small();
            cfg.include_xyz = include_xyz;
            let g = HashGrid::new(&cfg);
            let mut rng = Pcg64Mcg::seed_from_u64(23);
            let table: Vec<f64> = (0..g.n_params())
                .map(|_| rng.random_range(-1.0..1.0))
                .collect();
            let table32: Vec<f32> = table.iter().map(|&v| v as f32).collect();
            let r = 0.8;
            let mut fallback = 0;
            for trial in 0..400 {
                let active = 1 + trial % g.levels.len();
                let h = [1e-4, 2e-2, 0.3][trial % 3];
                let x: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.79..0.79));
                let mut taps: [[f64; 2]; 3] =
                    std::array::from_fn(|a| [(x[a] + h).min(r), (x[a] - h).max(-r)]);
                if trial % 5 == 0 {
                    taps[trial % 3][trial % 2] = x[trial % 3];
                }
                let d = g.output_dim();
                let rows: [usize; 7] = std::array::from_fn(|p| p * d);
                let skip: [bool; 7] = std::array::from_fn(|p| trial % 7 == 3 && p % 3 == 1);
                let d_out: Vec<f64> = (0..7 * d).map(|_| rng.random_range(-1.0..1.0)).collect();
                let got = g.encode_fd_input_vjp(&table, x, taps, r, active, &d_out, &rows, &skip);
                let d32: Vec<f32> = d_out.iter().map(|&v| v as f32).collect();
                let got32 = g.encode_fd_input_vjp(
                    &table32,
                    x.map(|v| v as f32),
                    taps.map(|t| t.map(|v| v as f32)),
                    r as f32,
                    active,
                    &d32,
                    &rows,
                    &skip,
                );
                fallback += usize::from(h > 0.1);
                for p in 0..7 {
                    let want = if skip[p] {
                        [0.0; 3]
                    } else {
                        let pt = fd_point(x, taps, p);
                        g.encode_input_vjp(&table, pt, r, active, &d_out[rows[p]..rows[p] + d])
                    };
                    for k in 0..3 {
                        let tol = 1e-10 * (1.0 + want[k].abs());
                        assert!(
                            (got[p][k] - want[k]).abs() < tol,
                            "trial {trial}, point {p}, axis {k}: {} vs {}",
                            got[p][k],
                            want[k]
                        );
                        let tol32 = 2e-3 * (1.0 + want[k].abs());
                        assert!(
                            (f64::from(got32[p][k]) - want[k]).abs() < tol32,
                            "f32, trial {trial}, point {p}, axis {k}: {} vs {}",
                            got32[p][k],
                            want[k]
                        );
                    }
                }
            }
            assert!(fallback > 100);
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
