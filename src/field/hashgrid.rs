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
//! - [`HashGrid::encode_fd`]: a sample and its six axis taps, per level, touching only the centre
//!   cell's corners and the far faces of the taps that leave it, branch-free;
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

/// One resolution level of the grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Level {
    /// `base·b^l − 1`.
    pub scale: f64,
    /// `ceil(scale) + 1` (dense index stride).
    pub resolution: u32,
    /// First entry of this level in the table.
    pub offset: usize,
    /// Entries of this level.
    pub size: u32,
    /// Hashed (true) or dense (false).
    pub hashed: bool,
}

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

/// Spatial-hash primes per axis (tcnn `grid.h`; Müller et al. 2022 eq. 4): a hashed corner's
/// entry is `(x·P0 ^ y·P1 ^ z·P2) mod T`, wrapping `u32`. Shared with [`super::lanes`].
pub(super) const PRIMES: [u32; 3] = [1, 2_654_435_761, 805_459_861];

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

/// The seven points of a finite-difference stencil (see [`fd_point`]).
#[inline(always)]
pub fn fd_points<T: Copy>(x: [T; 3], taps: [[T; 2]; 3]) -> [[T; 3]; 7] {
    std::array::from_fn(|p| fd_point(x, taps, p))
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

    fn small() -> HashGridConfig {
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
