//! The batched drivers of the level-parallel stencil ([`HashGrid::encode_fd_batch`],
//! [`HashGrid::encode_fd_backward_batch`], [`HashGrid::encode_batch`]) and the one software
//! pipeline they share: each sample is planned (cells, fractions, table indices) and its table
//! lines prefetched [`PREFETCH_AHEAD`] samples before it is computed, its plans kept in a ring of
//! slots ([`Ring`]).

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::{
    block_backward, block_forward, block_prefetch, corner, faces, gather, prefetch, LaneBlock,
    LaneConsts, Plan, PlanTwo, L, LANES, LV,
};
use crate::field::hashgrid::{fd_point, HashGrid, Sides};
use crate::field::Real;

/// Samples between planning (and prefetching) a sample and encoding it.
const PREFETCH_AHEAD: usize = 8;
/// Plan slots: the samples in flight plus the one in use.
const RING: usize = PREFETCH_AHEAD + 1;

/// The plans of the samples in flight: sample `i`'s plans (one per block) live in slot
/// `i % RING`, beside a flag saying whether every block could plan it.
struct Ring<T> {
    /// Blocks per sample.
    nb: usize,
    /// `[RING][nb]` plans, slot-major.
    plans: Vec<Plan<T>>,
    /// `[RING][nb]` second far faces, slot-major: written and read for one-sided samples only.
    twos: Vec<PlanTwo>,
    /// Per slot: false when a tap of the slot's sample moves further than the plan takes (one
    /// cell central, two one-sided) on an active lane (the sample then goes through the
    /// per-level path).
    ok: [bool; RING],
}

impl<T: Real> Ring<T> {
    /// A ring for `nb` blocks; `twos`: with second far faces (the stencil drivers), without
    /// for centre-only queries (then only [`plans_mut`](Self::plans_mut) and
    /// [`plans`](Self::plans) may be used).
    fn new(nb: usize, twos: bool) -> Self {
        Self {
            nb,
            plans: vec![Plan::default(); RING * nb],
            twos: vec![PlanTwo::default(); if twos { RING * nb } else { 0 }],
            ok: [true; RING],
        }
    }

    /// Sample `i`'s slot, to plan into.
    #[inline(always)]
    fn slot_mut(&mut self, i: usize) -> (&mut [Plan<T>], &mut [PlanTwo], &mut bool) {
        let s = i % RING;
        let r = s * self.nb..(s + 1) * self.nb;
        (
            &mut self.plans[r.clone()],
            &mut self.twos[r],
            &mut self.ok[s],
        )
    }

    /// Sample `i`'s slot, to compute from.
    #[inline(always)]
    fn slot(&self, i: usize) -> (&[Plan<T>], &[PlanTwo], bool) {
        let s = i % RING;
        let r = s * self.nb..(s + 1) * self.nb;
        (&self.plans[r.clone()], &self.twos[r], self.ok[s])
    }

    /// Sample `i`'s plans alone, to plan into (centre-only queries).
    #[inline(always)]
    fn plans_mut(&mut self, i: usize) -> &mut [Plan<T>] {
        let s = i % RING;
        &mut self.plans[s * self.nb..(s + 1) * self.nb]
    }

    /// Sample `i`'s plans alone, to compute from (centre-only queries).
    #[inline(always)]
    fn plans(&self, i: usize) -> &[Plan<T>] {
        let s = i % RING;
        &self.plans[s * self.nb..(s + 1) * self.nb]
    }
}

/// The software pipeline of the three batched drivers, over samples `0..n`: sample `i` is
/// planned (`plan(ring, ctx, i)`, which also prefetches what it will read) [`PREFETCH_AHEAD`]
/// samples before it is computed (`compute(ring, ctx, i)`), so its table loads are in flight
/// while the samples between are computed. `ctx` is the buffer both phases touch: the one
/// `compute` writes (encodings or gradients), which `plan` may read (prefetch).
#[inline(always)]
fn pipeline<T, C: ?Sized>(
    n: usize,
    ring: &mut Ring<T>,
    ctx: &mut C,
    mut plan: impl FnMut(&mut Ring<T>, &C, usize),
    mut compute: impl FnMut(&Ring<T>, &mut C, usize),
) {
    for i in 0..n.min(PREFETCH_AHEAD) {
        plan(ring, ctx, i);
    }
    for i in 0..n {
        if i + PREFETCH_AHEAD < n {
            plan(ring, ctx, i + PREFETCH_AHEAD);
        }
        compute(ring, ctx, i);
    }
}

/// Per-call constants of the level-parallel path: the blocks, their lane constants for `active`
/// levels, and how many blocks hold an active level (`live`; the others output zeros).
struct Blocks<'a, T> {
    blocks: &'a [LaneBlock],
    consts: Vec<LaneConsts<T>>,
    live: usize,
}

impl<'a, T: Real> Blocks<'a, T> {
    fn new(blocks: &'a [LaneBlock], active: usize) -> Self {
        Self {
            blocks,
            consts: blocks.iter().map(|b| b.consts(active)).collect(),
            live: blocks.iter().filter(|b| b.level0 < active).count(),
        }
    }

    /// Plans a stencil sample (unit centre `uc`, unit taps `ut` of the `sides` in use)
    /// for every live block into `plans` (and, for a one-sided sample, `twos`) and prefetches
    /// from `buf` what the block will touch; false if a tap moves more than one cell (central
    /// samples) or two cells (one-sided samples) on an active lane.
    #[inline(always)]
    fn plan_stencil(
        &self,
        uc: [T; 3],
        ut: [[T; 2]; 3],
        sides: Sides,
        plans: &mut [Plan<T>],
        twos: &mut [PlanTwo],
        buf: &[T],
    ) -> bool {
        let mut good = true;
        for (bi, blk) in self.blocks.iter().enumerate().take(self.live) {
            let (pl, two) = (&mut plans[bi], &mut twos[bi]);
            let k = &self.consts[bi];
            if sides == Sides::Both {
                good &= blk.plan::<T, false>(k, uc, ut, sides, true, pl, two);
                if good {
                    block_prefetch::<T, false>(pl, two, buf);
                }
            } else {
                good &= blk.plan::<T, true>(k, uc, ut, sides, true, pl, two);
                if good {
                    block_prefetch::<T, true>(pl, two, buf);
                }
            }
        }
        good
    }
}

impl HashGrid {
    fn unit_stencil<T: Real>(x: [T; 3], taps: [[T; 2]; 3], radius: T) -> ([T; 3], [[T; 2]; 3]) {
        let inv = T::ONE / (radius + radius);
        let uc = [0, 1, 2].map(|a| (x[a] + radius) * inv);
        let ut = [0, 1, 2].map(|a| [(taps[a][0] + radius) * inv, (taps[a][1] + radius) * inv]);
        (uc, ut)
    }

    /// Batched [`encode_fd`](Self::encode_fd) over the samples of a chunk: sample `i`'s centre
    /// `xs[i]` and taps `taps[i]`, rows and the [`Sides`] in use from `rows(i)`. The taps of an
    /// unused side must equal the centre (`taps[i][a][s] == xs[i][a]`); the level-parallel path
    /// neither computes nor writes their rows (the per-sample fallback writes them, with the
    /// centre's values), so the caller may point them at one spare row. Uses the level-parallel
    /// blocks when
    /// `F = 2` (falling back per sample when a tap moves more than one cell), planning each
    /// sample 8 samples before its use and prefetching what it will read. Same
    /// values as calling [`encode_fd`](Self::encode_fd) per sample up to rounding (tested).
    #[allow(clippy::too_many_arguments)]
    pub fn encode_fd_batch<T: Real>(
        &self,
        table: &[T],
        xs: &[[T; 3]],
        taps: &[[[T; 2]; 3]],
        radius: T,
        active: usize,
        out: &mut [T],
        rows: impl Fn(usize) -> ([usize; 7], Sides),
    ) {
        self.fd_batch(table, xs, taps, radius, active, out, &rows);
    }

    /// Batched [`encode_fd_backward`](Self::encode_fd_backward) (see
    /// [`encode_fd_batch`](Self::encode_fd_batch)): scatter-adds into `grad`. A forward
    /// difference's unused tap rows are not read by the level-parallel path; the fallback reads
    /// them, so they must hold zeros.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_fd_backward_batch<T: Real>(
        &self,
        xs: &[[T; 3]],
        taps: &[[[T; 2]; 3]],
        radius: T,
        active: usize,
        d_out: &[T],
        rows: impl Fn(usize) -> ([usize; 7], Sides),
        grad: &mut [T],
    ) {
        self.fd_batch_bwd(xs, taps, radius, active, d_out, &rows, grad);
    }

    /// Batched [`encode`](Self::encode) of points without taps (SDF queries: occupancy updates,
    /// marching cubes): point `i`'s encoding goes to `out[i·stride..i·stride + output_dim]`.
    /// Level-parallel blocks with prefetching when `F = 2`, the per-level path otherwise; same
    /// values up to rounding (tested).
    pub fn encode_batch<T: Real>(
        &self,
        table: &[T],
        xs: &[[T; 3]],
        radius: T,
        active: usize,
        out: &mut [T],
        stride: usize,
    ) {
        assert!(table.len() >= self.n_params() && stride >= self.output_dim());
        assert!(
            out.len() >= xs.len().saturating_sub(1) * stride + self.output_dim() || xs.is_empty()
        );
        let Some(blocks) = self.lane_blocks() else {
            for (i, x) in xs.iter().enumerate() {
                self.encode(table, *x, radius, active, &mut out[i * stride..]);
            }
            return;
        };
        let xd = self.xyz_dim();
        let b = Blocks::<T>::new(blocks, active);
        let inv = T::ONE / (radius + radius);
        let unit = |x: [T; 3]| [0, 1, 2].map(|a| (x[a] + radius) * inv);
        let mut ring = Ring::new(blocks.len(), false);
        let plan = |ring: &mut Ring<T>, _: &[T], i: usize| {
            let uc = unit(xs[i]);
            let plans = ring.plans_mut(i);
            for (bi, blk) in blocks.iter().enumerate().take(b.live) {
                let pl = &mut plans[bi];
                blk.plan_centre(&b.consts[bi], uc, pl);
                for c in [0usize, 2, 4, 6] {
                    // All 8 index lanes (see `block_prefetch`).
                    for j in 0..LV {
                        prefetch(table, pl.ce[c][j]);
                    }
                }
            }
        };
        let compute = |ring: &Ring<T>, out: &mut [T], i: usize| {
            let row = i * stride;
            if self.include_xyz {
                for d in 0..3 {
                    out[row + d] = xs[i][d] / radius;
                }
            }
            let plans = ring.plans(i);
            for (bi, blk) in blocks.iter().enumerate() {
                let o = row + xd + 2 * blk.level0;
                let n = 2 * blk.n_levels;
                if bi >= b.live {
                    out[o..o + n].fill(T::ZERO);
                    continue;
                }
                let pl = &plans[bi];
                let k = &b.consts[bi];
                let cv: [L<T>; 8] = std::array::from_fn(|c| gather(table, &pl.ce[c]));
                let wq = faces(&pl.w, 0);
                let mut v = [T::ZERO; LANES];
                for l in 0..LANES {
                    let (mut f0, mut f1) = (T::ZERO, T::ZERO);
                    for q in 0..4 {
                        f0 = wq[q][l].fma(cv[corner(0, 0, q)][l], f0);
                        f1 = wq[q][l].fma(cv[corner(0, 1, q)][l], f1);
                    }
                    let x = pl.w[0][0][l].fma(f0, pl.w[0][1][l] * f1);
                    v[l] = if k.act[l] != 0 { x } else { T::ZERO };
                }
                out[o..o + n].copy_from_slice(&v[..n]);
            }
        };
        pipeline(xs.len(), &mut ring, out, plan, compute);
    }

    #[allow(clippy::too_many_arguments)]
    fn fd_batch<T: Real>(
        &self,
        table: &[T],
        xs: &[[T; 3]],
        taps: &[[[T; 2]; 3]],
        radius: T,
        active: usize,
        out: &mut [T],
        rows: &dyn Fn(usize) -> ([usize; 7], Sides),
    ) {
        assert!(table.len() >= self.n_params() && taps.len() == xs.len());
        let Some(blocks) = self.lane_blocks() else {
            for i in 0..xs.len() {
                self.encode_fd(table, xs[i], taps[i], radius, active, out, &rows(i).0);
            }
            return;
        };
        let xd = self.xyz_dim();
        let b = Blocks::<T>::new(blocks, active);
        let mut ring = Ring::new(blocks.len(), true);
        let plan = |ring: &mut Ring<T>, _: &[T], i: usize| {
            let (uc, ut) = Self::unit_stencil(xs[i], taps[i], radius);
            let (plans, twos, ok) = ring.slot_mut(i);
            *ok = b.plan_stencil(uc, ut, rows(i).1, plans, twos, table);
        };
        let compute = |ring: &Ring<T>, out: &mut [T], i: usize| {
            let (r, sides) = rows(i);
            let (plans, twos, ok) = ring.slot(i);
            if !ok {
                // Rare: the whole sample through the per-level path.
                self.encode_fd(table, xs[i], taps[i], radius, active, out, &r);
                return;
            }
            for (bi, blk) in blocks.iter().enumerate() {
                let br = r.map(|v| v + xd + 2 * blk.level0);
                if bi >= b.live {
                    for p in 0..7 {
                        out[br[p]..br[p] + 2 * blk.n_levels].fill(T::ZERO);
                    }
                    continue;
                }
                let (k, pl, two) = (&b.consts[bi], &plans[bi], &twos[bi]);
                if sides == Sides::Both {
                    block_forward::<T, false>(blk, k, pl, two, table, out, &br, sides);
                } else {
                    block_forward::<T, true>(blk, k, pl, two, table, out, &br, sides);
                }
            }
            if self.include_xyz {
                for p in 0..7 {
                    let pt = fd_point(xs[i], taps[i], p);
                    for d in 0..3 {
                        out[r[p] + d] = pt[d] / radius;
                    }
                }
            }
        };
        pipeline(xs.len(), &mut ring, out, plan, compute);
    }

    #[allow(clippy::too_many_arguments)]
    fn fd_batch_bwd<T: Real>(
        &self,
        xs: &[[T; 3]],
        taps: &[[[T; 2]; 3]],
        radius: T,
        active: usize,
        d_out: &[T],
        rows: &dyn Fn(usize) -> ([usize; 7], Sides),
        grad: &mut [T],
    ) {
        assert!(grad.len() >= self.n_params() && taps.len() == xs.len());
        let Some(blocks) = self.lane_blocks() else {
            for i in 0..xs.len() {
                self.encode_fd_backward(xs[i], taps[i], radius, active, d_out, &rows(i).0, grad);
            }
            return;
        };
        let xd = self.xyz_dim();
        let b = Blocks::<T>::new(blocks, active);
        let mut ring = Ring::new(blocks.len(), true);
        let plan = |ring: &mut Ring<T>, grad: &[T], i: usize| {
            let (uc, ut) = Self::unit_stencil(xs[i], taps[i], radius);
            let (plans, twos, ok) = ring.slot_mut(i);
            *ok = b.plan_stencil(uc, ut, rows(i).1, plans, twos, grad);
        };
        let compute = |ring: &Ring<T>, grad: &mut [T], i: usize| {
            let (r, sides) = rows(i);
            let (plans, twos, ok) = ring.slot(i);
            if !ok {
                self.encode_fd_backward(xs[i], taps[i], radius, active, d_out, &r, grad);
                return;
            }
            for (bi, blk) in blocks.iter().enumerate().take(b.live) {
                let br = r.map(|v| v + xd + 2 * blk.level0);
                let (k, pl, two) = (&b.consts[bi], &plans[bi], &twos[bi]);
                if sides == Sides::Both {
                    block_backward::<T, false>(blk, k, pl, two, grad, d_out, &br, sides);
                } else {
                    block_backward::<T, true>(blk, k, pl, two, grad, d_out, &br, sides);
                }
            }
        };
        pipeline(xs.len(), &mut ring, grad, plan, compute);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::config::HashGridConfig;
    use crate::field::hashgrid::{fd_points, stencil_rows};
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// The batched level-parallel path against the naive reference, forward and backward, on
    /// grids with a partial last block, dense and hashed levels, with and without the xyz prefix:
    /// taps one cell away on fine levels, two cells away (the one-sided span of 2), inside the
    /// cell, several cells away (per-sample fallback), at the box faces, and every progressive
    /// mask.
    #[test]
    fn batch_matches_naive() {
        let mut rng = Pcg64Mcg::seed_from_u64(23);
        let mut worst = 0.0f64;
        for (n_levels, log2, include_xyz) in [(11usize, 12u32, true), (16, 10, false), (3, 8, true)]
        {
            let g = HashGrid::new(&HashGridConfig {
                n_levels,
                n_features_per_level: 2,
                log2_hashmap_size: log2,
                base_resolution: 4.0,
                per_level_scale: 1.45,
                include_xyz,
                ..Default::default()
            });
            assert!(g.lane_blocks().is_some());
            let table: Vec<f64> = (0..g.n_params())
                .map(|_| rng.random_range(-1.0..1.0))
                .collect();
            let r = 0.8;
            let d = g.output_dim();
            for active in [n_levels, 1, n_levels / 2 + 1] {
                let n = 64;
                let mut xs = Vec::new();
                let mut taps = Vec::new();
                for i in 0..n {
                    let mut c = [0.0; 3];
                    for v in c.iter_mut() {
                        *v = rng.random_range(-r..r);
                    }
                    if i % 9 == 0 {
                        c = [r, -r, rng.random_range(-r..r)];
                    }
                    let eps = match i % 5 {
                        0 | 1 => g.fd_eps(active, r),
                        2 => 0.3 * g.fd_eps(active, r),
                        3 => 2.0 * g.fd_eps(active, r), // two cells on the finest level
                        _ => 0.2,                       // several cells: per-sample fallback
                    };
                    xs.push(c);
                    taps.push([0, 1, 2].map(|a| [(c[a] + eps).min(r), (c[a] - eps).max(-r)]));
                }
                // Every third sample one-sided, + and − in turn: the other side's taps on the
                // centre, skipped (their rows alias one spare row, which only the per-sample
                // fallback writes).
                let sides = |i: usize| match i % 6 {
                    1 => Sides::Plus,
                    3 => Sides::Minus,
                    _ => Sides::Both,
                };
                for i in 0..n {
                    for p in 0..2 {
                        if !sides(i).slots().contains(&p) {
                            for a in 0..3 {
                                taps[i][a][p] = xs[i][a];
                            }
                        }
                    }
                }
                let spare = 7 * n * d;
                let rows = |i: usize| -> ([usize; 7], Sides) {
                    let mut r = stencil_rows(i, n + 6 * i, d);
                    for p in 1..7 {
                        if !sides(i).slots().contains(&((p - 1) % 2)) {
                            r[p] = spare;
                        }
                    }
                    (r, sides(i))
                };
                let mut out = vec![7.0; (7 * n + 1) * d];
                g.encode_fd_batch(&table, &xs, &taps, r, active, &mut out, rows);
                let mut dout: Vec<f64> = (0..(7 * n + 1) * d)
                    .map(|_| rng.random_range(-1.0..1.0))
                    .collect();
                dout[spare..].fill(0.0);
                let mut gf = vec![0.0; g.n_params()];
                g.encode_fd_backward_batch(&xs, &taps, r, active, &dout, rows, &mut gf);
                let mut gn = vec![0.0; g.n_params()];
                for i in 0..n {
                    let pts = fd_points(xs[i], taps[i]);
                    let (rw, sd) = rows(i);
                    for p in 0..7 {
                        if p > 0 && !sd.slots().contains(&((p - 1) % 2)) {
                            // Skipped: its row is never read back; unwritten on the fast path.
                            assert!(
                                out[(n + 6 * i + p - 1) * d..(n + 6 * i + p) * d]
                                    .iter()
                                    .all(|&v| v == 7.0),
                                "a skipped tap's own row was written"
                            );
                            continue;
                        }
                        let want = g.encode_naive(&table, pts[p], r, active);
                        for j in 0..d {
                            worst = worst.max((want[j] - out[rw[p] + j]).abs());
                        }
                        g.encode_backward_naive(
                            pts[p],
                            r,
                            active,
                            &dout[rw[p]..rw[p] + d],
                            &mut gn,
                        );
                    }
                }
                for (a, b) in gf.iter().zip(&gn) {
                    worst = worst.max((a - b).abs());
                }
            }
        }
        assert!(worst < 1e-12, "level-parallel vs naive max diff {worst}");
    }

    /// The batched centre-only encoding against the naive reference: inside, on and outside the
    /// box (wrapping cells), every progressive mask, F = 2 (level-parallel) and F = 1 (fallback).
    #[test]
    fn centre_batch_matches_naive() {
        let mut rng = Pcg64Mcg::seed_from_u64(29);
        let mut worst = 0.0f64;
        for (f, n_levels) in [(2usize, 11usize), (1, 5)] {
            let g = HashGrid::new(&HashGridConfig {
                n_levels,
                n_features_per_level: f,
                log2_hashmap_size: 12,
                base_resolution: 4.0,
                per_level_scale: 1.45,
                ..Default::default()
            });
            assert_eq!(g.lane_blocks().is_some(), f == 2);
            let table: Vec<f64> = (0..g.n_params())
                .map(|_| rng.random_range(-1.0..1.0))
                .collect();
            let r = 0.8;
            let d = g.output_dim();
            let stride = d + 3;
            let xs: Vec<[f64; 3]> = (0..50)
                .map(|i| match i % 10 {
                    0 => [r, -r, r],
                    1 => [1.7 * r, -2.3 * r, 0.0],
                    _ => [0, 1, 2].map(|_| rng.random_range(-r..r)),
                })
                .collect();
            for active in [n_levels, 1, n_levels / 2 + 1] {
                let mut out = vec![5.0; xs.len() * stride];
                g.encode_batch(&table, &xs, r, active, &mut out, stride);
                for (i, x) in xs.iter().enumerate() {
                    let want = g.encode_naive(&table, *x, r, active);
                    for j in 0..d {
                        worst = worst.max((want[j] - out[i * stride + j]).abs());
                    }
                    assert!(out[i * stride + d..(i + 1) * stride]
                        .iter()
                        .all(|&v| v == 5.0));
                }
            }
        }
        assert!(worst < 1e-12, "centre batch vs naive max diff {worst}");
    }

    /// The fast plan takes one-sided taps that move up to two cells of the finest active level
    /// (the one-sided span of 2 stays on the level-parallel path) and refuses three, on either
    /// side; central samples keep their one-cell plan (two cells go to the fallback).
    #[test]
    fn plan_accepts_two_cells_and_refuses_three() {
        let g = HashGrid::new(&HashGridConfig {
            n_levels: 16,
            n_features_per_level: 2,
            log2_hashmap_size: 12,
            base_resolution: 16.0,
            per_level_scale: 1.3195,
            include_xyz: true,
            ..Default::default()
        });
        let blocks = g.lane_blocks().unwrap();
        let b = Blocks::<f64>::new(blocks, 16);
        let table = vec![0.0f64; g.n_params()];
        let mut plans = vec![Plan::default(); blocks.len()];
        let mut twos = vec![PlanTwo::default(); blocks.len()];
        let r = 1.0;
        let eps = g.fd_eps(16, r);
        // ε is `scale/(scale + 1)` of a finest cell, so from the middle of a finest cell k·ε
        // moves exactly k cells (either way) for k ≤ 3.
        let sc = g.levels[15].scale;
        let c = [0.6, 0.3, 0.45].map(|u: f64| ((u * sc).round() / sc) * 2.0 * r - r);
        for (span, want) in [(1.0, true), (2.0, true), (3.0, false)] {
            for sides in [Sides::Plus, Sides::Minus, Sides::Both] {
                let want = want && (sides != Sides::Both || span == 1.0);
                let h = span * eps;
                let taps = [0, 1, 2].map(|a| {
                    let (p, m) = (c[a] + h, c[a] - h);
                    match sides {
                        Sides::Plus => [p, c[a]],
                        Sides::Minus => [c[a], m],
                        Sides::Both => [p, m],
                    }
                });
                let (uc, ut) = HashGrid::unit_stencil(c, taps, r);
                let ok = b.plan_stencil(uc, ut, sides, &mut plans, &mut twos, &table);
                assert_eq!(ok, want, "span {span}, {sides:?}");
                if span == 2.0 && sides != Sides::Both {
                    let last = twos.last().unwrap();
                    assert!(
                        (0..3).any(|a| last.any_far2[a].iter().any(|&f| f)),
                        "span 2 planned no second far face ({sides:?})"
                    );
                }
            }
        }
    }
}
