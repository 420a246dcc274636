//! The gate of pose refinement (`train.pose_refine.gate`): before any camera moves, listen to
//! each view's pose gradient for a share of the run, and refine only when the gradient points
//! one way.
//!
//! Why: on poses that are already as good as the images can tell (exact cameras, or COLMAP's
//! bundle-adjusted ones), the pose gradient is noise about zero, and Adam, whose step does not
//! shrink with the gradient, walks the cameras off by a fraction of a pixel anyway, which costs
//! the mesh accuracy (`docs/pose-refinement.md`). Off by pixels, the gradient keeps its sign.
//!
//! The test: with the cameras held still, each view's `(ω, t)` gradient `g_s` at the listened
//! steps `s` is summed per component `k`, `S_k = Σ g_{s,k}`, `Q_k = Σ g_{s,k}²`. Under the null
//! hypothesis (zero-mean gradients, independent from step to step: the batch's rays are drawn
//! afresh at every step), the self-normalised sum `S_k / √Q_k` is close to a standard normal
//! (Efron, "Student's t-test under symmetry conditions", JASA 64, 1969), so the view's
//! statistic `T = Σ_k S_k² / Q_k` is close to χ² with 6 degrees of freedom (measured on exact
//! and on COLMAP's cameras of `blob`: median 4.7–6.9, χ²₆'s is 5.35); a consistent gradient
//! makes `T` grow in proportion to the steps listened. The verdict:
//! 1. when the median view's `T` exceeds χ²₆'s 0.999 quantile ([`GATE_CHI2`]), the poses are
//!    off as a set and every view is refined (as without the gate);
//! 2. otherwise each view whose own `T` exceeds the quantile that keeps the chance of any
//!    noise-only view passing below 0.001 (Bonferroni over the views: χ²₆'s `1 − 0.001/n`
//!    quantile) is refined, the others keep a zero correction for the rest of the run and no
//!    longer pay for their rays' gradient.

/// The 0.999 quantile of the χ² distribution with 6 degrees of freedom ([`chi2_6_quantile`]).
pub const GATE_CHI2: f64 = 22.458;

/// The survival function of χ² with 6 degrees of freedom, `P(X > x) = e^{−x/2}(1 + x/2 +
/// x²/8)` (an even number of degrees of freedom has this closed form).
pub fn chi2_6_sf(x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let h = x / 2.0;
    (-h).exp() * (1.0 + h + h * h / 2.0)
}

/// The `1 − alpha` quantile of χ² with 6 degrees of freedom (`alpha` in `(0, 1)`), by
/// bisection of [`chi2_6_sf`] to 1e-9.
pub fn chi2_6_quantile(alpha: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    while chi2_6_sf(hi) > alpha {
        hi *= 2.0;
    }
    while hi - lo > 1e-9 * hi {
        let mid = 0.5 * (lo + hi);
        if chi2_6_sf(mid) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The gate's evidence and verdict (checkpointed as `pose.gate`, `[views][14]` rows
/// [`Gate::to_rows`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Gate {
    /// `[views][6]`: the sum over the listened steps of each view's `(ω, t)` gradient ...
    pub sum: Vec<[f64; 6]>,
    /// ... and of its square.
    pub sq: Vec<[f64; 6]>,
    /// Steps listened.
    pub steps: u64,
    /// `[views]`: whether each view is refined, once the listening is over (`None` before).
    pub refine: Option<Vec<bool>>,
}

impl Gate {
    /// Nothing heard yet, for `views` views.
    pub fn new(views: usize) -> Self {
        Self {
            sum: vec![[0.0; 6]; views],
            sq: vec![[0.0; 6]; views],
            steps: 0,
            refine: None,
        }
    }

    /// Whether the listening is still going on.
    pub fn listening(&self) -> bool {
        self.refine.is_none()
    }

    /// Whether view `v`'s correction may move: while listening, none does; after, the views
    /// that passed.
    pub fn moves(&self, v: usize) -> bool {
        self.refine.as_ref().is_some_and(|r| r[v])
    }

    /// Whether view `v`'s rays' gradient is wanted: while listening, every view's; after, the
    /// refined views'.
    pub fn hears(&self, v: usize) -> bool {
        self.refine.as_ref().is_none_or(|r| r[v])
    }

    /// Adds one step's `[views][6]` gradients (zero for a view without a differentiated ray),
    /// and gives the verdict once `listen` steps are heard.
    pub fn listen(&mut self, grads: &[[f64; 6]], listen: u64) {
        for ((s, q), g) in self.sum.iter_mut().zip(&mut self.sq).zip(grads) {
            for k in 0..6 {
                s[k] += g[k];
                q[k] += g[k] * g[k];
            }
        }
        self.steps += 1;
        if self.steps >= listen.max(1) {
            self.refine = Some(self.verdict());
        }
    }

    /// The verdict of the module doc: every view when the median view passes χ²₆'s 0.999
    /// quantile; otherwise the views that pass the Bonferroni-corrected one.
    fn verdict(&self) -> Vec<bool> {
        let n = self.sum.len();
        let t: Vec<f64> = (0..n).map(|v| self.statistic(v)).collect();
        if median(&t) > GATE_CHI2 {
            return vec![true; n];
        }
        let bar = chi2_6_quantile(0.001 / n.max(1) as f64);
        t.iter().map(|&x| x > bar).collect()
    }

    /// View `v`'s statistic `T = Σ_k S_k² / Q_k` (a component never heard adds 0).
    pub fn statistic(&self, v: usize) -> f64 {
        self.sum[v]
            .iter()
            .zip(&self.sq[v])
            .map(|(s, q)| if *q > 0.0 { s * s / q } else { 0.0 })
            .sum()
    }

    /// `[views][14]` rows: `S` (6), `Q` (6), the steps listened, the verdict (0 while
    /// listening, 1 refined, −1 held still).
    pub fn to_rows(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.sum.len() * 14);
        for v in 0..self.sum.len() {
            out.extend(self.sum[v]);
            out.extend(self.sq[v]);
            out.push(self.steps as f64);
            out.push(match &self.refine {
                None => 0.0,
                Some(r) if r[v] => 1.0,
                Some(_) => -1.0,
            });
        }
        out
    }

    /// The inverse of [`Self::to_rows`] for `views` views; `None` when the rows do not fit, a
    /// value is not finite, a square sum is negative, or the rows disagree on the steps or on
    /// whether the listening is over.
    pub fn from_rows(rows: &[f64], views: usize) -> Option<Self> {
        if rows.len() != views * 14 || rows.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let mut g = Self::new(views);
        let steps = rows.get(12).copied().unwrap_or(0.0);
        let listening = rows.get(13).is_some_and(|&d| d == 0.0);
        let mut verdict = Vec::with_capacity(views);
        for (v, r) in rows.chunks_exact(14).enumerate() {
            g.sum[v].copy_from_slice(&r[..6]);
            g.sq[v].copy_from_slice(&r[6..12]);
            let bad_verdict = ![0.0, 1.0, -1.0].contains(&r[13]) || (r[13] == 0.0) != listening;
            if r[6..12].iter().any(|&q| q < 0.0) || r[12] != steps || r[12] < 0.0 || bad_verdict {
                return None;
            }
            verdict.push(r[13] > 0.0);
        }
        g.steps = steps as u64;
        g.refine = (!listening).then_some(verdict);
        Some(g)
    }

    /// What the gate decided, for the run's metrics.
    pub fn summary(&self) -> GateSummary {
        let n = self.sum.len();
        let t: Vec<f64> = (0..n).map(|v| self.statistic(v)).collect();
        GateSummary {
            steps: self.steps,
            decided: !self.listening(),
            refined_views: (0..n).filter(|&v| self.moves(v)).count(),
            median_statistic: median(&t),
        }
    }
}

/// The median of `x` (the upper one of an even count; 0 when empty).
fn median(x: &[f64]) -> f64 {
    let mut t = x.to_vec();
    t.sort_by(f64::total_cmp);
    t.get(t.len() / 2).copied().unwrap_or(0.0)
}

/// What the gate decided (`metrics.json` `train.pose_refine.gate`).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GateSummary {
    /// Steps listened.
    pub steps: u64,
    /// Whether the listening ended within the run (false: no view was refined).
    pub decided: bool,
    /// Views that passed and were refined, of the training views.
    pub refined_views: usize,
    /// The median over the views of the statistic `T` (about 5.3 for pure noise: the median
    /// of χ²₆).
    pub median_statistic: f64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    use rand_pcg::Pcg64Mcg;

    /// One step of `views` gradients: standard normal noise, plus `shift` on one component of
    /// the views `signal`.
    fn heard(
        rng: &mut Pcg64Mcg,
        views: usize,
        signal: std::ops::Range<usize>,
        shift: f64,
    ) -> Vec<[f64; 6]> {
        (0..views)
            .map(|v| {
                let mut x = [0.0; 6];
                for (k, xk) in x.iter_mut().enumerate() {
                    let s = if signal.contains(&v) && k == 4 {
                        shift
                    } else {
                        0.0
                    };
                    let e: f64 = StandardNormal.sample(rng);
                    *xk = e + s;
                }
                x
            })
            .collect()
    }

    /// The quantiles are χ²₆'s (tabulated: 22.458 at 0.999, 12.592 at 0.95).
    #[test]
    fn the_quantiles_are_chi_squared_with_six_degrees_of_freedom() {
        assert!((chi2_6_quantile(0.001) - GATE_CHI2).abs() < 1e-3);
        assert!((chi2_6_quantile(0.05) - 12.592).abs() < 1e-3);
        assert!((chi2_6_sf(0.0) - 1.0).abs() < 1e-15);
        assert!(chi2_6_quantile(1e-6) > chi2_6_quantile(1e-3));
    }

    /// Noise holds every view still; a few views with a consistent gradient (half the noise)
    /// are refined alone; a set where most views have one is refined whole; nothing
    /// moves while listening; the rows round-trip and refuse what does not fit.
    #[test]
    fn the_gate_passes_a_consistent_gradient_and_holds_noise_still() {
        let mut rng = Pcg64Mcg::seed_from_u64(7);
        let (views, steps) = (46, 300u64);
        let run = |rng: &mut Pcg64Mcg, signal: std::ops::Range<usize>, shift: f64| {
            let mut gate = Gate::new(views);
            for s in 0..steps {
                assert!(gate.listening() && !gate.moves(3) && gate.hears(3));
                gate.listen(&heard(rng, views, signal.clone(), shift), steps);
                assert_eq!(gate.listening(), s + 1 < steps);
            }
            gate
        };
        for trial in 0..20 {
            let noise = run(&mut rng, 0..0, 0.0);
            assert_eq!(noise.summary().refined_views, 0, "trial {trial}");
            assert!(!noise.hears(3));
        }
        // Three views with a mean of 0.5 over 300 steps: S/√Q ≈ 0.5·√300/√1.25 ≈ 7.7, T ≈ 65,
        // above the corrected bar (about 35 for 46 views).
        let few = run(&mut rng, 0..3, 0.5);
        let moved: Vec<usize> = (0..views).filter(|&v| few.moves(v)).collect();
        assert!(
            moved.iter().all(|&v| v < 3) && !moved.is_empty(),
            "{moved:?}"
        );
        // Thirty views with a mean of 0.3: T ≈ 30, above 22.458 but mostly below the corrected
        // bar; the median passes, so every view is refined.
        let most = run(&mut rng, 0..30, 0.3);
        assert_eq!(most.summary().refined_views, views);
        assert!(most.summary().median_statistic > GATE_CHI2);

        let back = Gate::from_rows(&most.to_rows(), views).unwrap();
        assert_eq!(back, most);
        let mut fresh = Gate::new(3);
        fresh.listen(&[[1.0; 6]; 3], 5);
        assert_eq!(Gate::from_rows(&fresh.to_rows(), 3).unwrap(), fresh);
        let mut rows = few.to_rows();
        assert!(Gate::from_rows(&rows, views + 1).is_none());
        rows[6] = -1.0;
        assert!(Gate::from_rows(&rows, views).is_none());
        let mut rows = few.to_rows();
        rows[14 + 13] = 0.0;
        assert!(
            Gate::from_rows(&rows, views).is_none(),
            "one view still listening"
        );
        let mut rows = few.to_rows();
        rows[0] = f64::NAN;
        assert!(Gate::from_rows(&rows, views).is_none());
    }
}
