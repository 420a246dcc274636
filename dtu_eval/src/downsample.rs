//! Seeded shuffle and greedy radius downsampling (jzhangbs/DTUeval-python `eval.py`, steps
//! "random shuffle pcd index" and "downsample pcd").
//!
//! The reference shuffles the sampled points with an unseeded numpy generator, asks sklearn for
//! every point's neighbours within the radius (inclusive: `|p − q| <= r`), then walks the points
//! in order: a point still kept removes all its neighbours. Because distance is symmetric, this
//! is the greedy rule "point `i` is kept iff no kept point `j < i` lies within `r`", which is
//! what [`radius_downsample`] computes (the shuffle here is seeded, so the result is
//! reproducible). Distances are `f64` on the `f32` coordinates, compared as `d² <= r²`, as
//! sklearn's kd-tree does. Neighbours are found on a uniform grid (a DTU mesh sampled at the
//! radius has well under one neighbour per point, so a k-d tree's per-query cost is wasted).

use crate::nn::dist_sq;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;

/// Grid cells per parallel task of [`neighbour_pairs`].
const CHUNK: usize = 4096;

/// Shuffles `points` in place with a Fisher–Yates pass driven by `Pcg64Mcg::seed_from_u64(seed)`.
/// Same seed, same order.
pub fn shuffle<T>(points: &mut [T], seed: u64) {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    for i in (1..points.len()).rev() {
        let j = rng.random_range(0..=i);
        points.swap(i, j);
    }
}

/// Greedy radius downsampling of `points` (`[n][3]`, in their given order): returns the keep
/// mask `[n]`. Point `i` is kept iff no kept point before it lies within `radius` (inclusive).
///
/// Fast path, in two phases. (1) In parallel, every pair `i < j` with `|p_i − p_j| <= radius`
/// is found with a uniform grid ([`neighbour_pairs`]). (2) A sequential pass in the given order
/// applies the greedy rule: a point not yet removed is kept and removes its later neighbours
/// (earlier neighbours need no look: a kept one would already have removed this point).
/// Memory: 8 bytes per neighbour pair plus 16 per point. The result equals
/// [`radius_downsample_brute`].
pub fn radius_downsample(points: &[[f32; 3]], radius: f64) -> Vec<bool> {
    radius_downsample_chunked(points, radius, CHUNK)
}

fn radius_downsample_chunked(points: &[[f32; 3]], radius: f64, chunk: usize) -> Vec<bool> {
    let pairs = neighbour_pairs(points, radius, chunk);
    let mut removed = vec![false; points.len()];
    for run in pairs.chunk_by(|a, b| a.0 == b.0) {
        let i = run[0].0 as usize;
        if !removed[i] {
            for &(_, j) in run {
                removed[j as usize] = true;
            }
        }
    }
    removed.into_iter().map(|r| !r).collect()
}

/// Packed grid cell key: `cx << 42 | cy << 21 | cz`, each in `1 ..= 2²⁰ + 1` so that a cell's
/// neighbours are the key plus a constant, without borrows between fields.
const AXIS_BITS: u32 = 21;

/// Every pair `(i, j)`, `i < j`, of points within `radius` (inclusive; `f64` distance on the
/// `f32` coordinates, as [`dist_sq`]), sorted by `i` then `j`. `points` must be finite and
/// fewer than 2³² (as for [`crate::nn::PointTree`]).
///
/// The points are binned into cubic cells of edge slightly above `radius` (or coarser when the
/// extent needs more than 2²⁰ cells per axis), so that neighbours lie in the same or adjacent
/// cells. Cells are sorted by key (x-major, z-minor); each cell is paired with itself, with the
/// next cell of its column (`z + 1`), and with the three-cell column runs `(x, y + 1)`,
/// `(x + 1, y − 1 ..= y + 1)`: the half of the 26-neighbourhood after it, so each pair of cells
/// is visited once. Those runs are found by pointers that only move forward, since the target
/// keys grow with the cell key. Chunks of [`CHUNK`] cells run in parallel.
pub fn neighbour_pairs(points: &[[f32; 3]], radius: f64, chunk: usize) -> Vec<(u32, u32)> {
    assert!(radius.is_finite() && radius >= 0.0, "radius {radius}");
    assert!(points.len() < u32::MAX as usize, "{} points", points.len());
    let Some((lo, hi)) = crate::mesh::bounds(points) else {
        return Vec::new();
    };
    let extent = (0..3)
        .map(|k| hi[k] as f64 - lo[k] as f64)
        .fold(0.0, f64::max);
    // Slightly above the radius so that rounding never puts two points within `radius` two
    // cells apart; coarser when needed to keep indices below 2^20.
    let cell = (radius * (1.0 + 1e-6))
        .max(extent / (1u64 << 20) as f64)
        .max(1e-30);
    let mut keyed: Vec<(u64, u32)> = points
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let key = (0..3).fold(0u64, |key, k| {
                let c = ((p[k] as f64 - lo[k] as f64) / cell).floor() as u64 + 1;
                key << AXIS_BITS | c
            });
            (key, i as u32)
        })
        .collect();
    keyed.par_sort_unstable();
    // Cells: key and start index into `keyed`; a sentinel closes the last one.
    let mut cells: Vec<(u64, usize)> = Vec::new();
    for (s, &(key, _)) in keyed.iter().enumerate() {
        if cells.last().is_none_or(|&(k, _)| k != key) {
            cells.push((key, s));
        }
    }
    cells.push((u64::MAX, keyed.len()));
    let n_cells = cells.len() - 1;
    let members = |c: usize| &keyed[cells[c].1..cells[c + 1].1];
    let r2 = radius * radius;
    let step = |dx: i64, dy: i64, dz: i64| (dx << (2 * AXIS_BITS)) + (dy << AXIS_BITS) + dz;
    let columns = [step(0, 1, 0), step(1, -1, 0), step(1, 0, 0), step(1, 1, 0)];
    let chunk = chunk.max(1);
    let chunks: Vec<Vec<(u32, u32)>> = (0..n_cells.div_ceil(chunk))
        .into_par_iter()
        .map(|t| {
            let range = t * chunk..((t + 1) * chunk).min(n_cells);
            let mut out = Vec::new();
            let mut push_pairs = |a: &[(u64, u32)], b: &[(u64, u32)], same: bool| {
                for (ia, &(_, i)) in a.iter().enumerate() {
                    let b = if same { &b[ia + 1..] } else { b };
                    for &(_, j) in b {
                        if dist_sq(&points[i as usize], &points[j as usize]) <= r2 {
                            out.push((i.min(j), i.max(j)));
                        }
                    }
                }
            };
            let first_key = cells[range.start].0 as i64;
            let mut ptr: [usize; 4] = std::array::from_fn(|c| {
                let target = (first_key + columns[c] - 1) as u64;
                cells[..n_cells].partition_point(|&(k, _)| k < target)
            });
            for c in range {
                let key = cells[c].0;
                let own = members(c);
                push_pairs(own, own, true);
                if cells[c + 1].0 == key + 1 {
                    push_pairs(own, members(c + 1), false);
                }
                for (col, p) in columns.iter().zip(ptr.iter_mut()) {
                    let first = (key as i64 + col - 1) as u64;
                    let last = (key as i64 + col + 1) as u64;
                    while cells[*p].0 < first {
                        *p += 1;
                    }
                    let mut q = *p;
                    while cells[q].0 <= last {
                        push_pairs(own, members(q), false);
                        q += 1;
                    }
                }
            }
            out
        })
        .collect();
    let mut pairs: Vec<(u32, u32)> = chunks.concat();
    pairs.par_sort_unstable();
    pairs
}

/// Brute-force reference for [`radius_downsample`]: `O(n · kept)`, the greedy rule verbatim.
pub fn radius_downsample_brute(points: &[[f32; 3]], radius: f64) -> Vec<bool> {
    let r2 = radius * radius;
    let mut kept: Vec<usize> = Vec::new();
    let mut mask = vec![false; points.len()];
    for (i, p) in points.iter().enumerate() {
        if kept.iter().all(|&j| dist_sq(&points[j], p) > r2) {
            kept.push(i);
            mask[i] = true;
        }
    }
    mask
}

/// The points whose `mask` entry is true, in order.
pub fn select<T: Copy>(points: &[T], mask: &[bool]) -> Vec<T> {
    points
        .iter()
        .zip(mask)
        .filter_map(|(p, &m)| m.then_some(*p))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seed() -> u64 {
        std::env::var("DTU_EVAL_FUZZ_SEED")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(3)
    }

    #[test]
    fn shuffle_is_a_seeded_permutation() {
        let v: Vec<u32> = (0..1000).collect();
        let mut a = v.clone();
        let mut b = v.clone();
        shuffle(&mut a, 5);
        shuffle(&mut b, 5);
        assert_eq!(a, b);
        assert_ne!(a, v);
        let mut c = v.clone();
        shuffle(&mut c, 6);
        assert_ne!(a, c);
        a.sort();
        assert_eq!(a, v);
    }

    #[test]
    fn hand_made_chain() {
        // Points 0.15 apart on a line: 0 kept, 1 removed (0.15), 2 kept (0.30 from 0), ...
        let pts: Vec<[f32; 3]> = (0..5).map(|i| [0.15 * i as f32, 0.0, 0.0]).collect();
        let m = radius_downsample(&pts, 0.2);
        assert_eq!(m, vec![true, false, true, false, true]);
        // Exactly on the radius counts as a neighbour (inclusive).
        let pts = [[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 0.0, 0.0]];
        assert_eq!(radius_downsample(&pts, 0.5), vec![true, false, false]);
        assert!(radius_downsample(&[], 0.2).is_empty());
    }

    #[test]
    fn coarse_grid_and_zero_radius_edge_cases() {
        let mut rng = Pcg64Mcg::seed_from_u64(seed() ^ 77);
        // Two tight clusters 1 km apart: the grid must coarsen its cells beyond the radius.
        let mut pts: Vec<[f32; 3]> = (0..1500)
            .map(|i| {
                let base = if i % 2 == 0 { 0.0 } else { 1.0e6 };
                std::array::from_fn(|_| base + rng.random::<f32>())
            })
            .collect();
        assert_eq!(
            radius_downsample(&pts, 0.2),
            radius_downsample_brute(&pts, 0.2)
        );
        // Radius 0: exactly the duplicates go (f32 at 1e6 has a 1/16 step: there are many).
        let dup = pts[..10].to_vec();
        pts.extend(dup);
        let m = radius_downsample(&pts, 0.0);
        assert_eq!(m, radius_downsample_brute(&pts, 0.0));
        let distinct: std::collections::HashSet<[u32; 3]> =
            pts.iter().map(|p| p.map(f32::to_bits)).collect();
        assert_eq!(m.iter().filter(|&&k| k).count(), distinct.len());
        assert!(distinct.len() <= pts.len() - 10);
        // Pairs come out sorted, each once.
        let pairs = neighbour_pairs(&pts, 0.3, 7);
        assert!(pairs.windows(2).all(|w| w[0] < w[1]) && pairs.iter().all(|p| p.0 < p.1));
    }

    #[test]
    fn equals_brute_force_on_random_sets() {
        let s = seed();
        let mut rng = Pcg64Mcg::seed_from_u64(s);
        // Dense (many removals) and sparse sets, with duplicates.
        for (n, box_mm) in [(3000, 2.0f32), (2000, 20.0), (1500, 0.5)] {
            let mut pts: Vec<[f32; 3]> = (0..n)
                .map(|_| std::array::from_fn(|_| 500.0 + box_mm * rng.random::<f32>()))
                .collect();
            let dup = pts[..100].to_vec();
            pts.extend(dup);
            shuffle(&mut pts, s);
            let fast = radius_downsample(&pts, 0.2);
            let slow = radius_downsample_brute(&pts, 0.2);
            assert_eq!(fast, slow, "seed {s}, n {n}, box {box_mm}");
            // Small chunks: lists cross many chunk boundaries.
            for chunk in [1, 97] {
                let chunked = radius_downsample_chunked(&pts, 0.2, chunk);
                assert_eq!(chunked, slow, "seed {s}, n {n}, chunk {chunk}");
            }
            let kept = fast.iter().filter(|&&k| k).count();
            assert!(kept > 0 && kept < pts.len(), "kept {kept} of {}", pts.len());
        }
    }
}
