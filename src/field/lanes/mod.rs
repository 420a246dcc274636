//! Level-parallel finite-difference stencil of the hash grid (the training hot path, `F = 2`).
//!
//! [`HashGrid::encode_fd`](super::HashGrid::encode_fd) visits levels one after another. Here one
//! block of 8 levels is processed at once in 16 lanes, lane `2·j + f` = feature `f` of level
//! `level0 + j`, which is exactly the layout of 16 consecutive values of an encoding row
//! (`[xyz, level 0 f0, level 0 f1, level 1 f0, …]`). Every step (positions, cells, fractions, the
//! face interpolation of the seven points) is the same arithmetic on 16 independent lanes, which
//! the compiler turns into vector instructions for `f32`. The table indices (per-axis terms,
//! hashing, the modulo) depend on the level alone, so they are computed once per level, on 8
//! lanes: the two features of a level sit in adjacent slots, read and written as one pair at the
//! level's index. That halves the planning's integer work (callgrind, `x86-64-v3`, two `fast`
//! steps: 7 % fewer instructions in all). The table reads and gradient writes are 8 independent
//! pair loads / read-modify-writes (different levels live in disjoint table regions, so the
//! pairs of one access never alias).
//!
//! Geometry of the stencil (same as the per-level path): the centre cell's 8 corners, plus for
//! each of the six taps the 4 corners of the far face of the tap's cell when the tap leaves the
//! centre cell (a tap moves at most one cell when `ε` is at most one cell of the finest active
//! level), and, for one-sided samples only, those of a second far face when a tap moves two
//! cells (the one-sided taps at `2ε`, `RenderConfig::fd_one_sided_span`). Along the tap's axis
//! the value is a linear interpolation between two faces chosen per lane from
//! `[face 0, face 1, far face, second far face]`; the faces are bilinear interpolations with the
//! shared weights of the two other axes. A sample whose taps move further falls back to the
//! per-level path (the caller checks the returned flag). The kernels take a const `TWO`: the
//! central samples' form (`false`) never reads or writes a second far face, so it compiles to
//! the one-cell stencil alone ([`PlanTwo`]).
//!
//! The code is generic over [`Real`]: the `f64` gradient checks run this same code.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::hashgrid::level::{Level, Sides, PRIMES};
use super::Real;

mod batch;

/// Lanes per block: 8 levels × 2 features.
pub const LANES: usize = 16;
/// Levels per block: the table indices are per level (the two features of a level are adjacent
/// slots, so lane `2j + 1` reads index `j` plus one), and their integer work runs on 8 lanes.
const LV: usize = LANES / 2;

/// Per-lane constants of a block of up to 8 levels (`F = 2`).
#[derive(Debug, Clone, PartialEq)]
pub struct LaneBlock {
    /// First level of the block.
    pub level0: usize,
    /// Levels in the block (≤ 8); lanes of missing levels repeat the block's first level and are
    /// masked out.
    pub n_levels: usize,
    scale: [f64; LANES],
    /// Per level `j` of the block (index lanes, [`LV`]): per-axis multipliers of the cell
    /// coordinates: hashed `(1, π₁, π₂)`, dense `(1, r, r²)`.
    mul: [[u32; LV]; 3],
    /// All ones on hashed levels (combine the terms with xor), zero on dense ones (add them).
    hashed: [u32; LV],
    size: [u32; LV],
    /// `size − 1` for power-of-two sizes, all ones otherwise (then a conditional subtraction
    /// reduces the index).
    and_mask: [u32; LV],
    /// Flat index of the level's entry 0, feature 0: `2·offset`.
    base: [u32; LV],
}

impl LaneBlock {
    /// Blocks covering `levels` (F = 2), or `None` when flat indices would not fit in `u32`.
    pub fn build(levels: &[Level], n_params: usize) -> Option<Vec<LaneBlock>> {
        if n_params >= u32::MAX as usize {
            return None;
        }
        let mut blocks = Vec::new();
        for level0 in (0..levels.len()).step_by(LANES / 2) {
            let n_levels = (levels.len() - level0).min(LANES / 2);
            let mut b = LaneBlock {
                level0,
                n_levels,
                scale: [0.0; LANES],
                mul: [[0; LV]; 3],
                hashed: [0; LV],
                size: [0; LV],
                and_mask: [0; LV],
                base: [0; LV],
            };
            for lane in 0..LANES {
                let j = if lane / 2 < n_levels { lane / 2 } else { 0 };
                b.scale[lane] = levels[level0 + j].scale;
            }
            for lane in 0..LV {
                let j = if lane < n_levels { lane } else { 0 };
                let lvl = &levels[level0 + j];
                let r = lvl.resolution;
                let m = if lvl.hashed {
                    PRIMES
                } else {
                    [1, r, r.wrapping_mul(r)]
                };
                for a in 0..3 {
                    b.mul[a][lane] = m[a];
                }
                b.hashed[lane] = if lvl.hashed { u32::MAX } else { 0 };
                b.size[lane] = lvl.size;
                b.and_mask[lane] = if lvl.size.is_power_of_two() {
                    lvl.size - 1
                } else {
                    u32::MAX
                };
                b.base[lane] = (2 * lvl.offset) as u32;
            }
            blocks.push(b);
        }
        Some(blocks)
    }
}

type L<T> = [T; LANES];
/// Per-level table indices of a block: entry `j` is feature 0 of level `level0 + j`.
type I = [u32; LV];

/// Everything the forward and backward of one block need for one sample. Filled by
/// [`LaneBlock::plan`] into a buffer the caller keeps across samples (nothing is zeroed or copied
/// per sample; far-face entries are only read where `any_far` says they were written).
#[derive(Clone)]
pub(crate) struct Plan<T> {
    /// Centre-corner flat indices per level (corner bit `a` = offset along axis `a`).
    ce: [I; 8],
    /// Far-face flat indices `[axis][+/−][face corner]` per level: the face one cell beyond the
    /// centre cell's (`cell + 2` for the `+` tap, `cell − 1` for the `−` tap).
    fe: [[[I; 4]; 2]; 3],
    /// Whether any lane of tap `[axis][+/−]` leaves the centre cell.
    any_far: [[bool; 2]; 3],
    /// Lane masks (all ones / zero): the tap `[axis][+/−]` leaves the centre cell.
    far_m: [[L<u32>; 2]; 3],
    /// Weights `[axis][0/1]` of the centre (`1 − frac`, `frac`).
    w: [[L<T>; 2]; 3],
    /// Fractions of the taps along their axis.
    ft: [[L<T>; 2]; 3],
}

/// What a one-sided sample's taps two cells out add to its [`Plan`]: the second far faces.
/// Kept apart from the plan and read only by the kernels' `TWO = true` forms, so that the
/// central path's plans and code are those of the one-cell stencil (a plan holding these
/// fields slowed the central step by about 4 %).
#[derive(Clone)]
pub(crate) struct PlanTwo {
    /// Whether any lane of tap `[axis][+/−]` moves two cells.
    any_far2: [[bool; 2]; 3],
    /// Second far face, one more cell out (`cell + 3` / `cell − 2`), `[axis][+/−][face corner]`,
    /// per level.
    fe2: [[[I; 4]; 2]; 3],
    /// Lane masks: the tap `[axis][+/−]` moves two cells.
    far2_m: [[L<u32>; 2]; 3],
}

impl Default for PlanTwo {
    fn default() -> Self {
        Self {
            any_far2: [[false; 2]; 3],
            fe2: [[[[0; LV]; 4]; 2]; 3],
            far2_m: [[[0; LANES]; 2]; 3],
        }
    }
}

impl<T: Real> Default for Plan<T> {
    fn default() -> Self {
        Self {
            ce: [[0; LV]; 8],
            fe: [[[[0; LV]; 4]; 2]; 3],
            any_far: [[false; 2]; 3],
            far_m: [[[0; LANES]; 2]; 3],
            w: [[[T::ZERO; LANES]; 2]; 3],
            ft: [[[T::ZERO; LANES]; 2]; 3],
        }
    }
}

/// Two per-axis index terms combined both ways (hashed levels xor, dense levels add).
#[derive(Clone, Copy, Default)]
struct Pair {
    x: I,
    a: I,
}

/// Per-call lane constants of a block: scales in `T` and the active-lane mask.
#[derive(Clone, Copy)]
pub(crate) struct LaneConsts<T> {
    sc: L<T>,
    /// All ones on lanes of active levels.
    act: L<u32>,
}

/// Corner index of face corner `q` of axis `a` at offset `i` along `a` (the other axes `b`,
/// `c` = `a+1`, `a+2` mod 3 take bits 0 and 1 of `q`).
#[inline(always)]
fn corner(a: usize, i: usize, q: usize) -> usize {
    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
    (i << a) | ((q & 1) << b) | ((q >> 1) << c)
}

impl LaneBlock {
    /// Lane constants for `active` levels.
    pub(crate) fn consts<T: Real>(&self, active: usize) -> LaneConsts<T> {
        let mut c = LaneConsts {
            sc: [T::ZERO; LANES],
            act: [0; LANES],
        };
        for l in 0..LANES {
            c.sc[l] = T::from_f64(self.scale[l]);
            let on = l / 2 < self.n_levels && self.level0 + l / 2 < active;
            c.act[l] = if on { u32::MAX } else { 0 };
        }
        c
    }

    /// Flat indices (feature 0) of the levels from a pair of per-axis terms combined beforehand
    /// (`pair`, `xor` and `add` forms, see [`Pair`]) and the third axis' term `t`, reduced
    /// modulo the level size.
    #[inline(always)]
    fn index(&self, pair: &Pair, t: &I) -> I {
        let mut out = [0u32; LV];
        let mut slow = false;
        for l in 0..LV {
            let h = pair.x[l] ^ t[l];
            let d = pair.a[l].wrapping_add(t[l]);
            let mh = self.hashed[l];
            let i = ((h & mh) | (d & !mh)) & self.and_mask[l];
            // Dense levels: one subtraction covers the corners of cells inside the box.
            let s = self.size[l];
            let i = if i >= s { i.wrapping_sub(s) } else { i };
            slow |= i >= s;
            out[l] = i;
        }
        if slow {
            // Far outside the level (points outside the box): the exact modulo, lane by lane.
            for l in 0..LV {
                let h = pair.x[l] ^ t[l];
                let d = pair.a[l].wrapping_add(t[l]);
                let i = if self.hashed[l] != 0 { h } else { d };
                out[l] = i % self.size[l];
            }
        }
        for l in 0..LV {
            out[l] = self.base[l].wrapping_add(out[l].wrapping_mul(2));
        }
        out
    }

    /// The centre part of [`plan`](Self::plan) alone (weights and the 8 corner indices), for
    /// points without taps.
    #[inline(always)]
    fn plan_centre<T: Real>(&self, k: &LaneConsts<T>, uc: [T; 3], pl: &mut Plan<T>) {
        let half = T::from_f64(0.5);
        let mut terms = [[[0u32; LV]; 2]; 3];
        for a in 0..3 {
            let mut cell = [0u32; LANES];
            for l in 0..LANES {
                let pos = k.sc[l] * uc[a] + half;
                let fl = pos.floor();
                cell[l] = fl.cell_u32();
                let f = pos - fl;
                pl.w[a][0][l] = T::ONE - f;
                pl.w[a][1][l] = f;
            }
            for j in 0..LV {
                let c = cell[2 * j];
                terms[a][0][j] = c.wrapping_mul(self.mul[a][j]);
                terms[a][1][j] = c.wrapping_add(1).wrapping_mul(self.mul[a][j]);
            }
        }
        for q in 0..4 {
            let (ty, tz) = (&terms[1][q & 1], &terms[2][q >> 1]);
            let mut pr = Pair::default();
            for l in 0..LV {
                pr.x[l] = ty[l] ^ tz[l];
                pr.a[l] = ty[l].wrapping_add(tz[l]);
            }
            for i in 0..2 {
                pl.ce[(q << 1) | i] = self.index(&pr, &terms[0][i]);
            }
        }
    }

    /// Fills `pl` with the cells, fractions, tap offsets and (if `indices`) table indices of one
    /// sample; the taps of a side not in `sides` are left out (a one-sided difference: nothing
    /// of theirs is planned, read or written). Returns false if a tap moves more than one cell
    /// on an active lane, or, with `TWO` (one-sided samples only), two cells; the second far
    /// faces then go to `two` (left untouched without `TWO`).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn plan<T: Real, const TWO: bool>(
        &self,
        k: &LaneConsts<T>,
        uc: [T; 3],
        ut: [[T; 2]; 3],
        sides: Sides,
        indices: bool,
        pl: &mut Plan<T>,
        two: &mut PlanTwo,
    ) -> bool {
        debug_assert!(!TWO || sides != Sides::Both);
        let half = T::from_f64(0.5);
        let mut cell = [[0u32; LANES]; 3];
        let mut ok = true;
        for a in 0..3 {
            for l in 0..LANES {
                let pos = k.sc[l] * uc[a] + half;
                let fl = pos.floor();
                cell[a][l] = fl.cell_u32();
                let f = pos - fl;
                pl.w[a][0][l] = T::ONE - f;
                pl.w[a][1][l] = f;
            }
            for p in 0..2 {
                if !sides.slots().contains(&p) {
                    pl.any_far[a][p] = false;
                    if TWO {
                        two.any_far2[a][p] = false;
                    }
                    continue;
                }
                let (mut bad, mut any, mut any2) = (0u32, 0u32, 0u32);
                let ftp = &mut pl.ft[a][p];
                let farm = &mut pl.far_m[a][p];
                if !TWO {
                    // Taps at most one cell out: d ∈ {0, 1} (+) or {0, −1} (−).
                    for l in 0..LANES {
                        let pos = k.sc[l] * ut[a][p] + half;
                        let fl = pos.floor();
                        ftp[l] = pos - fl;
                        let d = fl.cell_u32().wrapping_sub(cell[a][l]);
                        let dd = if p == 0 { d } else { d.wrapping_add(1) };
                        let act = k.act[l];
                        bad |= if dd > 1 { act } else { 0 };
                        let far = if d != 0 { act } else { 0 };
                        farm[l] = far;
                        any |= far;
                    }
                } else {
                    // One-sided taps may sit up to 2ε out (`fd_one_sided_span`).
                    let far2m = &mut two.far2_m[a][p];
                    for l in 0..LANES {
                        let pos = k.sc[l] * ut[a][p] + half;
                        let fl = pos.floor();
                        ftp[l] = pos - fl;
                        let d = fl.cell_u32().wrapping_sub(cell[a][l]);
                        // Cells moved: + tap d ∈ {0, 1, 2}; − tap d ∈ {0, −1, −2}.
                        let moved = if p == 0 { d } else { 0u32.wrapping_sub(d) };
                        let act = k.act[l];
                        bad |= if moved > 2 { act } else { 0 };
                        let far = if moved != 0 { act } else { 0 };
                        let far2 = if moved == 2 { act } else { 0 };
                        farm[l] = far;
                        far2m[l] = far2;
                        any |= far;
                        any2 |= far2;
                    }
                }
                ok &= bad == 0;
                pl.any_far[a][p] = any != 0;
                if TWO {
                    two.any_far2[a][p] = any2 != 0;
                }
            }
        }
        if !ok || !indices {
            return ok;
        }
        // Per-axis terms of the coordinates cell and cell+1 (`terms[a][1]`, `terms[a][2]`; a
        // neighbour's term is one multiplier away).
        let mut terms = [[[0u32; LV]; 4]; 3];
        for a in 0..3 {
            for m in 1..3 {
                for j in 0..LV {
                    terms[a][m][j] = cell[a][2 * j]
                        .wrapping_add(m as u32)
                        .wrapping_sub(1)
                        .wrapping_mul(self.mul[a][j]);
                }
            }
        }
        // Combined terms of the two axes other than `a`, for the 4 face corners `q`.
        let mut pairs = [[Pair::default(); 4]; 3];
        for a in 0..3 {
            let (b, c2) = ((a + 1) % 3, (a + 2) % 3);
            for q in 0..4 {
                let (tb, tc) = (&terms[b][1 + (q & 1)], &terms[c2][1 + (q >> 1)]);
                let pr = &mut pairs[a][q];
                for l in 0..LV {
                    pr.x[l] = tb[l] ^ tc[l];
                    pr.a[l] = tb[l].wrapping_add(tc[l]);
                }
            }
        }
        for c in 0..8 {
            // Corner c = face corner q of axis 0 at offset i = c & 1 (q: bits of y and z).
            pl.ce[c] = self.index(&pairs[0][c >> 1], &terms[0][1 + (c & 1)]);
        }
        for a in 0..3 {
            let mul = &self.mul[a];
            let mut ta = [0u32; LV];
            // + tap: far face at cell+1+d, term `terms[a][2]` plus `d` multipliers.
            if pl.any_far[a][0] {
                let (t, m) = (&terms[a][2], &pl.far_m[a][0]);
                for l in 0..LV {
                    ta[l] = t[l].wrapping_add(m[2 * l] & mul[l]);
                }
                for q in 0..4 {
                    pl.fe[a][0][q] = self.index(&pairs[a][q], &ta);
                }
            }
            // + tap moving two cells: second far face at cell+3 (two multipliers more).
            if TWO && two.any_far2[a][0] {
                let (t, m) = (&terms[a][2], &two.far2_m[a][0]);
                for l in 0..LV {
                    ta[l] = t[l].wrapping_add((m[2 * l] & mul[l]).wrapping_mul(2));
                }
                for q in 0..4 {
                    two.fe2[a][0][q] = self.index(&pairs[a][q], &ta);
                }
            }
            // − tap: far face at cell+d, term `terms[a][1]` minus `|d|` multipliers.
            if pl.any_far[a][1] {
                let (t, m) = (&terms[a][1], &pl.far_m[a][1]);
                for l in 0..LV {
                    ta[l] = t[l].wrapping_sub(m[2 * l] & mul[l]);
                }
                for q in 0..4 {
                    pl.fe[a][1][q] = self.index(&pairs[a][q], &ta);
                }
            }
            // − tap moving two cells: second far face at cell−2.
            if TWO && two.any_far2[a][1] {
                let (t, m) = (&terms[a][1], &two.far2_m[a][1]);
                for l in 0..LV {
                    ta[l] = t[l].wrapping_sub((m[2 * l] & mul[l]).wrapping_mul(2));
                }
                for q in 0..4 {
                    two.fe2[a][1][q] = self.index(&pairs[a][q], &ta);
                }
            }
        }
        true
    }
}

/// The 16 lane values at the per-level indices `idx`: 8 pairs (the two features of a level are
/// adjacent: lanes `2j`, `2j + 1` read `idx[j]`, `idx[j] + 1`), loaded as 8 two-element reads.
#[inline(always)]
fn gather<T: Real>(buf: &[T], idx: &I) -> L<T> {
    let mut v = [T::ZERO; LANES];
    for j in 0..LV {
        // SAFETY: every index is `2·offset_l + 2·(e mod size_l)`, so the pair `idx[j]`,
        // `idx[j] + 1` lies below `2·n_entries`, and the callers assert
        // `buf.len() >= n_params = 2·n_entries`.
        let pair = unsafe { *(buf.as_ptr().add(idx[j] as usize) as *const [T; 2]) };
        v[2 * j] = pair[0];
        v[2 * j + 1] = pair[1];
    }
    v
}

/// Adds the 16 lane values at `idx` (8 pair read-modify-writes, see [`gather`]).
#[inline(always)]
fn scatter_add<T: Real>(buf: &mut [T], idx: &I, v: &L<T>) {
    for j in 0..LV {
        // SAFETY: as in `gather`. Pairs of one call never alias (distinct levels); calls are
        // sequential.
        unsafe {
            let p = &mut *(buf.as_mut_ptr().add(idx[j] as usize) as *mut [T; 2]);
            p[0] += v[2 * j];
            p[1] += v[2 * j + 1];
        }
    }
}

#[inline(always)]
fn prefetch<T>(buf: &[T], i: u32) {
    #[cfg(target_arch = "x86_64")]
    {
        let p = buf.as_ptr().wrapping_add(i as usize) as *const i8;
        // SAFETY: a prefetch is a hint; it never faults, whatever the address.
        #[allow(unused_unsafe)]
        unsafe {
            std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p)
        };
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (buf, i);
    }
}

/// Face values `[face 0, face 1]` of axis `a` from the centre corners, and the bilinear weights
/// of that axis' faces.
#[inline(always)]
fn faces<T: Real>(w: &[[L<T>; 2]; 3], a: usize) -> [L<T>; 4] {
    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
    let mut wq = [[T::ZERO; LANES]; 4];
    for q in 0..4 {
        for l in 0..LANES {
            wq[q][l] = w[b][q & 1][l] * w[c][q >> 1][l];
        }
    }
    wq
}

/// Forward of one block for one sample from its plan; `rows[p]` is the start of point `p`'s
/// 16 values. The rows of taps of a side not in `sides` are not written. `TWO`: the sample was
/// planned with second far faces (`two`, one-sided samples); without it `two` is not read.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn block_forward<T: Real, const TWO: bool>(
    blk: &LaneBlock,
    k: &LaneConsts<T>,
    pl: &Plan<T>,
    two: &PlanTwo,
    table: &[T],
    out: &mut [T],
    rows: &[usize; 7],
    sides: Sides,
) {
    let cv: [L<T>; 8] = std::array::from_fn(|c| gather(table, &pl.ce[c]));
    let n = 2 * blk.n_levels;
    for a in 0..3 {
        let wq = faces(&pl.w, a);
        let mut f0 = [T::ZERO; LANES];
        let mut f1 = [T::ZERO; LANES];
        for q in 0..4 {
            let (c0, c1) = (corner(a, 0, q), corner(a, 1, q));
            for l in 0..LANES {
                f0[l] = wq[q][l].fma(cv[c0][l], f0[l]);
                f1[l] = wq[q][l].fma(cv[c1][l], f1[l]);
            }
        }
        if a == 0 {
            let mut v = [T::ZERO; LANES];
            for l in 0..LANES {
                let x = pl.w[0][0][l].fma(f0[l], pl.w[0][1][l] * f1[l]);
                v[l] = if k.act[l] != 0 { x } else { T::ZERO };
            }
            out[rows[0]..rows[0] + n].copy_from_slice(&v[..n]);
        }
        for p in sides.slots() {
            let mut ff = [T::ZERO; LANES];
            if pl.any_far[a][p] {
                for q in 0..4 {
                    let fv = gather(table, &pl.fe[a][p][q]);
                    for l in 0..LANES {
                        ff[l] = wq[q][l].fma(fv[l], ff[l]);
                    }
                }
            }
            let far2_here = TWO && two.any_far2[a][p];
            let mut ff2 = [T::ZERO; LANES];
            if far2_here {
                for q in 0..4 {
                    let fv = gather(table, &two.fe2[a][p][q]);
                    for l in 0..LANES {
                        ff2[l] = wq[q][l].fma(fv[l], ff2[l]);
                    }
                }
            }
            let mut v = [T::ZERO; LANES];
            let (ft, farm) = (&pl.ft[a][p], &pl.far_m[a][p]);
            // The one- and two-cell forms in separate loops: without a lane two cells out, the
            // plain selects.
            if !far2_here {
                for l in 0..LANES {
                    let t = ft[l];
                    let far = farm[l] != 0;
                    // + tap: (f0, f1) or (f1, far); − tap: (f0, f1) or (far, f0).
                    let (lo, hi) = if p == 0 {
                        (
                            if far { f1[l] } else { f0[l] },
                            if far { ff[l] } else { f1[l] },
                        )
                    } else {
                        (
                            if far { ff[l] } else { f0[l] },
                            if far { f0[l] } else { f1[l] },
                        )
                    };
                    let x = (T::ONE - t).fma(lo, t * hi);
                    v[l] = if k.act[l] != 0 { x } else { T::ZERO };
                }
            } else {
                let far2m = &two.far2_m[a][p];
                for l in 0..LANES {
                    let t = ft[l];
                    let (far, far2) = (farm[l] != 0, far2m[l] != 0);
                    // + tap: (f0, f1), (f1, far) or (far, far2); − tap: (f0, f1), (far, f0)
                    // or (far2, far).
                    let (lo, hi) = if p == 0 {
                        let lo = if far { f1[l] } else { f0[l] };
                        let hi = if far { ff[l] } else { f1[l] };
                        (
                            if far2 { ff[l] } else { lo },
                            if far2 { ff2[l] } else { hi },
                        )
                    } else {
                        let lo = if far { ff[l] } else { f0[l] };
                        let hi = if far { f0[l] } else { f1[l] };
                        (
                            if far2 { ff2[l] } else { lo },
                            if far2 { ff[l] } else { hi },
                        )
                    };
                    let x = (T::ONE - t).fma(lo, t * hi);
                    v[l] = if k.act[l] != 0 { x } else { T::ZERO };
                }
            }
            let r = rows[1 + 2 * a + p];
            out[r..r + n].copy_from_slice(&v[..n]);
        }
    }
}

/// Backward of one block for one sample from its plan: scatter-adds the gradient of the 16
/// values of each of the seven points (`d_out[rows[p]..]`) into `grad`; the rows of taps of a
/// side not in `sides` are not read. `TWO` and `two` as in [`block_forward`].
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn block_backward<T: Real, const TWO: bool>(
    blk: &LaneBlock,
    k: &LaneConsts<T>,
    pl: &Plan<T>,
    two: &PlanTwo,
    grad: &mut [T],
    d_out: &[T],
    rows: &[usize; 7],
    sides: Sides,
) {
    let inp = BwdIn {
        k,
        pl,
        two,
        d_out,
        rows,
        sides,
        n: 2 * blk.n_levels,
    };
    let mut dc = [[T::ZERO; LANES]; 8];
    bwd_axis::<T, TWO, 0>(&inp, grad, &mut dc);
    bwd_axis::<T, TWO, 1>(&inp, grad, &mut dc);
    bwd_axis::<T, TWO, 2>(&inp, grad, &mut dc);
    for c in 0..8 {
        scatter_add(grad, &pl.ce[c], &dc[c]);
    }
}

/// Row `r` of `d_out` (`n` values, the rest and inactive levels' lanes zero).
#[inline(always)]
fn load_row<T: Real>(k: &LaneConsts<T>, d_out: &[T], r: usize, n: usize) -> L<T> {
    let mut g = [T::ZERO; LANES];
    if n == LANES {
        g.copy_from_slice(&d_out[r..r + LANES]);
    } else {
        g[..n].copy_from_slice(&d_out[r..r + n]);
    }
    for l in 0..LANES {
        g[l] = if k.act[l] != 0 { g[l] } else { T::ZERO };
    }
    g
}

/// The read-only inputs of one sample's [`block_backward`], shared by its three [`bwd_axis`]
/// calls: `n` is the block's active lane count (`2 × levels`).
struct BwdIn<'a, T> {
    k: &'a LaneConsts<T>,
    pl: &'a Plan<T>,
    two: &'a PlanTwo,
    d_out: &'a [T],
    rows: &'a [usize; 7],
    sides: Sides,
    n: usize,
}

/// Axis `A` of [`block_backward`]: scatters the far faces of the taps along `A` and adds the
/// centre corners' share to `dc`. A const axis, so that the corner indices are constants (a
/// loop over the axes computed them at run time, with bounds checks).
#[inline(always)]
fn bwd_axis<T: Real, const TWO: bool, const A: usize>(
    inp: &BwdIn<'_, T>,
    grad: &mut [T],
    dc: &mut [L<T>; 8],
) {
    let BwdIn {
        k,
        pl,
        two,
        d_out,
        rows,
        sides,
        n,
    } = *inp;
    let a = A;
    let load = |r: usize| load_row(k, d_out, r, n);
    let wq = faces(&pl.w, a);
    let mut d0 = [T::ZERO; LANES];
    let mut d1 = [T::ZERO; LANES];
    if a == 0 {
        let g = load(rows[0]);
        for l in 0..LANES {
            d0[l] = pl.w[0][0][l] * g[l];
            d1[l] = pl.w[0][1][l] * g[l];
        }
    }
    for p in sides.slots() {
        let g = load(rows[1 + 2 * a + p]);
        let mut dfar = [T::ZERO; LANES];
        let mut dfar2 = [T::ZERO; LANES];
        let (ft, farm) = (&pl.ft[a][p], &pl.far_m[a][p]);
        let z = T::ZERO;
        let far2_here = TWO && two.any_far2[a][p];
        if !far2_here {
            for l in 0..LANES {
                let t = ft[l];
                let (glo, ghi) = ((T::ONE - t) * g[l], t * g[l]);
                let far = farm[l] != 0;
                if p == 0 {
                    // (f0, f1) ← (glo, ghi), or (f1, far) ← (glo, ghi).
                    d0[l] += if far { z } else { glo };
                    d1[l] += if far { glo } else { ghi };
                    dfar[l] = if far { ghi } else { z };
                } else {
                    // (f0, f1) ← (glo, ghi), or (far, f0) ← (glo, ghi).
                    d0[l] += if far { ghi } else { glo };
                    d1[l] += if far { z } else { ghi };
                    dfar[l] = if far { glo } else { z };
                }
            }
        } else {
            let far2m = &two.far2_m[a][p];
            for l in 0..LANES {
                let t = ft[l];
                let (glo, ghi) = ((T::ONE - t) * g[l], t * g[l]);
                let (far, far2) = (farm[l] != 0, far2m[l] != 0);
                if p == 0 {
                    // … or (far, far2) ← (glo, ghi).
                    d0[l] += if far { z } else { glo };
                    let d1v = if far { glo } else { ghi };
                    d1[l] += if far2 { z } else { d1v };
                    let fv = if far { ghi } else { z };
                    dfar[l] = if far2 { glo } else { fv };
                    dfar2[l] = if far2 { ghi } else { z };
                } else {
                    // … or (far2, far) ← (glo, ghi).
                    let d0v = if far { ghi } else { glo };
                    d0[l] += if far2 { z } else { d0v };
                    d1[l] += if far { z } else { ghi };
                    let fv = if far { glo } else { z };
                    dfar[l] = if far2 { ghi } else { fv };
                    dfar2[l] = if far2 { glo } else { z };
                }
            }
        }
        if far2_here {
            for q in 0..4 {
                let mut v = [T::ZERO; LANES];
                for l in 0..LANES {
                    v[l] = wq[q][l] * dfar2[l];
                }
                scatter_add(grad, &two.fe2[a][p][q], &v);
            }
        }
        if pl.any_far[a][p] {
            for q in 0..4 {
                let mut v = [T::ZERO; LANES];
                for l in 0..LANES {
                    v[l] = wq[q][l] * dfar[l];
                }
                scatter_add(grad, &pl.fe[a][p][q], &v);
            }
        }
    }
    for q in 0..4 {
        let (c0, c1) = (corner(a, 0, q), corner(a, 1, q));
        for l in 0..LANES {
            dc[c0][l] = wq[q][l].fma(d0[l], dc[c0][l]);
            dc[c1][l] = wq[q][l].fma(d1[l], dc[c1][l]);
        }
    }
}

/// Prefetches what [`block_forward`] / [`block_backward`] will touch for a sample: the centre
/// cell's four x-rows and the far faces of the y and z taps that leave it (x taps stay in the
/// centre's rows or the next entries). `TWO` and `two` as in [`block_forward`].
#[inline(always)]
fn block_prefetch<T: Real, const TWO: bool>(pl: &Plan<T>, two: &PlanTwo, buf: &[T]) {
    // All 8 index lanes, whatever the block's level count: a fixed count unrolls without a
    // compare and branch per prefetch (callgrind, `x86-64-v3`: the plan closures execute 10 %
    // fewer instructions), and the lanes of missing levels hold indices of the block's first
    // level (valid addresses; a prefetch never faults anyway).
    for c in [0usize, 2, 4, 6] {
        for j in 0..LV {
            prefetch(buf, pl.ce[c][j]);
        }
    }
    for a in 1..3 {
        for p in 0..2 {
            if pl.any_far[a][p] {
                for q in 0..4 {
                    if corner(a, 0, q) & 1 != 0 {
                        continue;
                    }
                    // Lanes whose tap stays in the cell prefetch a centre line again: harmless.
                    for j in 0..LV {
                        prefetch(buf, pl.fe[a][p][q][j]);
                    }
                    if TWO && two.any_far2[a][p] {
                        for j in 0..LV {
                            prefetch(buf, two.fe2[a][p][q][j]);
                        }
                    }
                }
            }
        }
    }
}
