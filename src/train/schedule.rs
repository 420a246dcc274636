//! The optimiser's learning-rate multiplier over a run. The model's step-dependent values (loss
//! weights, cos anneal, active levels, the four-number [`Scheduled`](crate::render::Scheduled))
//! live in [`crate::render::schedule`].
//!
//! Every function takes the step explicitly; nothing here holds mutable state, so a resumed run
//! sees exactly the values an uninterrupted run would.

use serde::{Deserialize, Serialize};

/// The learning-rate multiplier: linear warm-up from `warmup_start` to 1 over `warmup_steps`,
/// constant until `constant_steps`, then exponential decay reaching `final_factor` at the last
/// step `max_steps` (the run's iteration count, passed to [`LrSchedule::factor`]) (instant-nsr-pl
/// `configs/neus-dtu-wmask.yaml`: ConstantLR for 5000 steps then
/// ExponentialLR with `gamma = 0.1^(1/(max_steps - 5000))`; the warm-up follows NeuS's
/// `warm_up_end`, and is off (0 steps) in the reference configuration).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LrSchedule {
    /// Steps of linear warm-up (0 = none).
    pub warmup_steps: u64,
    /// Multiplier at step 0 when warming up.
    pub warmup_start: f64,
    /// Last step of the constant phase (counted from 0, warm-up included).
    pub constant_steps: u64,
    /// Multiplier at `max_steps` (0.1 in the reference).
    pub final_factor: f64,
}

impl Default for LrSchedule {
    /// The reference: no warm-up, constant for 5000 steps, decay to 0.1×.
    fn default() -> Self {
        Self {
            warmup_steps: 0,
            warmup_start: 0.0,
            constant_steps: 5000,
            final_factor: 0.1,
        }
    }
}

impl LrSchedule {
    /// The multiplier of the base learning rate at `step` of a run of `max_steps` steps.
    pub fn factor(&self, step: u64, max_steps: u64) -> f64 {
        let warm = if step < self.warmup_steps {
            self.warmup_start + (1.0 - self.warmup_start) * step as f64 / self.warmup_steps as f64
        } else {
            1.0
        };
        let decay = if step <= self.constant_steps || max_steps <= self.constant_steps {
            1.0
        } else {
            let span = (max_steps - self.constant_steps) as f64;
            self.final_factor
                .powf((step - self.constant_steps) as f64 / span)
        };
        warm * decay
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lr_is_constant_then_decays_to_the_final_factor() {
        let s = LrSchedule {
            warmup_steps: 0,
            warmup_start: 0.0,
            constant_steps: 5000,
            final_factor: 0.1,
        };
        assert_eq!(s.factor(0, 20000), 1.0);
        assert_eq!(s.factor(5000, 20000), 1.0);
        assert!((s.factor(20000, 20000) - 0.1).abs() < 1e-12);
        // Exponential: halfway through the decay the factor is sqrt(0.1).
        assert!((s.factor(12500, 20000) - 0.1f64.sqrt()).abs() < 1e-12);
        let w = LrSchedule {
            warmup_steps: 10,
            warmup_start: 0.0,
            ..s
        };
        assert_eq!(w.factor(0, 20000), 0.0);
        assert!((w.factor(5, 20000) - 0.5).abs() < 1e-12);
        assert_eq!(w.factor(10, 20000), 1.0);
    }
}
