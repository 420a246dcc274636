//! Occupancy grid for empty-space skipping (nerfacc 0.3 `OccupancyGrid`, as instant-nsr-pl's
//! `NeuSModel.update_step` drives it).
//!
//! `resolution³` cells over `[-r, r]³`, each with an occupancy value `occ` (an EMA-style running
//! max of the NeuS alpha) and a binary flag. The update rule (`every_n_step` / `_update`):
//! every `update_every` (16) steps, starting at step 0,
//! - steps `< warmup_steps` (256): evaluate **every** cell;
//! - later: `N/4` uniformly random cells plus `N/4` random occupied cells (all occupied cells when
//!   there are fewer), with replacement;
//! - at a uniformly jittered point in each chosen cell, `occ ← max(occ·0.95, α(x))` where `α` is the
//!   NeuS alpha of an interval of the render step centred on `x` with `cos = −1`
//!   ([`crate::render::alpha::neus_alpha`]);
//! - `binary = occ > min(mean(occ), threshold)` with `threshold = grid_prune_occ_thre = 0.001`
//!   (`neus-dtu-wmask.yaml`).
//!
//! Before the first update every cell counts as occupied (nerfacc starts empty but updates at
//! step 0 before the first march; starting full makes forgetting that update harmless).

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use rand::Rng;
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};

/// Steps of the schedule the reference decay belongs to (instant-nsr-pl
/// `configs/neus-dtu-wmask.yaml`, `trainer.max_steps: 20000`, the grid updated every 16 steps).
pub const REFERENCE_STEPS: u64 = 20_000;

/// The reference's decay per update (nerfacc 0.3 `OccupancyGrid.every_n_step`, `ema_decay=0.95`).
pub const REFERENCE_DECAY: f32 = 0.95;

/// The decay per update that makes a run of `iterations` steps forget at the reference's pace per
/// fraction of the run: `0.95^(20000 / iterations)`. The grid is updated every `update_every`
/// steps in both, so a run ten times shorter has a tenth of the updates, and each must decay as
/// much as ten of the reference's (`fast`, 2000 steps: 0.599).
///
/// Why: with the unscaled 0.95 a cell whose alpha once reached 1 needs 135 visits to fall below
/// the 0.001 threshold, at most one per update, so at least 2160 steps, longer than the whole
/// `fast` run; empty space a short run once marked (the hole of a holed shape) stays occupied to
/// the end and takes samples where no surface is. Scaled, holes open more often (measured:
/// docs/recipe.md).
pub fn decay_for_run(iterations: u64) -> f32 {
    rescale_decay(REFERENCE_DECAY, REFERENCE_STEPS, iterations)
}

/// The decay per update that forgets over a run of `to_steps` as much as `decay` does over
/// `from_steps` (same update interval): `decay^(from_steps / to_steps)`, in f64. Used by
/// [`decay_for_run`] and by `study pareto`'s shortened runs.
pub fn rescale_decay(decay: f32, from_steps: u64, to_steps: u64) -> f32 {
    let ratio = from_steps as f64 / to_steps.max(1) as f64;
    (decay as f64).powf(ratio) as f32
}

/// Settings of the occupancy grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OccupancyConfig {
    /// Use the grid at all (instant-nsr-pl `grid_prune: true`).
    pub enabled: bool,
    /// Cells per axis (128).
    pub resolution: usize,
    /// Decay per update of the running max (0.95, the reference's for 20 000 steps; presets
    /// shorter than that use [`decay_for_run`]). In `[0, 1]`.
    pub ema_decay: f32,
    /// Occupancy threshold (`grid_prune_occ_thre`, 0.001).
    pub threshold: f32,
    /// Steps during which every cell is evaluated at each update (256).
    pub warmup_steps: u64,
    /// Update period in steps (16).
    pub update_every: u64,
}

impl Default for OccupancyConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            resolution: 128,
            ema_decay: REFERENCE_DECAY,
            threshold: 0.001,
            warmup_steps: 256,
            update_every: 16,
        }
    }
}

/// The grid (`[res][res][res]`, x fastest).
#[derive(Debug, Clone, PartialEq)]
pub struct OccupancyGrid {
    pub resolution: usize,
    pub radius: f32,
    /// Running occupancy per cell, `[res³]`, index `x + res·(y + res·z)`.
    pub occ: Vec<f32>,
    /// Occupied flags, `[res³]`.
    pub binary: Vec<bool>,
}

impl OccupancyGrid {
    /// A grid over `[-radius, radius]³` with every cell occupied and `occ = 0`.
    pub fn new(resolution: usize, radius: f32) -> Self {
        let n = resolution.pow(3);
        Self {
            resolution,
            radius,
            occ: vec![0.0; n],
            binary: vec![true; n],
        }
    }

    pub fn n_cells(&self) -> usize {
        self.occ.len()
    }

    /// Cell index of a point; points outside are clamped to the border cells.
    #[inline]
    pub fn cell_of(&self, p: [f32; 3]) -> usize {
        let res = self.resolution;
        let mut idx = [0usize; 3];
        for k in 0..3 {
            let u = (p[k] + self.radius) / (2.0 * self.radius) * res as f32;
            idx[k] = if u.is_nan() || u < 0.0 {
                0
            } else {
                (u as usize).min(res - 1)
            };
        }
        idx[0] + res * (idx[1] + res * idx[2])
    }

    #[inline]
    pub fn is_occupied(&self, p: [f32; 3]) -> bool {
        self.binary[self.cell_of(p)]
    }

    /// Fraction of occupied cells.
    pub fn occupied_fraction(&self) -> f32 {
        self.binary.iter().filter(|&&b| b).count() as f32 / self.n_cells().max(1) as f32
    }

    /// Cells and jittered points to evaluate at `step`, or `None` if `step` is not an update step.
    pub fn plan_update(
        &self,
        cfg: &OccupancyConfig,
        step: u64,
        seed: u64,
    ) -> Option<(Vec<usize>, Vec<[f32; 3]>)> {
        if !step.is_multiple_of(cfg.update_every.max(1)) {
            return None;
        }
        let mut rng = Pcg64Mcg::seed_from_u64(seed ^ step.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        let n = self.n_cells();
        let cells: Vec<usize> = if step < cfg.warmup_steps {
            (0..n).collect()
        } else {
            let q = n / 4;
            let mut c: Vec<usize> = (0..q).map(|_| rng.random_range(0..n)).collect();
            let occupied: Vec<usize> = (0..n).filter(|&i| self.binary[i]).collect();
            if occupied.len() <= q {
                c.extend_from_slice(&occupied);
            } else {
                c.extend((0..q).map(|_| occupied[rng.random_range(0..occupied.len())]));
            }
            c
        };
        let res = self.resolution;
        let cell = 2.0 * self.radius / res as f32;
        let pts = cells
            .iter()
            .map(|&i| {
                let (x, y, z) = (i % res, (i / res) % res, i / (res * res));
                let j: [f32; 3] = [rng.random(), rng.random(), rng.random()];
                [
                    -self.radius + (x as f32 + j[0]) * cell,
                    -self.radius + (y as f32 + j[1]) * cell,
                    -self.radius + (z as f32 + j[2]) * cell,
                ]
            })
            .collect();
        Some((cells, pts))
    }

    /// Applies evaluated occupancies (`alpha[j]` for `cells[j]`): new values are computed from the
    /// old ones first and then written in order, so repeated cells behave like the reference's
    /// indexed assignment (the last write wins) and the result is deterministic.
    pub fn apply_update(&mut self, cfg: &OccupancyConfig, cells: &[usize], alpha: &[f32]) {
        let new: Vec<f32> = cells
            .iter()
            .zip(alpha)
            .map(|(&c, &a)| {
                let a = if a.is_nan() { 1.0 } else { a };
                (self.occ[c] * cfg.ema_decay).max(a)
            })
            .collect();
        for (&c, v) in cells.iter().zip(new) {
            self.occ[c] = v;
        }
        let mean = self.occ.iter().map(|&v| v as f64).sum::<f64>() / self.n_cells().max(1) as f64;
        let thr = (mean as f32).min(cfg.threshold);
        for (b, &o) in self.binary.iter_mut().zip(&self.occ) {
            *b = o > thr;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn update_rule_follows_reference() {
        let cfg = OccupancyConfig {
            resolution: 4,
            ..Default::default()
        };
        let mut g = OccupancyGrid::new(4, 1.0);
        assert!(g.plan_update(&cfg, 5, 1).is_none(), "only every 16 steps");
        let (cells, pts) = g.plan_update(&cfg, 0, 1).unwrap();
        assert_eq!(cells.len(), 64, "warm-up evaluates every cell");
        for (&c, p) in cells.iter().zip(&pts) {
            assert_eq!(g.cell_of(*p), c, "jittered point stays in its cell");
        }
        // Occupy only cell 0.
        let alpha: Vec<f32> = cells
            .iter()
            .map(|&c| if c == 0 { 0.5 } else { 0.0 })
            .collect();
        g.apply_update(&cfg, &cells, &alpha);
        assert!(g.binary[0] && g.binary.iter().filter(|&&b| b).count() == 1);
        // Decay: 0.5·0.95 beats a new 0.1.
        g.apply_update(&cfg, &[0], &[0.1]);
        assert!((g.occ[0] - 0.475).abs() < 1e-7);
        // After warm-up: a quarter uniform plus the occupied cells.
        let (cells, _) = g.plan_update(&cfg, 256, 1).unwrap();
        assert_eq!(cells.len(), 16 + 1);
        assert_eq!(*cells.last().unwrap(), 0);
    }

    #[test]
    fn box_edge_points_map_to_border_cells() {
        let g = OccupancyGrid::new(8, 1.0);
        assert_eq!(g.cell_of([1.0, 1.0, 1.0]), 511);
        assert_eq!(g.cell_of([-1.0, -1.0, -1.0]), 0);
        assert_eq!(g.cell_of([f32::NAN, 5.0, -5.0]), 7 * 8);
    }

    /// The scaled decay forgets at the same pace per fraction of the run: an occupied cell (occ 1)
    /// visited at every update with alpha 0 is unmarked after the same share of the run's updates,
    /// whatever the run's length; the reference's own length gives the reference's 0.95.
    #[test]
    fn run_scaled_decay_forgets_at_the_same_fraction_of_the_run() {
        assert_eq!(decay_for_run(REFERENCE_STEPS), REFERENCE_DECAY);
        assert!((decay_for_run(2000) - 0.95f32.powi(10)).abs() < 1e-6);
        let unmarked_after = |iterations: u64| {
            let cfg = OccupancyConfig {
                resolution: 2,
                ema_decay: decay_for_run(iterations),
                ..Default::default()
            };
            let mut g = OccupancyGrid::new(2, 1.0);
            let all: Vec<usize> = (0..8).collect();
            // Every cell at 1, so the mean keeps the threshold at 0.001.
            g.apply_update(&cfg, &all, &[1.0; 8]);
            let updates = iterations / cfg.update_every;
            let n = (1..=updates)
                .find(|_| {
                    g.apply_update(&cfg, &[0], &[0.0]);
                    !g.binary[0]
                })
                .expect("the cell is forgotten within the run");
            n as f64 / updates as f64
        };
        let reference = unmarked_after(REFERENCE_STEPS);
        assert!((reference - 135.0 / 1250.0).abs() < 1e-9, "{reference}");
        for iterations in [1000, 2000, 8000] {
            let share = unmarked_after(iterations);
            // One update of slack: the shorter run counts in coarser steps.
            let slack = 16.0 / iterations as f64;
            assert!(
                (share - reference).abs() <= slack,
                "{iterations} steps: forgotten after {share:.4} of the run, reference {reference:.4}"
            );
        }
        // The unscaled decay at 2000 steps never forgets within the run.
        let cfg = OccupancyConfig {
            resolution: 2,
            ..Default::default()
        };
        let mut g = OccupancyGrid::new(2, 1.0);
        g.apply_update(&cfg, &(0..8).collect::<Vec<_>>(), &[1.0; 8]);
        for _ in 0..2000 / 16 {
            g.apply_update(&cfg, &[0], &[0.0]);
        }
        assert!(g.binary[0], "0.95 over 125 updates leaves {}", g.occ[0]);
    }
}
