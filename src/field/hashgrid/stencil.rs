//! The finite-difference stencil of the hash grid, one level at a time: a sample and its six
//! axis taps (the training path), touching only the centre cell's 8 corners and the far faces of
//! the taps that leave it. The batched, level-parallel version of the same stencil (8 levels in
//! 16 lanes) is [`crate::field::lanes`].

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::level::PRIMES;
use super::{corner_of, corner_weights, HashGrid};
use crate::field::Real;

/// Point `p` of a finite-difference stencil: 0 = the centre, `1 + 2a` / `2 + 2a` = the centre
/// with axis `a` set to `taps[a][0]` / `taps[a][1]`.
#[inline(always)]
pub fn fd_point<T: Copy>(x: [T; 3], taps: [[T; 2]; 3], p: usize) -> [T; 3] {
    let mut q = x;
    if p > 0 {
        let a = (p - 1) / 2;
        q[a] = taps[a][(p - 1) % 2];
    }
    q
}

/// Row starts (in values, `d` per row) of a stencil's seven points when the centre is row
/// `centre` and the six taps are the consecutive rows from `first_tap`, in [`fd_point`]'s order.
#[inline(always)]
pub fn stencil_rows(centre: usize, first_tap: usize, d: usize) -> [usize; 7] {
    std::array::from_fn(|p| {
        if p == 0 {
            centre * d
        } else {
            (first_tap + p - 1) * d
        }
    })
}

/// The seven points of a finite-difference stencil (see [`fd_point`]).
#[inline(always)]
pub fn fd_points<T: Copy>(x: [T; 3], taps: [[T; 2]; 3]) -> [[T; 3]; 7] {
    std::array::from_fn(|p| fd_point(x, taps, p))
}

impl HashGrid {
    /// Encodes a sample and its six finite-difference taps (the training path): point 0 is `x`,
    /// points `1 + 2a` and `2 + 2a` are `x` with axis `a` replaced by `taps[a][0]` (≥ `x[a]`, the
    /// `+ε` tap) and `taps[a][1]` (≤ `x[a]`, the `−ε` tap). Point `p`'s encoding goes to
    /// `out[rows[p]..rows[p] + output_dim]`. Same values as [`encode_group`](Self::encode_group)
    /// on the seven points up to rounding (tested against [`encode_naive`](Self::encode_naive)).
    ///
    /// On a level where every tap moves at most one cell from the centre's cell (always, when
    /// `ε` is at most one cell of the finest active level), the seven points only touch the
    /// centre cell's 8 corners plus, per tap, the 4 corners of the far face of the tap's cell:
    /// the trilinear interpolation is split into a bilinear one on the two other axes (shared
    /// weights) and a linear one along the tap's axis, choosing planes by table lookup instead of
    /// branches, so the loads of all levels overlap (no mispredicted branch flushes them). Other
    /// levels fall back to eight corners per point.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_fd<T: Real>(
        &self,
        table: &[T],
        x: [T; 3],
        taps: [[T; 2]; 3],
        radius: T,
        active: usize,
        out: &mut [T],
        rows: &[usize; 7],
    ) {
        match self.n_features {
            1 => self.fd_f::<T, 1, false>(
                table,
                None,
                x,
                taps,
                radius,
                active,
                Some(out),
                None,
                rows,
            ),
            2 => self.fd_f::<T, 2, false>(
                table,
                None,
                x,
                taps,
                radius,
                active,
                Some(out),
                None,
                rows,
            ),
            4 => self.fd_f::<T, 4, false>(
                table,
                None,
                x,
                taps,
                radius,
                active,
                Some(out),
                None,
                rows,
            ),
            8 => self.fd_f::<T, 8, false>(
                table,
                None,
                x,
                taps,
                radius,
                active,
                Some(out),
                None,
                rows,
            ),
            _ => {
                let pts = fd_points(x, taps);
                self.encode_group(table, &pts, radius, active, out, rows)
            }
        }
    }

    /// Backward of [`encode_fd`](Self::encode_fd): scatter-adds `d_out[rows[p]..]` (the gradient
    /// of point `p`'s encoding) into the table gradient `grad`. The corner gradients of the seven
    /// points are combined per plane first; each level writes 8 + 6·4 entries.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_fd_backward<T: Real>(
        &self,
        x: [T; 3],
        taps: [[T; 2]; 3],
        radius: T,
        active: usize,
        d_out: &[T],
        rows: &[usize; 7],
        grad: &mut [T],
    ) {
        let (g, d) = (Some(grad), Some(d_out));
        match self.n_features {
            1 => self.fd_f::<T, 1, true>(&[], g, x, taps, radius, active, None, d, rows),
            2 => self.fd_f::<T, 2, true>(&[], g, x, taps, radius, active, None, d, rows),
            4 => self.fd_f::<T, 4, true>(&[], g, x, taps, radius, active, None, d, rows),
            8 => self.fd_f::<T, 8, true>(&[], g, x, taps, radius, active, None, d, rows),
            _ => {
                let pts = fd_points(x, taps);
                self.encode_group_backward(&pts, radius, active, d_out, rows, g.expect("grad"))
            }
        }
    }

    /// Forward (`BWD = false`: reads `table`, writes `out`) or backward (`BWD = true`: reads
    /// `d_out`, scatters into `grad`) of the finite-difference stencil with `F` features.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn fd_f<T: Real, const F: usize, const BWD: bool>(
        &self,
        table: &[T],
        mut grad: Option<&mut [T]>,
        x: [T; 3],
        taps: [[T; 2]; 3],
        radius: T,
        active: usize,
        mut out: Option<&mut [T]>,
        d_out: Option<&[T]>,
        rows: &[usize; 7],
    ) {
        let xd = self.xyz_dim();
        let inv = T::ONE / (radius + radius);
        let uc = Self::to_unit(x, radius);
        let mut ut = [[T::ZERO; 2]; 3];
        for a in 0..3 {
            for p in 0..2 {
                ut[a][p] = (taps[a][p] + radius) * inv;
            }
        }
        if !BWD {
            if let Some(o) = out.as_deref_mut() {
                if self.include_xyz {
                    for p in 0..7 {
                        let pt = fd_point(x, taps, p);
                        for d in 0..3 {
                            o[rows[p] + d] = pt[d] / radius;
                        }
                    }
                }
            }
        }
        let half = T::from_f64(0.5);
        for (l, lvl) in self.levels.iter().enumerate() {
            let base = xd + l * F;
            if l >= active {
                if BWD {
                    break;
                }
                if let Some(o) = out.as_deref_mut() {
                    for p in 0..7 {
                        o[rows[p] + base..rows[p] + base + F].fill(T::ZERO);
                    }
                }
                continue;
            }
            let s = T::from_f64(lvl.scale);
            // Centre cell and fraction; tap cells relative to the centre's along their axis.
            let mut cell = [0u32; 3];
            let mut w = [[T::ZERO; 2]; 3];
            let mut ft = [[T::ZERO; 2]; 3];
            let mut dd = [[0i32; 2]; 3];
            let mut ok = true;
            for a in 0..3 {
                let pos = s * uc[a] + half;
                let fl = pos.floor();
                cell[a] = fl.cell_u32();
                let f = pos - fl;
                w[a] = [T::ONE - f, f];
                for p in 0..2 {
                    let pt = s * ut[a][p] + half;
                    let flt = pt.floor();
                    ft[a][p] = pt - flt;
                    dd[a][p] = (flt.cell_u32()).wrapping_sub(cell[a]) as i32;
                }
                ok &= (dd[a][0] == 0 || dd[a][0] == 1) && (dd[a][1] == 0 || dd[a][1] == -1);
            }
            if !ok {
                // A tap more than one cell away (ε above a cell of this level): eight corners per
                // point. Never taken in training, where ε is one cell of the finest active level.
                let pts = fd_points(x, taps);
                for p in 0..7 {
                    let u = Self::to_unit(pts[p], radius);
                    let (c, fr) = Self::locate(lvl, u);
                    let wc = corner_weights(fr);
                    if BWD {
                        let g = &d_out.expect("d_out")[rows[p] + base..rows[p] + base + F];
                        let gr = grad.as_deref_mut().expect("grad");
                        for k in 0..8 {
                            let e = self.entry(lvl, corner_of(c, k)) * F;
                            for q in 0..F {
                                gr[e + q] += wc[k] * g[q];
                            }
                        }
                    } else {
                        let o = out.as_deref_mut().expect("out");
                        let row = &mut o[rows[p] + base..rows[p] + base + F];
                        row.fill(T::ZERO);
                        for k in 0..8 {
                            let e = self.entry(lvl, corner_of(c, k)) * F;
                            for q in 0..F {
                                row[q] += wc[k] * table[e + q];
                            }
                        }
                    }
                }
                continue;
            }
            // Per-axis index terms of the coordinates cell−1 .. cell+2.
            let mut terms = [[0u32; 4]; 3];
            for a in 0..3 {
                let mul = if lvl.hashed {
                    PRIMES[a]
                } else {
                    [
                        1,
                        lvl.resolution,
                        lvl.resolution.wrapping_mul(lvl.resolution),
                    ][a]
                };
                for m in 0..4 {
                    terms[a][m] = cell[a]
                        .wrapping_add(m as u32)
                        .wrapping_sub(1)
                        .wrapping_mul(mul);
                }
            }
            let hashed = lvl.hashed;
            let mask = if lvl.size.is_power_of_two() {
                lvl.size - 1
            } else {
                u32::MAX
            };
            let idx = |tx: u32, ty: u32, tz: u32| -> usize {
                let i = if hashed {
                    tx ^ ty ^ tz
                } else {
                    tx.wrapping_add(ty).wrapping_add(tz)
                };
                let i = if mask != u32::MAX {
                    i & mask
                } else if i >= lvl.size {
                    i % lvl.size
                } else {
                    i
                };
                (lvl.offset + i as usize) * F
            };
            // Centre corners (bit a of `c` = offset along axis a) and their trilinear weights.
            let mut ce = [0usize; 8];
            let mut w8 = [T::ZERO; 8];
            for c in 0..8 {
                let (i, j, k) = (c & 1, (c >> 1) & 1, c >> 2);
                ce[c] = idx(terms[0][1 + i], terms[1][1 + j], terms[2][1 + k]);
                w8[c] = w[0][i] * w[1][j] * w[2][k];
            }
            // Far-face entries of each tap and the bilinear weights of a face of axis a.
            let mut fe = [[[0usize; 4]; 2]; 3];
            let mut wq = [[T::ZERO; 4]; 3];
            for a in 0..3 {
                let (b, c2) = ((a + 1) % 3, (a + 2) % 3);
                for q in 0..4 {
                    let (ob, oc) = (q & 1, q >> 1);
                    wq[a][q] = w[b][ob] * w[c2][oc];
                    for p in 0..2 {
                        // + tap: face at cell+1+d (m = 2+d); − tap: face at cell+d (m = 1+d).
                        let m = if p == 0 { 2 + dd[a][0] } else { 1 + dd[a][1] } as usize;
                        let mut t = [0u32; 3];
                        t[a] = terms[a][m];
                        t[b] = terms[b][1 + ob];
                        t[c2] = terms[c2][1 + oc];
                        fe[a][p][q] = idx(t[0], t[1], t[2]);
                    }
                }
            }
            // Corner index of face q of axis a at offset i along a.
            let corner = |a: usize, i: usize, q: usize| -> usize {
                let (b, c2) = ((a + 1) % 3, (a + 2) % 3);
                (i << a) | ((q & 1) << b) | ((q >> 1) << c2)
            };
            // Faces used by a tap: planes [face 0, face 1, far face]; + tap (d ∈ {0,1}) uses
            // (d, d+1), − tap (d ∈ {−1,0}) uses (−2d, 1+d).
            let sel = |a: usize, p: usize| -> (usize, usize) {
                let d = dd[a][p];
                if p == 0 {
                    (d as usize, (d + 1) as usize)
                } else {
                    ((-2 * d) as usize, (1 + d) as usize)
                }
            };
            if !BWD {
                let mut cv = [[T::ZERO; F]; 8];
                for c in 0..8 {
                    cv[c].copy_from_slice(&table[ce[c]..ce[c] + F]);
                }
                let o = out.as_deref_mut().expect("out");
                let mut v = [T::ZERO; F];
                for c in 0..8 {
                    for q in 0..F {
                        v[q] += w8[c] * cv[c][q];
                    }
                }
                o[rows[0] + base..rows[0] + base + F].copy_from_slice(&v);
                for a in 0..3 {
                    let mut planes = [[T::ZERO; F]; 3];
                    for i in 0..2 {
                        for q in 0..4 {
                            let c = corner(a, i, q);
                            for k in 0..F {
                                planes[i][k] += wq[a][q] * cv[c][k];
                            }
                        }
                    }
                    for p in 0..2 {
                        let mut far = [T::ZERO; F];
                        for q in 0..4 {
                            let e = fe[a][p][q];
                            for k in 0..F {
                                far[k] += wq[a][q] * table[e + k];
                            }
                        }
                        planes[2] = far;
                        let (lo, hi) = sel(a, p);
                        let t = ft[a][p];
                        let r = rows[1 + 2 * a + p] + base;
                        for k in 0..F {
                            o[r + k] = (T::ONE - t) * planes[lo][k] + t * planes[hi][k];
                        }
                    }
                }
            } else {
                let d_out = d_out.expect("d_out");
                let gr = grad.as_deref_mut().expect("grad");
                let g0 = &d_out[rows[0] + base..rows[0] + base + F];
                let mut dc = [[T::ZERO; F]; 8];
                for c in 0..8 {
                    for k in 0..F {
                        dc[c][k] = w8[c] * g0[k];
                    }
                }
                for a in 0..3 {
                    let mut dface = [[T::ZERO; F]; 2];
                    for p in 0..2 {
                        let r = rows[1 + 2 * a + p] + base;
                        let g = &d_out[r..r + F];
                        let t = ft[a][p];
                        let (lo, hi) = sel(a, p);
                        let mut dp = [[T::ZERO; F]; 3];
                        for k in 0..F {
                            dp[lo][k] += (T::ONE - t) * g[k];
                            dp[hi][k] += t * g[k];
                        }
                        for k in 0..F {
                            dface[0][k] += dp[0][k];
                            dface[1][k] += dp[1][k];
                        }
                        // The far face (zero gradient when the tap stays in the centre cell,
                        // where the far face is one of the centre's faces: adding 0 is harmless).
                        for q in 0..4 {
                            let e = fe[a][p][q];
                            for k in 0..F {
                                gr[e + k] += wq[a][q] * dp[2][k];
                            }
                        }
                    }
                    for i in 0..2 {
                        for q in 0..4 {
                            let c = corner(a, i, q);
                            for k in 0..F {
                                dc[c][k] += wq[a][q] * dface[i][k];
                            }
                        }
                    }
                }
                for c in 0..8 {
                    for k in 0..F {
                        gr[ce[c] + k] += dc[c][k];
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::small;
    use super::*;
    use crate::field::config::HashGridConfig;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// The stencil path (centre + 6 axis taps, planes chosen by table lookup) against the naive
    /// reference, forward and backward: taps inside the centre cell, one cell away on fine levels,
    /// several cells away (the fallback), clamped at the box faces, masked levels, F = 1, 2, 3.
    #[test]
    fn fd_stencil_matches_naive() {
        let mut rng = Pcg64Mcg::seed_from_u64(17);
        let mut worst = 0.0f64;
        let mut fallback_cases = 0;
        for f in [2usize, 1, 3] {
            let g = HashGrid::new(&HashGridConfig {
                n_features_per_level: f,
                ..small()
            });
            let table: Vec<f64> = (0..g.n_params())
                .map(|_| rng.random_range(-1.0..1.0))
                .collect();
            let r = 1.0;
            let d = g.output_dim();
            let finest = g.fd_eps(6, r);
            for trial in 0..300 {
                let mut c = [0.0; 3];
                for v in c.iter_mut() {
                    *v = rng.random_range(-1.0..1.0);
                }
                match trial % 5 {
                    0 => c = [1.0, -1.0, rng.random_range(-1.0..1.0)],
                    1 => c[1] = 1.0 - 1e-4,
                    _ => {}
                }
                let active = 1 + trial % 6;
                // One cell of the finest active level (training), smaller, or several cells.
                let eps = match trial % 3 {
                    0 => g.fd_eps(active, r),
                    1 => 0.37 * finest,
                    _ => 0.4,
                };
                if eps > g.fd_eps(active, r) * 1.01 {
                    fallback_cases += 1;
                }
                let taps =
                    [0, 1, 2].map(|a| [(c[a] + eps).clamp(-r, r), (c[a] - eps).clamp(-r, r)]);
                let rows = [0, d, 2 * d, 3 * d, 4 * d, 5 * d, 6 * d];
                let mut out = vec![9.0; 7 * d];
                g.encode_fd(&table, c, taps, r, active, &mut out, &rows);
                let pts = fd_points(c, taps);
                for p in 0..7 {
                    let want = g.encode_naive(&table, pts[p], r, active);
                    for j in 0..d {
                        worst = worst.max((want[j] - out[rows[p] + j]).abs());
                    }
                }
                let dout: Vec<f64> = (0..7 * d).map(|_| rng.random_range(-1.0..1.0)).collect();
                let mut gf = vec![0.0; g.n_params()];
                let mut gn = vec![0.0; g.n_params()];
                g.encode_fd_backward(c, taps, r, active, &dout, &rows, &mut gf);
                for p in 0..7 {
                    g.encode_backward_naive(
                        pts[p],
                        r,
                        active,
                        &dout[rows[p]..rows[p] + d],
                        &mut gn,
                    );
                }
                for (a, b) in gf.iter().zip(&gn) {
                    worst = worst.max((a - b).abs());
                }
            }
        }
        assert!(fallback_cases > 100);
        assert!(worst < 1e-12, "stencil vs naive max diff {worst}");
    }
}
