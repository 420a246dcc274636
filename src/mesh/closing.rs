//! Grey-scale morphological closing of a sampled SDF before marching cubes: it fills pinholes and
//! tunnels narrower than about two grid cells and leaves planes, convex parts and larger holes as
//! they are.
//!
//! The closing of values `f` on the grid with the cube of half-width `r` points is
//! `C(f) = E(D(f))`, with the dilation `D(f)(p) = min f(q)` and the erosion `E(g)(p) = max g(q)`
//! over the grid points `q` with `|q − p|∞ ≤ r` (the window clipped at the grid's faces). Flat
//! structuring elements commute with thresholding (Serra, *Image Analysis and Mathematical
//! Morphology*, 1982, ch. XII), so the inside set `{C(f) ≤ iso}` is exactly the binary closing of
//! `{f ≤ iso}`: the union of every cube of `(2r + 1)³` points that fits in the outside is kept
//! outside, and any outside gap too narrow to hold one is filled. For values affine in the grid
//! indices (a planar SDF) and windows away from the faces, `D` subtracts `r·|∇f|₁` and `E` adds it
//! back, so `C(f) = f` to the last bit up to rounding: a flat face does not move.
//!
//! Why: a colour loss that sends more rays to thin parts (the error map, `train.error_map`)
//! leaves sub-millimetre tunnels through thin sheets (a 2.2 mm fin) and at a torus' rim, each one
//! handle on the mesh's genus. The closing removes them at extraction; NeuS and instant-nsr-pl
//! extract the raw level set (`extract_geometry` / `isosurface`), so this is a deviation, off at
//! `r = 0`.
//!
//! The cube is separable: `D` is a 1-D minimum along x, then y, then z, and `E` a 1-D maximum
//! in the same order. The streaming form (`mcubes.rs`) holds `2·(2r + 1) + 2` planes.

/// In-place 1-D minimum (`max = false`) or maximum of every row of a plane `[ny][nx]` along x,
/// then of every column along y, with windows of half-width `r` clipped at the plane's edges.
///
/// `line` is scratch space (resized as needed).
pub(crate) fn filter_plane(
    plane: &mut [f32],
    nx: usize,
    ny: usize,
    r: usize,
    max: bool,
    line: &mut Vec<f32>,
) {
    debug_assert_eq!(plane.len(), nx * ny);
    line.resize(nx.max(ny), 0.0);
    for row in plane.chunks_mut(nx) {
        line[..nx].copy_from_slice(row);
        filter_line(&line[..nx], row.iter_mut(), r, max);
    }
    for i in 0..nx {
        for (j, l) in line[..ny].iter_mut().enumerate() {
            *l = plane[j * nx + i];
        }
        filter_line(&line[..ny], plane[i..].iter_mut().step_by(nx), r, max);
    }
}

/// Writes the windowed minimum or maximum of `src` (half-width `r`, clipped) to `dst`.
fn filter_line<'a>(src: &[f32], dst: impl Iterator<Item = &'a mut f32>, r: usize, max: bool) {
    let n = src.len();
    for (t, d) in dst.take(n).enumerate() {
        let w = &src[t.saturating_sub(r)..=(t + r).min(n - 1)];
        *d = if max {
            w.iter().copied().fold(f32::NEG_INFINITY, f32::max)
        } else {
            w.iter().copied().fold(f32::INFINITY, f32::min)
        };
    }
}

/// Element-wise minimum (`max = false`) or maximum of `planes` into `out`.
pub(crate) fn combine_planes<'a>(
    out: &mut [f32],
    mut planes: impl Iterator<Item = &'a [f32]>,
    max: bool,
) {
    let first = planes.next().expect("at least one plane");
    out.copy_from_slice(first);
    for p in planes {
        for (o, &v) in out.iter_mut().zip(p) {
            *o = if max { o.max(v) } else { o.min(v) };
        }
    }
}

/// The closing of grid values `values` (`[k][j][i]`, x fastest, resolution `res`) with the cube
/// of half-width `r` points (module docs), in place. `r = 0` leaves the values as they are.
///
/// Values must not be NaN (`f32::min` would drop them): marching cubes checks before it closes.
pub fn close_values(values: &mut [f32], res: [usize; 3], r: usize) {
    let [nx, ny, nz] = res;
    assert_eq!(values.len(), nx * ny * nz, "values do not match the grid");
    if r == 0 {
        return;
    }
    let plane = nx * ny;
    let mut line = Vec::new();
    for max in [false, true] {
        for p in values.chunks_mut(plane) {
            filter_plane(p, nx, ny, r, max, &mut line);
        }
        let src = values.to_vec();
        for k in 0..nz {
            let lo = k.saturating_sub(r);
            let hi = (k + r).min(nz - 1);
            combine_planes(
                &mut values[k * plane..(k + 1) * plane],
                (lo..=hi).map(|q| &src[q * plane..(q + 1) * plane]),
                max,
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// The slow reference: for every point, the minimum over its clipped cube, then the maximum
    /// of those over the same cube.
    fn naive(values: &[f32], res: [usize; 3], r: usize) -> Vec<f32> {
        let [nx, ny, nz] = res;
        let idx = |i: usize, j: usize, k: usize| (k * ny + j) * nx + i;
        let window = |v: &[f32], i: usize, j: usize, k: usize, max: bool| {
            let mut m = if max {
                f32::NEG_INFINITY
            } else {
                f32::INFINITY
            };
            for c in k.saturating_sub(r)..=(k + r).min(nz - 1) {
                for b in j.saturating_sub(r)..=(j + r).min(ny - 1) {
                    for a in i.saturating_sub(r)..=(i + r).min(nx - 1) {
                        let x = v[idx(a, b, c)];
                        m = if max { m.max(x) } else { m.min(x) };
                    }
                }
            }
            m
        };
        let mut d = vec![0.0; values.len()];
        let mut e = vec![0.0; values.len()];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    d[idx(i, j, k)] = window(values, i, j, k, false);
                }
            }
        }
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    e[idx(i, j, k)] = window(&d, i, j, k, true);
                }
            }
        }
        e
    }

    /// The separable closing equals the brute-force one bit for bit, on random values over
    /// boxes with unequal sides (one side shorter than the window) and several radii.
    #[test]
    fn separable_closing_matches_the_naive_cube() {
        let mut rng = Pcg64Mcg::seed_from_u64(5);
        for (res, r) in [
            ([7, 5, 6], 1),
            ([9, 4, 3], 2),
            ([2, 6, 5], 3),
            ([5, 5, 5], 0),
        ] {
            let v: Vec<f32> = (0..res[0] * res[1] * res[2])
                .map(|_| rng.random_range(-1.0..1.0))
                .collect();
            let mut fast = v.clone();
            close_values(&mut fast, res, r);
            assert_eq!(fast, naive(&v, res, r), "res {res:?}, r {r}");
        }
    }

    /// A plane's values come back unchanged away from the grid's faces (a flat face of an object
    /// does not move), and a closing is idempotent: closing twice equals closing once.
    #[test]
    fn planes_stay_and_closing_is_idempotent() {
        let res = [12, 11, 10];
        let g = [0.3f32, -0.45, 0.2];
        let v: Vec<f32> = (0..10)
            .flat_map(|k| {
                (0..11).flat_map(move |j| {
                    (0..12).map(move |i| g[0] * i as f32 + g[1] * j as f32 + g[2] * k as f32 - 0.7)
                })
            })
            .collect();
        let mut c = v.clone();
        close_values(&mut c, res, 1);
        let mut worst = 0.0f32;
        for k in 2..8 {
            for j in 2..9 {
                for i in 2..10 {
                    let q = (k * 11 + j) * 12 + i;
                    worst = worst.max((c[q] - v[q]).abs());
                }
            }
        }
        assert!(worst < 1e-5, "a plane moved by {worst}");
        let mut twice = c.clone();
        close_values(&mut twice, res, 1);
        assert_eq!(twice, c);
    }
}
