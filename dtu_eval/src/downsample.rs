//! Seeded shuffle and greedy radius downsampling (jzhangbs/DTUeval-python `eval.py`, steps
//! "random shuffle pcd index" and "downsample pcd").
//!
//! The reference shuffles the sampled points with an unseeded numpy generator, asks sklearn for
//! every point's neighbours within the radius (inclusive: `|p − q| <= r`), then walks the points
//! in order: a point still kept removes all its neighbours. Because distance is symmetric, this
//! is the greedy rule "point `i` is kept iff no kept point `j < i` lies within `r`", which is
//! what [`radius_downsample`] computes (the shuffle here is seeded, so the result is
//! reproducible). Distances are `f64` on the `f32` coordinates, compared as `d² <= r²`, as
//! sklearn's kd-tree does.

use crate::nn::{dist_sq, PointTree, TreeError};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;

/// Points examined per speculative parallel block in [`radius_downsample`].
const BLOCK: usize = 1 << 16;

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
/// Fast path: a k-d tree over all points. Points are processed in blocks of [`BLOCK`]; the radius
/// queries of the points of a block that are not yet removed run in parallel, then a sequential
/// pass applies the greedy rule in order using those neighbour lists (only neighbours after the
/// point matter: earlier ones are already decided). The result equals [`radius_downsample_brute`].
pub fn radius_downsample(points: &[[f32; 3]], radius: f64) -> Result<Vec<bool>, TreeError> {
    radius_downsample_blocked(points, radius, BLOCK)
}

fn radius_downsample_blocked(
    points: &[[f32; 3]],
    radius: f64,
    block: usize,
) -> Result<Vec<bool>, TreeError> {
    assert!(radius.is_finite() && radius >= 0.0, "radius {radius}");
    let n = points.len();
    let mut removed = vec![false; n];
    if n == 0 {
        return Ok(Vec::new());
    }
    let tree = PointTree::new(points)?;
    let r2 = radius * radius;
    let mut start = 0;
    while start < n {
        let end = (start + block).min(n);
        // Speculative: neighbours (after the point) of every point not removed yet.
        let candidates: Vec<usize> = (start..end).filter(|&i| !removed[i]).collect();
        let lists: Vec<Vec<u32>> = candidates
            .par_iter()
            .with_min_len(256)
            .map(|&i| {
                let mut l = tree.within(&points[i], r2);
                l.retain(|&j| j as usize > i);
                l
            })
            .collect();
        for (&i, list) in candidates.iter().zip(&lists) {
            if removed[i] {
                continue; // removed by an earlier point of this block
            }
            for &j in list {
                removed[j as usize] = true;
            }
        }
        start = end;
    }
    Ok(removed.into_iter().map(|r| !r).collect())
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
        let m = radius_downsample(&pts, 0.2).unwrap();
        assert_eq!(m, vec![true, false, true, false, true]);
        // Exactly on the radius counts as a neighbour (inclusive).
        let pts = [[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 0.0, 0.0]];
        assert_eq!(
            radius_downsample(&pts, 0.5).unwrap(),
            vec![true, false, false]
        );
        assert!(radius_downsample(&[], 0.2).unwrap().is_empty());
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
            let fast = radius_downsample(&pts, 0.2).unwrap();
            let slow = radius_downsample_brute(&pts, 0.2);
            assert_eq!(fast, slow, "seed {s}, n {n}, box {box_mm}");
            // Small blocks: the speculation crosses many block boundaries.
            for block in [1, 97] {
                let blocked = radius_downsample_blocked(&pts, 0.2, block).unwrap();
                assert_eq!(blocked, slow, "seed {s}, n {n}, block {block}");
            }
            let kept = fast.iter().filter(|&&k| k).count();
            assert!(kept > 0 && kept < pts.len(), "kept {kept} of {}", pts.len());
        }
    }
}
