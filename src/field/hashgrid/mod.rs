//! Multiresolution hash encoding (Müller et al., "Instant Neural Graphics Primitives", 2022) with
//! tiny-cuda-nn semantics (`include/tiny-cuda-nn/encodings/grid.h`):
//!
//! - level `l`: `scale_l = base·b^l − 1`, `resolution_l = ceil(scale_l) + 1`;
//! - entries in level `l`: `next_multiple_of_8(min(resolution_l³, 2^log2_hashmap_size))`; the level
//!   is *dense* (index `x + y·res + z·res²`) when `resolution_l³` fits, else *hashed* with
//!   `x·1 ⊕ y·2654435761 ⊕ z·805459861` (wrapping `u32`); both taken modulo the level's entries;
//! - lookup at `pos = scale_l·u + 0.5` for `u ∈ [0,1]³`, trilinear over the 8 corners of
//!   `floor(pos)`.
//!
//! Positions come in the normalised space `x ∈ [-r, r]³` and are mapped to `u = (x + r)/(2r)`
//! (instant-nsr-pl `contract_to_unisphere` with an AABB contraction). With `include_xyz` the
//! encoding starts with `x/r ∈ [-1,1]³` (instant-nsr-pl `CompositeEncoding`, `2u − 1`).
//!
//! Table layout (one parameter group): `[n_entries][F]` row-major, levels one after another.
//! Levels at or beyond `active` (progressive coarse-to-fine mask) output zeros and get no gradient.
//!
//! Three paths, fastest last, all tested against [`HashGrid::encode_naive`] (the slow reference):
//! - [`HashGrid::encode_group`]: any `N` points; the 8 corners gathered for the first point are
//!   reused for every point in the same cell; the backward sums those points' corner gradients
//!   locally before one scatter;
//! - [`HashGrid::encode_fd`] (`stencil.rs`): a sample and its six axis taps, per level, touching
//!   only the centre cell's corners and the far faces of the taps that leave it, branch-free;
//! - [`HashGrid::encode_fd_batch`] / [`HashGrid::encode_batch`] ([`super::lanes`]): the same
//!   stencil for 8 levels at a time in 16 lanes over a batch of samples, with prefetching — the
//!   training and query path (3.5× the first one forward, 3.3× backward, one thread, default
//!   table).

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::config::HashGridConfig;
use super::lanes::LaneBlock;
use super::Real;
use rand::Rng;

pub(crate) mod level;
mod position_grad;
mod stencil;

pub use level::{Level, Sides, PRIMES};
pub use stencil::{fd_point, fd_points, stencil_rows};

/// The hash grid's geometry (no parameters: those live in the flat buffer).
#[derive(Debug, Clone, PartialEq)]
pub struct HashGrid {
    pub levels: Vec<Level>,
    /// Features per level `F`.
    pub n_features: usize,
    /// Total entries of all levels (`n_params = n_entries·F`).
    pub n_entries: usize,
    pub include_xyz: bool,
    base_resolution: f64,
    per_level_scale: f64,
    init_range: f32,
    /// Level-parallel blocks of the `F = 2` fast path ([`super::lanes`]).
    lanes: Option<Vec<LaneBlock>>,
}

#[inline(always)]
fn corner_of(cell: [u32; 3], c: usize) -> [u32; 3] {
    [
        cell[0].wrapping_add((c & 1) as u32),
        cell[1].wrapping_add(((c >> 1) & 1) as u32),
        cell[2].wrapping_add(((c >> 2) & 1) as u32),
    ]
}

#[inline(always)]
fn corner_weights<T: Real>(frac: [T; 3]) -> [T; 8] {
    let wx = [T::ONE - frac[0], frac[0]];
    let wy = [T::ONE - frac[1], frac[1]];
    let wz = [T::ONE - frac[2], frac[2]];
    let mut w = [T::ZERO; 8];
    for (c, wc) in w.iter_mut().enumerate() {
        *wc = wx[c & 1] * wy[(c >> 1) & 1] * wz[c >> 2];
    }
    w
}

impl HashGrid {
    /// Builds the level table from a (validated) config.
    pub fn new(cfg: &HashGridConfig) -> Self {
        let max_entries = 1u64 << cfg.log2_hashmap_size;
        let mut levels = Vec::with_capacity(cfg.n_levels);
        let mut offset = 0usize;
        for l in 0..cfg.n_levels {
            let scale = cfg.base_resolution * cfg.per_level_scale.powi(l as i32) - 1.0;
            let resolution = scale.ceil() as u64 + 1;
            let dense = resolution.saturating_pow(3);
            let size = dense.min(max_entries).div_ceil(8) * 8;
            levels.push(Level {
                scale,
                resolution: resolution as u32,
                offset,
                size: size as u32,
                hashed: dense > size,
            });
            offset += size as usize;
        }
        let lanes = if cfg.n_features_per_level == 2 {
            LaneBlock::build(&levels, offset * 2)
        } else {
            None
        };
        Self {
            lanes,
            levels,
            n_features: cfg.n_features_per_level,
            n_entries: offset,
            include_xyz: cfg.include_xyz,
            base_resolution: cfg.base_resolution,
            per_level_scale: cfg.per_level_scale,
            init_range: cfg.init_range,
        }
    }

    /// The level-parallel blocks of the `F = 2` fast path, if this grid has them.
    pub fn lane_blocks(&self) -> Option<&[LaneBlock]> {
        self.lanes.as_deref()
    }

    /// Parameters in the table (`n_entries · F`).
    pub fn n_params(&self) -> usize {
        self.n_entries * self.n_features
    }

    /// Width of the xyz prefix (3 or 0).
    pub fn xyz_dim(&self) -> usize {
        if self.include_xyz {
            3
        } else {
            0
        }
    }

    /// Output width: `xyz_dim + L·F` (35 by default).
    pub fn output_dim(&self) -> usize {
        self.xyz_dim() + self.levels.len() * self.n_features
    }

    /// Finite-difference step in normalised units tied to the finest active level:
    /// `2r / (base·b^(active−1))`, one cell of that level (instant-nsr-pl `geometry.py`,
    /// `finite_difference_eps: progressive`).
    pub fn fd_eps(&self, active: usize, radius: f64) -> f64 {
        let l = active.clamp(1, self.levels.len()) - 1;
        2.0 * radius / (self.base_resolution * self.per_level_scale.powi(l as i32))
    }

    /// Seeded initialisation: uniform in `±init_range` (tcnn's grid initialisation).
    pub fn init<R: Rng>(&self, table: &mut [f32], rng: &mut R) {
        let r = self.init_range;
        for v in table.iter_mut() {
            *v = if r > 0.0 {
                rng.random_range(-r..r)
            } else {
                0.0
            };
        }
    }

    /// Table entry of a grid corner (not yet multiplied by `F`).
    #[inline(always)]
    fn entry(&self, lvl: &Level, c: [u32; 3]) -> usize {
        let i = if lvl.hashed {
            c[0].wrapping_mul(PRIMES[0])
                ^ c[1].wrapping_mul(PRIMES[1])
                ^ c[2].wrapping_mul(PRIMES[2])
        } else {
            let r = lvl.resolution;
            c[0].wrapping_add(c[1].wrapping_mul(r))
                .wrapping_add(c[2].wrapping_mul(r.wrapping_mul(r)))
        };
        // Hashed levels have a power-of-two size (mask); dense indices exceed the size only on
        // the upper border (corner = resolution) or for points outside [0,1], so the division is
        // rare.
        let i = if lvl.size.is_power_of_two() {
            i & (lvl.size - 1)
        } else if i >= lvl.size {
            i % lvl.size
        } else {
            i
        };
        lvl.offset + i as usize
    }

    /// Cell and fractional position of `u ∈ [0,1]³` on a level (`pos = scale·u + 0.5`). Positions
    /// outside `[0,1]` wrap like tcnn's `(uint32_t)(int)floor(pos)`.
    #[inline(always)]
    fn locate<T: Real>(lvl: &Level, u: [T; 3]) -> ([u32; 3], [T; 3]) {
        let s = T::from_f64(lvl.scale);
        let half = T::from_f64(0.5);
        let mut cell = [0u32; 3];
        let mut frac = [T::ZERO; 3];
        for d in 0..3 {
            let pos = s * u[d] + half;
            let fl = pos.floor();
            cell[d] = fl.cell_u32();
            frac[d] = pos - fl;
        }
        (cell, frac)
    }

    #[inline(always)]
    fn to_unit<T: Real>(x: [T; 3], radius: T) -> [T; 3] {
        let inv = T::ONE / (radius + radius);
        [
            (x[0] + radius) * inv,
            (x[1] + radius) * inv,
            (x[2] + radius) * inv,
        ]
    }

    /// Encodes one point `x ∈ [-r,r]³` into `out[..output_dim]`.
    pub fn encode<T: Real>(&self, table: &[T], x: [T; 3], radius: T, active: usize, out: &mut [T]) {
        self.encode_group::<T, 1>(table, &[x], radius, active, out, &[0]);
    }

    /// Backward of [`encode`](Self::encode): scatter-adds `d_out[..output_dim]` into the table
    /// gradient `grad` (same layout as the table). The xyz prefix has no parameters.
    pub fn encode_backward<T: Real>(
        &self,
        x: [T; 3],
        radius: T,
        active: usize,
        d_out: &[T],
        grad: &mut [T],
    ) {
        self.encode_group_backward::<T, 1>(&[x], radius, active, d_out, &[0], grad);
    }

    /// Encodes `N` points, writing point `p`'s encoding to `out[rows[p]..rows[p] + output_dim]`.
    /// Corners gathered for point 0 are reused for every point that falls into the same cell on a
    /// level (used for a sample and its six finite-difference taps).
    pub fn encode_group<T: Real, const N: usize>(
        &self,
        table: &[T],
        pts: &[[T; 3]; N],
        radius: T,
        active: usize,
        out: &mut [T],
        rows: &[usize; N],
    ) {
        match self.n_features {
            2 => self.encode_group_f::<T, N, 2>(table, pts, radius, active, out, rows),
            _ => self.encode_group_f::<T, N, 0>(table, pts, radius, active, out, rows),
        }
    }

    /// [`encode_group`](Self::encode_group) with the feature count fixed at compile time (`FC`),
    /// or read at run time (`FC = 0`).
    fn encode_group_f<T: Real, const N: usize, const FC: usize>(
        &self,
        table: &[T],
        pts: &[[T; 3]; N],
        radius: T,
        active: usize,
        out: &mut [T],
        rows: &[usize; N],
    ) {
        let f = if FC == 0 { self.n_features } else { FC };
        let xd = self.xyz_dim();
        let mut u = [[T::ZERO; 3]; N];
        for p in 0..N {
            u[p] = Self::to_unit(pts[p], radius);
            if self.include_xyz {
                for d in 0..3 {
                    out[rows[p] + d] = pts[p][d] / radius;
                }
            }
        }
        let mut cache = [T::ZERO; 64];
        for (l, lvl) in self.levels.iter().enumerate() {
            let base = xd + l * f;
            if l >= active {
                for p in 0..N {
                    out[rows[p] + base..rows[p] + base + f].fill(T::ZERO);
                }
                continue;
            }
            let (cell0, frac0) = Self::locate(lvl, u[0]);
            for c in 0..8 {
                let e = self.entry(lvl, corner_of(cell0, c)) * f;
                cache[c * f..c * f + f].copy_from_slice(&table[e..e + f]);
            }
            for p in 0..N {
                let (cell, frac) = if p == 0 {
                    (cell0, frac0)
                } else {
                    Self::locate(lvl, u[p])
                };
                let w = corner_weights(frac);
                let row = &mut out[rows[p] + base..rows[p] + base + f];
                row.fill(T::ZERO);
                if cell == cell0 {
                    for c in 0..8 {
                        for k in 0..f {
                            row[k] += w[c] * cache[c * f + k];
                        }
                    }
                } else {
                    for c in 0..8 {
                        let e = self.entry(lvl, corner_of(cell, c)) * f;
                        for k in 0..f {
                            row[k] += w[c] * table[e + k];
                        }
                    }
                }
            }
        }
    }

    /// Backward of [`encode_group`](Self::encode_group): `d_out[rows[p]..]` holds the gradient of
    /// point `p`'s encoding; corner gradients of the points sharing point 0's cell are summed
    /// locally and scattered once.
    pub fn encode_group_backward<T: Real, const N: usize>(
        &self,
        pts: &[[T; 3]; N],
        radius: T,
        active: usize,
        d_out: &[T],
        rows: &[usize; N],
        grad: &mut [T],
    ) {
        match self.n_features {
            2 => self.encode_group_backward_f::<T, N, 2>(pts, radius, active, d_out, rows, grad),
            _ => self.encode_group_backward_f::<T, N, 0>(pts, radius, active, d_out, rows, grad),
        }
    }

    fn encode_group_backward_f<T: Real, const N: usize, const FC: usize>(
        &self,
        pts: &[[T; 3]; N],
        radius: T,
        active: usize,
        d_out: &[T],
        rows: &[usize; N],
        grad: &mut [T],
    ) {
        let f = if FC == 0 { self.n_features } else { FC };
        let xd = self.xyz_dim();
        let mut u = [[T::ZERO; 3]; N];
        for p in 0..N {
            u[p] = Self::to_unit(pts[p], radius);
        }
        let mut acc = [T::ZERO; 64];
        for (l, lvl) in self.levels.iter().enumerate().take(active) {
            let base = xd + l * f;
            let (cell0, frac0) = Self::locate(lvl, u[0]);
            acc[..8 * f].fill(T::ZERO);
            for p in 0..N {
                let (cell, frac) = if p == 0 {
                    (cell0, frac0)
                } else {
                    Self::locate(lvl, u[p])
                };
                let w = corner_weights(frac);
                let g = &d_out[rows[p] + base..rows[p] + base + f];
                if cell == cell0 {
                    for c in 0..8 {
                        for k in 0..f {
                            acc[c * f + k] += w[c] * g[k];
                        }
                    }
                } else {
                    for c in 0..8 {
                        let e = self.entry(lvl, corner_of(cell, c)) * f;
                        for k in 0..f {
                            grad[e + k] += w[c] * g[k];
                        }
                    }
                }
            }
            for c in 0..8 {
                let e = self.entry(lvl, corner_of(cell0, c)) * f;
                for k in 0..f {
                    grad[e + k] += acc[c * f + k];
                }
            }
        }
    }

    /// Slow reference encoding in `f64`, written independently of the fast path from the config
    /// formulas: per level, per corner, explicit index arithmetic in `u64`.
    pub fn encode_naive(&self, table: &[f64], x: [f64; 3], radius: f64, active: usize) -> Vec<f64> {
        let mut out = Vec::new();
        if self.include_xyz {
            out.extend(x.iter().map(|v| v / radius));
        }
        for (l, (c, w)) in self.naive_corners(x, radius).into_iter().enumerate() {
            for k in 0..self.n_features {
                let mut s = 0.0;
                if l < active {
                    for i in 0..8 {
                        s += w[i] * table[c[i] * self.n_features + k];
                    }
                }
                out.push(s);
            }
        }
        out
    }

    /// Slow reference backward: scatter-adds `d_out` into `grad` corner by corner.
    pub fn encode_backward_naive(
        &self,
        x: [f64; 3],
        radius: f64,
        active: usize,
        d_out: &[f64],
        grad: &mut [f64],
    ) {
        let xd = self.xyz_dim();
        for (l, (c, w)) in self.naive_corners(x, radius).into_iter().enumerate() {
            if l >= active {
                continue;
            }
            for k in 0..self.n_features {
                for i in 0..8 {
                    grad[c[i] * self.n_features + k] += w[i] * d_out[xd + l * self.n_features + k];
                }
            }
        }
    }

    /// Per level: the 8 corner entries and trilinear weights, computed the long way.
    fn naive_corners(&self, x: [f64; 3], radius: f64) -> Vec<([usize; 8], [f64; 8])> {
        let mut res = Vec::new();
        let mut offset = 0u64;
        for l in 0..self.levels.len() {
            let scale = self.base_resolution * self.per_level_scale.powi(l as i32) - 1.0;
            let resolution = scale.ceil() as u64 + 1;
            let size = u64::from(self.levels[l].size);
            let dense = resolution * resolution * resolution <= size;
            let mut corners = [0usize; 8];
            let mut weights = [0f64; 8];
            let pos: Vec<f64> = (0..3)
                .map(|d| scale * ((x[d] + radius) / (2.0 * radius)) + 0.5)
                .collect();
            for i in 0..8 {
                let mut w = 1.0;
                let mut g = [0u64; 3];
                for d in 0..3 {
                    let bit = (i >> d) & 1;
                    let fl = pos[d].floor();
                    g[d] = (fl as i64 as u32 as u64 + bit as u64) & 0xffff_ffff;
                    let fr = pos[d] - fl;
                    w *= if bit == 1 { fr } else { 1.0 - fr };
                }
                let idx = if dense {
                    (g[0] + g[1] * resolution + g[2] * resolution * resolution) & 0xffff_ffff
                } else {
                    let h = g[0] & 0xffff_ffff;
                    let h = h ^ ((g[1] * 2_654_435_761) & 0xffff_ffff);
                    h ^ ((g[2] * 805_459_861) & 0xffff_ffff)
                };
                corners[i] = (offset + idx % size) as usize;
                weights[i] = w;
            }
            res.push((corners, weights));
            offset += size;
        }
        res
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_pcg::Pcg64Mcg;

    pub(super) fn small() -> HashGridConfig {
        HashGridConfig {
            n_levels: 6,
            n_features_per_level: 2,
            log2_hashmap_size: 10,
            base_resolution: 4.0,
            per_level_scale: 1.9,
            ..Default::default()
        }
    }

    #[test]
    fn default_levels_match_tcnn() {
        let g = HashGrid::new(&HashGridConfig::default());
        let res: Vec<u32> = g.levels.iter().map(|l| l.resolution).collect();
        assert_eq!(res[0], 32);
        assert_eq!(res[15], 2048);
        let dense = g.levels.iter().filter(|l| !l.hashed).count();
        // 32³, 43³, 56³, 74³ fit in 2^19 entries; 97³ does not.
        assert_eq!(dense, 4, "resolutions {res:?}");
        assert_eq!(g.levels[0].size, 32 * 32 * 32);
        assert_eq!(g.levels[15].size, 1 << 19);
        assert_eq!(g.output_dim(), 35);
        let eps = g.fd_eps(16, 1.0);
        assert!((eps - 2.0 / 2048.0).abs() < 1e-9, "{eps}");
    }

    #[test]
    fn fast_group_matches_naive() {
        let g = HashGrid::new(&small());
        let mut rng = Pcg64Mcg::seed_from_u64(7);
        let table: Vec<f64> = (0..g.n_params())
            .map(|_| rng.random_range(-1.0..1.0))
            .collect();
        let r = 1.0;
        let d = g.output_dim();
        let mut worst = 0.0f64;
        for trial in 0..200 {
            let mut c = [0.0; 3];
            for v in c.iter_mut() {
                *v = rng.random_range(-1.0..1.0);
            }
            if trial == 0 {
                c = [1.0, -1.0, 1.0]; // box corner
            }
            let eps = if trial % 2 == 0 { 0.3 } else { 1e-3 };
            let mut pts = [c; 7];
            for k in 0..6 {
                pts[k + 1][k / 2] += if k % 2 == 0 { eps } else { -eps };
            }
            let rows = [0, d, 2 * d, 3 * d, 4 * d, 5 * d, 6 * d];
            let active = 1 + trial % 6;
            let mut out = vec![0.0; 7 * d];
            g.encode_group(&table, &pts, r, active, &mut out, &rows);
            for p in 0..7 {
                let want = g.encode_naive(&table, pts[p], r, active);
                for j in 0..d {
                    worst = worst.max((want[j] - out[rows[p] + j]).abs());
                }
            }
            // backward
            let dout: Vec<f64> = (0..7 * d).map(|_| rng.random_range(-1.0..1.0)).collect();
            let mut gf = vec![0.0; g.n_params()];
            let mut gn = vec![0.0; g.n_params()];
            g.encode_group_backward(&pts, r, active, &dout, &rows, &mut gf);
            for p in 0..7 {
                g.encode_backward_naive(pts[p], r, active, &dout[rows[p]..rows[p] + d], &mut gn);
            }
            for (a, b) in gf.iter().zip(&gn) {
                worst = worst.max((a - b).abs());
            }
        }
        assert!(worst < 1e-12, "fast vs naive max diff {worst}");
    }

    #[test]
    fn masked_levels_are_zero_and_get_no_gradient() {
        let g = HashGrid::new(&small());
        let table = vec![1.0f64; g.n_params()];
        let mut out = vec![9.0; g.output_dim()];
        g.encode(&table, [0.1, 0.2, 0.3], 1.0, 2, &mut out);
        // Levels 0 and 1 interpolate a constant table: 1; levels 2.. masked: 0.
        assert_eq!(&out[3..7], &[1.0; 4]);
        assert!(out[7..].iter().all(|&v| v == 0.0));
        assert_eq!(&out[..3], &[0.1, 0.2, 0.3]);
        let mut grad = vec![0.0; g.n_params()];
        g.encode_backward(
            [0.1, 0.2, 0.3],
            1.0,
            2,
            &vec![1.0; g.output_dim()],
            &mut grad,
        );
        let l2 = g.levels[2].offset * 2;
        assert!(grad[l2..].iter().all(|&v| v == 0.0));
        // Trilinear weights sum to one per level and feature.
        let total: f64 = grad[..l2].iter().sum();
        assert!((total - 4.0).abs() < 1e-12, "{total}");
    }

    #[test]
    fn gradient_matches_central_differences() {
        // The encoding is linear in the table, so differences are exact up to rounding.
        let g = HashGrid::new(&small());
        let mut rng = Pcg64Mcg::seed_from_u64(3);
        let mut table: Vec<f64> = (0..g.n_params())
            .map(|_| rng.random_range(-1.0..1.0))
            .collect();
        let x = [0.31, -0.72, 0.05];
        let w: Vec<f64> = (0..g.output_dim())
            .map(|_| rng.random_range(-1.0..1.0))
            .collect();
        let loss = |t: &[f64]| -> f64 {
            let mut o = vec![0.0; g.output_dim()];
            g.encode(t, x, 1.0, 6, &mut o);
            o.iter().zip(&w).map(|(a, b)| a * b).sum()
        };
        let mut grad = vec![0.0; g.n_params()];
        g.encode_backward(x, 1.0, 6, &w, &mut grad);
        let mut fails = Vec::new();
        for i in (0..g.n_params()).step_by(7) {
            let h = 1e-5;
            let old = table[i];
            table[i] = old + h;
            let lp = loss(&table);
            table[i] = old - h;
            let lm = loss(&table);
            table[i] = old;
            let fd = (lp - lm) / (2.0 * h);
            if (fd - grad[i]).abs() > 1e-8 + 1e-6 * fd.abs() {
                fails.push(format!("entry {i}: analytic {} fd {fd}", grad[i]));
            }
        }
        assert!(fails.is_empty(), "{}", fails.join("\n"));
    }
}
