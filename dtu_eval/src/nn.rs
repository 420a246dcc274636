//! Nearest-neighbour distances on a k-d tree (`kiddo::ImmutableKdTree<f32, 3>`), with the
//! brute-force references the tests compare against.
//!
//! Precision: coordinates are stored as `f32` (what PLY files hold), but every distance is computed
//! in `f64` from those `f32` values (`kiddo::SquaredEuclidean<f64>` widens each coordinate before
//! subtracting), summed in x, y, z order. This is what DTUeval-python gets from sklearn on the same
//! points (it works in float64), so per-point distances agree with numpy/scipy/open3d to rounding
//! of the final square root. Means are accumulated in `f64` by the caller.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

/// The squared-distance metric used throughout: `f32` coordinates widened to `f64`.
type Metric = SquaredEuclidean<f64>;

/// Queries per rayon task: large enough that scheduling costs nothing measurable.
const MIN_QUERIES_PER_TASK: usize = 1024;

/// Why a point set cannot be put in a tree.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TreeError {
    /// No points: nearest-neighbour distances are undefined.
    #[error("the point set is empty")]
    Empty,
    /// More points than a `u32` item index can address.
    #[error("{n} points are more than the k-d tree's u32 item index can address")]
    TooMany { n: usize },
    /// A coordinate is NaN, infinite or `±f32::MAX` (kiddo reserves `f32::MAX` as a sentinel).
    #[error("point {index} has an unusable coordinate {value:?}")]
    BadCoordinate { index: usize, value: [f32; 3] },
}

/// A static k-d tree over a point set (`[n][3]`, any frame and unit) answering nearest-neighbour
/// and radius queries with distances in `f64`.
pub struct PointTree<'a> {
    points: &'a [[f32; 3]],
    tree: ImmutableKdTree<f32, 3>,
}

impl<'a> PointTree<'a> {
    /// Builds the tree (in parallel for large sets). Fails on an empty set, non-finite
    /// coordinates or more than `u32::MAX` points.
    pub fn new(points: &'a [[f32; 3]]) -> Result<Self, TreeError> {
        if points.is_empty() {
            return Err(TreeError::Empty);
        }
        if points.len() > u32::MAX as usize {
            return Err(TreeError::TooMany { n: points.len() });
        }
        if let Some(index) = points
            .par_iter()
            .position_any(|p| p.iter().any(|c| !c.is_finite() || c.abs() == f32::MAX))
        {
            return Err(TreeError::BadCoordinate {
                index,
                value: points[index],
            });
        }
        let tree = ImmutableKdTree::new_from_slice_parallel(points)
            .map_err(|_| TreeError::TooMany { n: points.len() })?;
        Ok(Self { points, tree })
    }

    /// The points the tree was built on.
    pub fn points(&self) -> &'a [[f32; 3]] {
        self.points
    }

    /// Index of the nearest point to `q` and the squared distance to it (`f64`, unit²). Ties go to
    /// whichever point the tree meets first; the distance is exact either way.
    pub fn nearest_one(&self, q: &[f32; 3]) -> (usize, f64) {
        let hit = self.tree.query(q).nearest_one::<Metric>().execute();
        (hit.item as usize, hit.distance)
    }

    /// Euclidean distance from each query point to its nearest tree point: `[n_queries]`, `f64`,
    /// in the points' unit; the output order is the query order.
    ///
    /// Queries run in parallel, in Morton order ([`spatial_order`]): consecutive queries then
    /// walk the same tree nodes, which makes large batches several times faster than the
    /// (often shuffled) input order; results are scattered back, so nothing else changes.
    pub fn nearest_distances(&self, queries: &[[f32; 3]]) -> Vec<f64> {
        let order = spatial_order(queries);
        let sorted: Vec<f64> = order
            .par_iter()
            .with_min_len(MIN_QUERIES_PER_TASK)
            .map(|&i| self.nearest_one(&queries[i as usize]).1.sqrt())
            .collect();
        let mut out = vec![0.0; queries.len()];
        for (&i, d) in order.iter().zip(sorted) {
            out[i as usize] = d;
        }
        out
    }

    /// Indices of every tree point `p` with `|p - q|² <= radius²` (inclusive, as sklearn's
    /// `radius_neighbors`), in no particular order. `radius_sq` is the squared radius (`f64`).
    pub fn within(&self, q: &[f32; 3], radius_sq: f64) -> Vec<u32> {
        self.tree
            .query(q)
            .within::<Metric>(radius_sq)
            .unsorted()
            .execute()
            .into_iter()
            .map(|hit| hit.item)
            .collect()
    }
}

/// The indices of `points` (`[n][3]`, `n < 2³²`) sorted along a Morton (Z-order) curve over
/// their bounding box, 21 bits per axis: neighbours in space are mostly neighbours in the order.
/// Deterministic (ties broken by index). Non-finite coordinates sort to the box's edges.
pub fn spatial_order(points: &[[f32; 3]]) -> Vec<u32> {
    let Some((lo, hi)) = crate::mesh::bounds(points) else {
        return Vec::new();
    };
    let extent = (0..3)
        .map(|k| hi[k] as f64 - lo[k] as f64)
        .fold(0.0, f64::max);
    let scale = if extent > 0.0 {
        ((1u64 << 21) - 1) as f64 / extent
    } else {
        0.0
    };
    let mut keys: Vec<(u64, u32)> = points
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let key = (0..3).fold(0u64, |key, k| {
                let c =
                    ((p[k] as f64 - lo[k] as f64) * scale).clamp(0.0, ((1u64 << 21) - 1) as f64);
                key | spread_bits(c as u64) << k
            });
            (key, i as u32)
        })
        .collect();
    keys.par_sort_unstable();
    keys.into_iter().map(|(_, i)| i).collect()
}

/// Spreads the low 21 bits of `x` so that bit `b` moves to bit `3b`.
fn spread_bits(mut x: u64) -> u64 {
    x &= 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// Squared distance between two `f32` points computed in `f64`, summed x, y, z (the same
/// arithmetic as the tree's metric, so results compare exactly).
#[inline]
pub fn dist_sq(a: &[f32; 3], b: &[f32; 3]) -> f64 {
    let mut acc = 0.0f64;
    for k in 0..3 {
        let d = a[k] as f64 - b[k] as f64;
        acc += d * d;
    }
    acc
}

/// Brute-force reference for [`PointTree::nearest_distances`]: `O(n_points · n_queries)`.
pub fn nearest_distances_brute(points: &[[f32; 3]], queries: &[[f32; 3]]) -> Vec<f64> {
    queries
        .par_iter()
        .map(|q| {
            points
                .iter()
                .map(|p| dist_sq(p, q))
                .fold(f64::INFINITY, f64::min)
                .sqrt()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// Fuzz seed: `DTU_EVAL_FUZZ_SEED` reproduces a failing run.
    fn seed() -> u64 {
        std::env::var("DTU_EVAL_FUZZ_SEED")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(7)
    }

    fn cloud(rng: &mut Pcg64Mcg, n: usize, scale: f32, offset: f32) -> Vec<[f32; 3]> {
        (0..n)
            .map(|_| std::array::from_fn(|_| offset + scale * rng.random::<f32>()))
            .collect()
    }

    #[test]
    fn tiny_hand_made_set() {
        let pts = [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 4.0, 0.0]];
        let tree = PointTree::new(&pts).unwrap();
        let q = [
            [0.0, 0.0, 0.0],
            [3.0, 4.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 4.0, 12.0],
        ];
        assert_eq!(tree.nearest_distances(&q), vec![0.0, 3.0, 1.0, 12.0]);
        assert_eq!(tree.nearest_one(&[2.9, 0.1, 0.0]).0, 1);
        let mut w = tree.within(&[0.0, 0.0, 0.0], 9.0);
        w.sort();
        assert_eq!(w, vec![0, 1], "radius is inclusive");
    }

    #[test]
    fn nearest_equals_brute_force_exactly() {
        let s = seed();
        let mut rng = Pcg64Mcg::seed_from_u64(s);
        // DTU-like magnitudes (hundreds of mm) and a clustered set with many duplicates.
        for (n, m, scale, offset) in [(3000, 2000, 50.0, 400.0), (500, 4000, 1.0, -0.5)] {
            let mut pts = cloud(&mut rng, n, scale, offset);
            let dup = pts[..n / 5].to_vec();
            pts.extend(dup);
            let queries = cloud(&mut rng, m, scale * 1.2, offset - 0.1 * scale);
            let tree = PointTree::new(&pts).unwrap();
            let fast = tree.nearest_distances(&queries);
            let slow = nearest_distances_brute(&pts, &queries);
            let bad: Vec<_> = (0..m).filter(|&i| fast[i] != slow[i]).collect();
            assert!(
                bad.is_empty(),
                "seed {s}: {} mismatches, first {:?}",
                bad.len(),
                bad.first()
            );
            // The index returned really is at that distance.
            for q in queries.iter().take(200) {
                let (i, d2) = tree.nearest_one(q);
                assert_eq!(dist_sq(&pts[i], q), d2);
            }
        }
    }

    #[test]
    fn within_equals_brute_force_exactly() {
        let s = seed();
        let mut rng = Pcg64Mcg::seed_from_u64(s ^ 0x5eed);
        let pts = cloud(&mut rng, 4000, 5.0, 100.0);
        let tree = PointTree::new(&pts).unwrap();
        let r2 = 0.2f64 * 0.2;
        for q in pts.iter().step_by(7) {
            let mut fast = tree.within(q, r2);
            fast.sort();
            let slow: Vec<u32> = (0..pts.len() as u32)
                .filter(|&j| dist_sq(&pts[j as usize], q) <= r2)
                .collect();
            assert_eq!(fast, slow, "seed {s}");
        }
    }

    #[test]
    fn spatial_order_is_a_permutation_along_the_z_curve() {
        assert_eq!(spread_bits(0b1011), 0b1_000_001_001);
        assert_eq!(spread_bits(0x1f_ffff), 0x1249_2492_4924_9249);
        // The 2x2x2 corners of a cube come out in Morton order x, then y, then z.
        let pts: Vec<[f32; 3]> = (0..8u32)
            .rev()
            .map(|m| [(m & 1) as f32, (m >> 1 & 1) as f32, (m >> 2 & 1) as f32])
            .collect();
        assert_eq!(spatial_order(&pts), vec![7, 6, 5, 4, 3, 2, 1, 0]);
        let mut rng = Pcg64Mcg::seed_from_u64(1);
        let pts = cloud(&mut rng, 1000, 3.0, 0.0);
        let mut o = spatial_order(&pts);
        o.sort();
        assert_eq!(o, (0..1000).collect::<Vec<u32>>());
        assert!(spatial_order(&[]).is_empty());
    }

    #[test]
    fn bad_sets_are_errors() {
        assert_eq!(PointTree::new(&[]).err(), Some(TreeError::Empty));
        let pts = [[0.0, 0.0, 0.0], [f32::NAN, 0.0, 0.0]];
        assert!(matches!(
            PointTree::new(&pts).err(),
            Some(TreeError::BadCoordinate { index: 1, .. })
        ));
        let pts = [[0.0, f32::MAX, 0.0]];
        assert!(PointTree::new(&pts).is_err());
    }
}
