//! Summary statistics and the seeded percentile bootstrap of paired differences.
//!
//! # Bootstrap
//! The statistic is the mean of paired differences `arm − baseline` (same condition, scene and
//! seed). A confidence interval resamples the pairs with replacement, [`RESAMPLES`] times, from a
//! [`rand_pcg::Pcg64Mcg`] seeded with [`BOOTSTRAP_SEED`] XOR the FNV-1a hash of the comparison's
//! label (so each interval depends on its own data and label only, not on which other intervals
//! were computed before it), and takes the 2.5 % and 97.5 % percentiles of the resampled means
//! (type-7 linear interpolation between order statistics). Pooled intervals resample within
//! strata (one per scene or condition–scene cell), keeping each stratum's size: scenes differ in
//! difficulty far more than seeds do, and the pooled mean weights each pair equally.
//!
//! With 3 seeds a per-scene interval rests on 3 pairs (at most 10 distinct resampled means): it
//! is a description of the spread, not a reliable coverage guarantee; the pooled intervals are
//! the ones to read.

use rand::Rng;
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;
use serde::Serialize;

/// Bootstrap resamples per interval.
pub const RESAMPLES: usize = 10_000;
/// Base seed of every bootstrap stream ("neus-aug" in ASCII).
pub const BOOTSTRAP_SEED: u64 = 0x6e65_7573_2d61_7567;

/// Arithmetic mean; `None` for an empty slice.
pub fn mean(x: &[f64]) -> Option<f64> {
    (!x.is_empty()).then(|| x.iter().sum::<f64>() / x.len() as f64)
}

/// Sample standard deviation (`n − 1` in the denominator); `None` below two values.
pub fn sample_std(x: &[f64]) -> Option<f64> {
    let m = mean(x)?;
    (x.len() >= 2)
        .then(|| (x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (x.len() - 1) as f64).sqrt())
}

/// The `q`-quantile of sorted values, type-7 (linear interpolation between order statistics,
/// R's and NumPy's default). `q ∈ [0, 1]`; `sorted` must be non-empty and ascending.
pub fn quantile_sorted(sorted: &[f64], q: f64) -> f64 {
    let h = (sorted.len() - 1) as f64 * q.clamp(0.0, 1.0);
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(sorted.len() - 1);
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

/// A mean with its bootstrap confidence interval.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Ci {
    /// Mean of all pairs.
    pub mean: f64,
    /// Lower end of the 95 % percentile interval.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
    /// Number of pairs.
    pub n: usize,
    /// Pairs in the smallest non-empty stratum. A stratum of one pair never varies under
    /// resampling, so an interval with `min_stratum < 2` understates the spread (a pooled interval
    /// over scenes with one seed each has almost no width whatever the seeds would do).
    pub min_stratum: usize,
}

/// The seed of the bootstrap stream for the comparison called `label`.
pub fn stream_seed(label: &str) -> u64 {
    BOOTSTRAP_SEED ^ crate::util::fnv1a64(label.as_bytes())
}

/// Stratified percentile bootstrap of the mean over all values of `strata` (each inner slice is
/// one stratum, resampled with replacement at its own size), `resamples` times, seeded with
/// `seed`; the `level` interval (0.95 for 95 %). `None` when there is no value.
pub fn bootstrap_mean_ci(
    strata: &[Vec<f64>],
    resamples: usize,
    seed: u64,
    level: f64,
) -> Option<Ci> {
    let strata: Vec<&Vec<f64>> = strata.iter().filter(|s| !s.is_empty()).collect();
    let n: usize = strata.iter().map(|s| s.len()).sum();
    if n == 0 {
        return None;
    }
    let all: Vec<f64> = strata.iter().flat_map(|s| s.iter().copied()).collect();
    let m = mean(&all)?;
    let min_stratum = strata.iter().map(|s| s.len()).min().unwrap_or(0);
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let mut means = Vec::with_capacity(resamples.max(1));
    for _ in 0..resamples.max(1) {
        let mut sum = 0.0;
        for s in &strata {
            for _ in 0..s.len() {
                sum += s[rng.random_range(0..s.len())];
            }
        }
        means.push(sum / n as f64);
    }
    means.sort_by(f64::total_cmp);
    let a = (1.0 - level) / 2.0;
    Some(Ci {
        mean: m,
        lo: quantile_sorted(&means, a),
        hi: quantile_sorted(&means, 1.0 - a),
        n,
        min_stratum,
    })
}

/// [`bootstrap_mean_ci`] with [`RESAMPLES`], 95 %, and the stream of `label`.
pub fn paired_ci(label: &str, strata: &[Vec<f64>]) -> Option<Ci> {
    bootstrap_mean_ci(strata, RESAMPLES, stream_seed(label), 0.95)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn mean_std_quantile() {
        assert_eq!(mean(&[]), None);
        assert_eq!(mean(&[1.0, 2.0, 6.0]), Some(3.0));
        assert_eq!(sample_std(&[5.0]), None);
        assert!(
            (sample_std(&[1.0, 2.0, 3.0, 4.0]).unwrap() - 1.290_994_448_735_805_6).abs() < 1e-15
        );
        let s = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(quantile_sorted(&s, 0.0), 1.0);
        assert_eq!(quantile_sorted(&s, 1.0), 5.0);
        assert_eq!(quantile_sorted(&s, 0.5), 3.0);
        assert!((quantile_sorted(&s, 0.1) - 1.4).abs() < 1e-12);
    }

    #[test]
    fn a_constant_difference_has_a_zero_width_interval_at_that_constant() {
        let ci = paired_ci("c", &[vec![-0.25; 3], vec![-0.25; 5]]).unwrap();
        assert_eq!((ci.mean, ci.lo, ci.hi, ci.n), (-0.25, -0.25, -0.25, 8));
        assert_eq!(ci.min_stratum, 3);
        assert!(paired_ci("e", &[vec![], vec![]]).is_none());
    }

    #[test]
    fn same_label_same_interval_other_label_other_stream() {
        let d = vec![vec![0.1, -0.3, 0.2, 0.05, -0.1, 0.4]];
        assert_eq!(paired_ci("a", &d), paired_ci("a", &d));
        assert_ne!(paired_ci("a", &d), paired_ci("b", &d));
    }

    #[test]
    fn symmetric_data_gives_an_interval_around_the_mean_of_the_right_width() {
        // Normal(μ = 0.3, σ = 1), n = 400: the mean's standard error is 0.05, so the 95 %
        // interval is about ±1.96·0.05 = ±0.098 around the sample mean.
        let mut rng = Pcg64Mcg::seed_from_u64(7);
        let nd = Normal::new(0.3, 1.0).unwrap();
        let x: Vec<f64> = (0..400).map(|_| nd.sample(&mut rng)).collect();
        let ci = paired_ci("normal", std::slice::from_ref(&x)).unwrap();
        let se = sample_std(&x).unwrap() / 20.0;
        assert!(ci.lo < ci.mean && ci.mean < ci.hi, "{ci:?}");
        assert!(
            (ci.lo - 0.3).abs() < 0.2 && ci.lo < 0.3 + 0.05 && ci.hi > 0.3 - 0.05,
            "{ci:?}"
        );
        let half = 0.5 * (ci.hi - ci.lo);
        assert!(
            (half / (1.96 * se) - 1.0).abs() < 0.1,
            "half-width {half} vs {}",
            1.96 * se
        );
        // Symmetric around the mean to within Monte Carlo noise.
        assert!(
            ((ci.hi - ci.mean) - (ci.mean - ci.lo)).abs() < 0.02,
            "{ci:?}"
        );
    }

    /// The exact bootstrap distribution of the mean of n = 4 values enumerates all 4⁴ = 256
    /// equally likely resamples; the Monte Carlo percentiles must sit at its 2.5 % / 97.5 %
    /// points (up to the Monte Carlo error on a probability, ~0.5 % here).
    #[test]
    fn percentiles_match_the_enumerated_bootstrap_distribution() {
        let x = [0.0, 1.0, 3.0, 10.0];
        let mut exact = Vec::new();
        for a in 0..4 {
            for b in 0..4 {
                for c in 0..4 {
                    for d in 0..4 {
                        exact.push((x[a] + x[b] + x[c] + x[d]) / 4.0);
                    }
                }
            }
        }
        let cdf = |v: f64, strict: bool| {
            exact
                .iter()
                .filter(|&&m| if strict { m < v } else { m <= v })
                .count() as f64
                / exact.len() as f64
        };
        let ci = bootstrap_mean_ci(&[x.to_vec()], 40_000, 11, 0.95).unwrap();
        assert_eq!(ci.mean, 3.5);
        // P(mean < lo) ≤ 2.5 % ≤ P(mean ≤ lo), within tolerance; likewise at the top.
        let tol = 0.006;
        assert!(
            cdf(ci.lo, true) <= 0.025 + tol && cdf(ci.lo, false) >= 0.025 - tol,
            "lo {}",
            ci.lo
        );
        assert!(
            cdf(ci.hi, true) <= 0.975 + tol && cdf(ci.hi, false) >= 0.975 - tol,
            "hi {}",
            ci.hi
        );
    }

    #[test]
    fn strata_keep_their_sizes() {
        // Two strata with constant but different values: every resample has 2 × 5 and 1 × 1, so
        // the mean never moves.
        let ci = bootstrap_mean_ci(&[vec![5.0, 5.0], vec![1.0]], 500, 3, 0.95).unwrap();
        assert_eq!((ci.lo, ci.hi), (11.0 / 3.0, 11.0 / 3.0));
        // Without strata the same values would spread.
        let pooled = bootstrap_mean_ci(&[vec![5.0, 5.0, 1.0]], 500, 3, 0.95).unwrap();
        assert!(pooled.hi - pooled.lo > 1.0, "{pooled:?}");
    }
}
