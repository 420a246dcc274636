//! Reduced data (paper §4, "reduced number of training images"): a seeded random subset of the
//! training views.

use super::AugmentError;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;

/// The indices (ascending) of the views kept when training on `fraction` of `n_views` views.
///
/// Keeps `max(1, round(fraction · n_views))` views (half rounds up): 49 DTU views give 5, 12, 25
/// and 37 for 0.1, 0.25, 0.5 and 0.75. The subset is the first `k` entries of one seeded random
/// permutation of `0..n_views`, so under one seed the subsets are nested (the 10 % views are among
/// the 25 % ones), and the same seed gives the same subset. Errors: `n_views = 0` (no view to
/// keep) and a fraction outside `(0, 1]` or not finite (it would keep no view, or more than all).
pub fn views_fraction(
    n_views: usize,
    fraction: f64,
    seed: u64,
) -> Result<Vec<usize>, AugmentError> {
    let err = |reason: &str| AugmentError::ViewsFraction {
        fraction,
        n_views,
        reason: reason.to_string(),
    };
    if !(fraction.is_finite() && fraction > 0.0 && fraction <= 1.0) {
        return Err(err(
            "the fraction must lie in (0, 1] (e.g. 0.1, 0.25, 0.5, 0.75)",
        ));
    }
    if n_views == 0 {
        return Err(err("the scene has no views"));
    }
    let k = ((fraction * n_views as f64).round() as usize).clamp(1, n_views);
    let mut order: Vec<usize> = (0..n_views).collect();
    order.shuffle(&mut Pcg64Mcg::seed_from_u64(seed));
    let mut kept = order[..k].to_vec();
    kept.sort_unstable();
    Ok(kept)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_follow_the_fraction_and_never_drop_below_one() {
        let n = |f| views_fraction(49, f, 0).unwrap().len();
        assert_eq!(
            [n(0.1), n(0.25), n(0.5), n(0.75), n(1.0)],
            [5, 12, 25, 37, 49]
        );
        assert_eq!(views_fraction(3, 0.1, 0).unwrap().len(), 1);
        assert_eq!(views_fraction(1, 0.25, 9).unwrap(), vec![0]);
    }

    #[test]
    fn subsets_are_seeded_sorted_distinct_and_nested() {
        let a = views_fraction(64, 0.25, 7).unwrap();
        assert_eq!(a, views_fraction(64, 0.25, 7).unwrap());
        assert_ne!(a, views_fraction(64, 0.25, 8).unwrap());
        assert!(a.windows(2).all(|w| w[0] < w[1]) && *a.last().unwrap() < 64);
        let fractions = [0.1, 0.25, 0.5, 0.75, 1.0];
        let sets: Vec<_> = fractions
            .iter()
            .map(|&f| views_fraction(64, f, 7).unwrap())
            .collect();
        for pair in sets.windows(2) {
            assert!(
                pair[0].iter().all(|i| pair[1].contains(i)),
                "not nested: {pair:?}"
            );
        }
        // Not simply the first views: the kept set depends on the seed.
        assert_ne!(
            views_fraction(64, 0.1, 7).unwrap(),
            (0..6).collect::<Vec<_>>()
        );
    }

    #[test]
    fn fractions_that_leave_no_view_are_errors() {
        for f in [0.0, -0.5, 1.5, f64::NAN, f64::INFINITY] {
            let err = views_fraction(49, f, 0).unwrap_err().to_string();
            assert!(err.contains("(0, 1]"), "{f}: {err}");
        }
        let err = views_fraction(0, 0.5, 0).unwrap_err().to_string();
        assert!(err.contains("no views"), "{err}");
    }
}
