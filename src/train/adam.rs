//! AdamW (Loshchilov & Hutter 2019) exactly as PyTorch's `torch.optim.AdamW`, which instant-nsr-pl
//! uses (`configs/neus-dtu-wmask.yaml`: lr 0.01, betas (0.9, 0.99), eps 1e-15, and PyTorch's
//! default weight decay 0.01 applied to every group):
//!
//! `p ← p·(1 − lr·wd)`, `m ← β1·m + (1−β1)·g`, `v ← β2·v + (1−β2)·g²`,
//! `p ← p − (lr / (1−β1^t)) · m / (√v / √(1−β2^t) + eps)`.
//!
//! Each parameter group's learning rate is `lr · lr_scale(group) · factor`, where `factor` comes
//! from the schedule and is passed explicitly ([`crate::train::schedule::LrSchedule`]).
//!
//! NaN guard: a step whose gradients or resulting parameters would contain NaN or ±inf is
//! detected before anything is written, reported as [`OptimError::NonFinite`] (naming the group,
//! the first bad index and the count) and skipped: parameters, moments and the step counter stay
//! as they were.

use crate::field::ParamLayout;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// Optimiser hyper-parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AdamWConfig {
    /// Base learning rate (1e-2).
    pub lr: f32,
    pub beta1: f32,
    pub beta2: f32,
    pub eps: f32,
    /// Decoupled weight decay (0.01, PyTorch's AdamW default).
    pub weight_decay: f32,
}

impl Default for AdamWConfig {
    fn default() -> Self {
        Self {
            lr: 1e-2,
            beta1: 0.9,
            beta2: 0.99,
            eps: 1e-15,
            weight_decay: 0.01,
        }
    }
}

/// Errors of an optimiser step.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum OptimError {
    #[error("optimiser step skipped: {count} non-finite {what} in group `{group}` (first at flat index {index})")]
    NonFinite {
        /// `gradient` or `updated parameter`.
        what: &'static str,
        group: String,
        index: usize,
        count: usize,
    },
    #[error("optimiser: buffer lengths differ (params {params}, grads {grads}, layout {layout})")]
    Length {
        params: usize,
        grads: usize,
        layout: usize,
    },
}

/// AdamW state: first and second moments, step counter.
#[derive(Debug, Clone, PartialEq)]
pub struct AdamW {
    pub config: AdamWConfig,
    pub m: Vec<f32>,
    pub v: Vec<f32>,
    /// Completed steps.
    pub t: u64,
}

const BLOCK: usize = 1 << 15;

impl AdamW {
    pub fn new(config: AdamWConfig, n: usize) -> Self {
        Self {
            config,
            m: vec![0.0; n],
            v: vec![0.0; n],
            t: 0,
        }
    }

    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn update(
        p: f32,
        g: f32,
        m: f32,
        v: f32,
        lr: f32,
        c: &AdamWConfig,
        bc1: f32,
        sbc2: f32,
    ) -> (f32, f32, f32) {
        let p = p * (1.0 - lr * c.weight_decay);
        let m = c.beta1 * m + (1.0 - c.beta1) * g;
        let v = c.beta2 * v + (1.0 - c.beta2) * g * g;
        let denom = v.sqrt() / sbc2 + c.eps;
        (p - (lr / bc1) * m / denom, m, v)
    }

    /// One step with learning-rate factor `factor` (from the schedule). On error nothing changes.
    pub fn step(
        &mut self,
        params: &mut [f32],
        grads: &[f32],
        layout: &ParamLayout,
        factor: f32,
    ) -> Result<(), OptimError> {
        self.check(params, grads, layout, factor)?;
        self.write(params, grads, layout, factor);
        Ok(())
    }

    /// [`step`](Self::step), then the gradients are set to zero in the same pass over memory (the
    /// training loop needs zeroed gradients before the next step; this saves it a pass over the
    /// buffer). On error nothing changes, the gradients included.
    pub fn step_and_zero_grads(
        &mut self,
        params: &mut [f32],
        grads: &mut [f32],
        layout: &ParamLayout,
        factor: f32,
    ) -> Result<(), OptimError> {
        self.check(params, grads, layout, factor)?;
        self.write(params, grads, layout, factor);
        Ok(())
    }

    /// Per-step constants: bias corrections (`1 − β1^t`, `√(1 − β2^t)`) for step `t + 1`.
    fn corrections(&self) -> (f32, f32) {
        let c = &self.config;
        let t = (self.t + 1).min(i32::MAX as u64) as i32;
        (1.0 - c.beta1.powi(t), (1.0 - c.beta2.powi(t)).sqrt())
    }

    /// Pass 1: the updated values of every group are computed (vectorised, in parallel blocks)
    /// and checked for finiteness; nothing is written. Only when a block fails is the exact
    /// report (group, first index, count) computed.
    fn check(
        &self,
        params: &[f32],
        grads: &[f32],
        layout: &ParamLayout,
        factor: f32,
    ) -> Result<(), OptimError> {
        let n = params.len();
        if grads.len() != n || self.m.len() != n || self.v.len() != n || layout.total() != n {
            return Err(OptimError::Length {
                params: n,
                grads: grads.len(),
                layout: layout.total(),
            });
        }
        let c = &self.config;
        let (bc1, sbc2) = self.corrections();
        for grp in &layout.groups {
            let r = grp.range();
            let lr = c.lr * grp.lr_scale * factor;
            let (pp, gg, mm, vv) = (
                &params[r.clone()],
                &grads[r.clone()],
                &self.m[r.clone()],
                &self.v[r.clone()],
            );
            let n_bad_g: usize = gg
                .par_chunks(BLOCK)
                .map(|b| b.iter().filter(|x| !x.is_finite()).count())
                .sum();
            if n_bad_g > 0 {
                let (index, count) = first_bad(gg, |_, g| !g.is_finite()).expect("counted");
                return Err(OptimError::NonFinite {
                    what: "gradient",
                    group: grp.name.clone(),
                    index: r.start + index,
                    count,
                });
            }
            let n_bad_p: usize = pp
                .par_chunks(BLOCK)
                .zip(gg.par_chunks(BLOCK))
                .zip(mm.par_chunks(BLOCK).zip(vv.par_chunks(BLOCK)))
                .map(|((p, g), (m, v))| {
                    let mut bad = 0usize;
                    for i in 0..p.len() {
                        let (np, nm, nv) = Self::update(p[i], g[i], m[i], v[i], lr, c, bc1, sbc2);
                        bad += usize::from(!(np.is_finite() & nm.is_finite() & nv.is_finite()));
                    }
                    bad
                })
                .sum();
            if n_bad_p > 0 {
                let (index, count) = first_bad(pp, |i, &p| {
                    let (np, nm, nv) = Self::update(p, gg[i], mm[i], vv[i], lr, c, bc1, sbc2);
                    !(np.is_finite() && nm.is_finite() && nv.is_finite())
                })
                .expect("counted");
                return Err(OptimError::NonFinite {
                    what: "updated parameter",
                    group: grp.name.clone(),
                    index: r.start + index,
                    count,
                });
            }
        }
        Ok(())
    }

    /// Pass 2: writes the updated parameters and moments (checked by [`check`](Self::check)),
    /// reading the gradients through `grads` (which zeroes each one after use when it is
    /// `&mut [f32]`, see [`Grads`]).
    fn write<G: Grads>(
        &mut self,
        params: &mut [f32],
        mut grads: G,
        layout: &ParamLayout,
        factor: f32,
    ) {
        let c = self.config.clone();
        let (bc1, sbc2) = self.corrections();
        for grp in &layout.groups {
            let r = grp.range();
            let lr = c.lr * grp.lr_scale * factor;
            params[r.clone()]
                .par_chunks_mut(BLOCK)
                .zip(grads.blocks(r.clone()))
                .zip(self.m[r.clone()].par_chunks_mut(BLOCK))
                .zip(self.v[r.clone()].par_chunks_mut(BLOCK))
                .for_each(|(((p, mut g), m), v)| {
                    for i in 0..p.len() {
                        let gi = G::take(&mut g, i);
                        let (np, nm, nv) = Self::update(p[i], gi, m[i], v[i], lr, &c, bc1, sbc2);
                        p[i] = np;
                        m[i] = nm;
                        v[i] = nv;
                    }
                });
        }
        self.t += 1;
    }
}

/// The gradient buffer as [`AdamW::write`] reads it, in the same parallel blocks of [`BLOCK`]
/// values as the parameters: `&[f32]` reads each gradient, `&mut [f32]` reads it and sets it to
/// zero (the fused [`AdamW::step_and_zero_grads`]).
trait Grads {
    /// One block of gradients.
    type Block<'a>: Send
    where
        Self: 'a;

    /// The blocks of the flat range `r`.
    fn blocks(&mut self, r: Range<usize>) -> impl IndexedParallelIterator<Item = Self::Block<'_>>;

    /// Gradient `i` of a block (zeroing it, for the mutable form).
    fn take(block: &mut Self::Block<'_>, i: usize) -> f32;
}

impl Grads for &[f32] {
    type Block<'a>
        = &'a [f32]
    where
        Self: 'a;

    fn blocks(&mut self, r: Range<usize>) -> impl IndexedParallelIterator<Item = &[f32]> {
        self[r].par_chunks(BLOCK)
    }

    #[inline(always)]
    fn take(block: &mut &[f32], i: usize) -> f32 {
        block[i]
    }
}

impl Grads for &mut [f32] {
    type Block<'a>
        = &'a mut [f32]
    where
        Self: 'a;

    fn blocks(&mut self, r: Range<usize>) -> impl IndexedParallelIterator<Item = &mut [f32]> {
        self[r].par_chunks_mut(BLOCK)
    }

    #[inline(always)]
    fn take(block: &mut &mut [f32], i: usize) -> f32 {
        let g = block[i];
        block[i] = 0.0;
        g
    }
}

/// First index where `bad` holds and how many do, checked in parallel blocks.
fn first_bad<F: Fn(usize, &f32) -> bool + Sync>(xs: &[f32], bad: F) -> Option<(usize, usize)> {
    let per_block: Vec<(Option<usize>, usize)> = xs
        .par_chunks(BLOCK)
        .enumerate()
        .map(|(b, blk)| {
            let mut first = None;
            let mut count = 0;
            for (j, x) in blk.iter().enumerate() {
                if bad(b * BLOCK + j, x) {
                    first.get_or_insert(b * BLOCK + j);
                    count += 1;
                }
            }
            (first, count)
        })
        .collect();
    let count: usize = per_block.iter().map(|b| b.1).sum();
    per_block.iter().find_map(|b| b.0).map(|f| (f, count))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout(n: usize) -> ParamLayout {
        let mut l = ParamLayout::default();
        l.push("a", vec![n - 1], 1.0);
        l.push("variance", vec![1], 0.1);
        l
    }

    /// Matches a straightforward scalar transcription of PyTorch's AdamW over several steps.
    #[test]
    fn matches_reference_formula() {
        let l = layout(3);
        let mut p = vec![0.5f32, -0.25, 0.3];
        let mut opt = AdamW::new(AdamWConfig::default(), 3);
        let mut rp = [0.5f64, -0.25, 0.3];
        let (mut rm, mut rv) = ([0f64; 3], [0f64; 3]);
        for t in 1..=5 {
            let g: Vec<f32> = (0..3)
                .map(|i| 0.1 * (i as f32 + 1.0) * (t as f32).sin())
                .collect();
            opt.step(&mut p, &g, &l, 0.5).unwrap();
            for i in 0..3 {
                let lr = 0.01 * 0.5 * if i == 2 { 0.1 } else { 1.0 };
                rp[i] *= 1.0 - lr * 0.01;
                rm[i] = 0.9 * rm[i] + 0.1 * g[i] as f64;
                rv[i] = 0.99 * rv[i] + 0.01 * (g[i] as f64).powi(2);
                let bc1 = 1.0 - 0.9f64.powi(t);
                let bc2 = 1.0 - 0.99f64.powi(t);
                rp[i] -= lr / bc1 * rm[i] / (rv[i].sqrt() / bc2.sqrt() + 1e-15);
            }
        }
        for i in 0..3 {
            assert!(
                (p[i] as f64 - rp[i]).abs() < 1e-6,
                "param {i}: {} vs {}",
                p[i],
                rp[i]
            );
        }
        assert_eq!(opt.t, 5);
    }

    /// A NaN gradient or a step so large the parameters overflow is detected, reported with the
    /// group, and skipped without touching any state.
    #[test]
    fn non_finite_steps_are_skipped() {
        let l = layout(4);
        let mut p = vec![1.0f32, 2.0, 3.0, 0.3];
        let mut opt = AdamW::new(AdamWConfig::default(), 4);
        opt.step(&mut p, &[0.1, 0.1, 0.1, 0.1], &l, 1.0).unwrap();
        let (p0, m0, v0) = (p.clone(), opt.m.clone(), opt.v.clone());
        let err = opt
            .step(&mut p, &[0.1, f32::NAN, 0.1, 0.1], &l, 1.0)
            .unwrap_err();
        assert_eq!(
            err,
            OptimError::NonFinite {
                what: "gradient",
                group: "a".into(),
                index: 1,
                count: 1
            }
        );
        // Huge learning step (an infinite schedule factor) and an exploding gradient whose
        // square overflows the second moment.
        let err = opt
            .step(&mut p, &[0.1, 0.1, 0.1, 1.0], &l, f32::INFINITY)
            .unwrap_err();
        assert!(
            matches!(
                err,
                OptimError::NonFinite {
                    what: "updated parameter",
                    ..
                }
            ),
            "{err}"
        );
        let err = opt
            .step(&mut p, &[0.1, 0.1, 1e30, 1.0], &l, 1.0)
            .unwrap_err();
        assert!(
            matches!(
                err,
                OptimError::NonFinite {
                    what: "updated parameter",
                    index: 2,
                    ..
                }
            ),
            "{err}"
        );
        assert_eq!(
            (p.clone(), opt.m.clone(), opt.v.clone(), opt.t),
            (p0, m0, v0, 1)
        );
        assert!(p.iter().all(|v| v.is_finite()));
    }

    /// The fused variant leaves the same parameters and moments as `step` and zeroed gradients;
    /// on error it changes nothing, gradients included. Buffers span several parallel blocks.
    #[test]
    fn step_and_zero_grads_matches_step() {
        let n = 3 * BLOCK + 17;
        let l = layout(n);
        let g: Vec<f32> = (0..n)
            .map(|i| ((i * 7919) % 1000) as f32 * 1e-3 - 0.5)
            .collect();
        let p0: Vec<f32> = (0..n).map(|i| ((i * 104729) % 997) as f32 * 1e-3).collect();
        let (mut p1, mut p2) = (p0.clone(), p0.clone());
        let mut o1 = AdamW::new(AdamWConfig::default(), n);
        let mut o2 = o1.clone();
        for _ in 0..3 {
            o1.step(&mut p1, &g, &l, 0.7).unwrap();
            let mut g2 = g.clone();
            o2.step_and_zero_grads(&mut p2, &mut g2, &l, 0.7).unwrap();
            assert!(g2.iter().all(|&v| v == 0.0));
        }
        assert_eq!((&p1, &o1.m, &o1.v, o1.t), (&p2, &o2.m, &o2.v, o2.t));
        let mut bad = g.clone();
        bad[2 * BLOCK + 5] = f32::INFINITY;
        let before = (p2.clone(), o2.clone(), bad.clone());
        let err = o2
            .step_and_zero_grads(&mut p2, &mut bad, &l, 0.7)
            .unwrap_err();
        assert_eq!(
            err,
            OptimError::NonFinite {
                what: "gradient",
                group: "a".into(),
                index: 2 * BLOCK + 5,
                count: 1
            }
        );
        assert_eq!((p2, o2, bad), before);
    }
}
