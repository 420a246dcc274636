//! Step-dependent values: the reference's four-number schedule and the learning-rate schedule.
//!
//! Every function takes the step explicitly; nothing here holds mutable state, so a resumed run
//! sees exactly the values an uninterrupted run would.

use serde::{Deserialize, Serialize};

/// A value that may change with the training step, as instant-nsr-pl's `C()` helper reads
/// config values (`systems/base.py`): either a constant, or `[start_step, start, end, end_step]`,
/// linear from `start` at `start_step` to `end` at `end_step`, clamped outside. In TOML: `0.1`
/// or `[0, 0.1, 0.0, 5000]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Schedule {
    /// The same value at every step.
    Constant(f64),
    /// `[start_step, start_value, end_value, end_step]`.
    Linear(u64, f64, f64, u64),
}

impl Schedule {
    /// The value at `step`.
    pub fn at(&self, step: u64) -> f64 {
        match *self {
            Schedule::Constant(v) => v,
            Schedule::Linear(s0, v0, v1, s1) => {
                if s1 <= s0 {
                    return if step >= s1 { v1 } else { v0 };
                }
                let t = ((step as f64 - s0 as f64) / (s1 - s0) as f64).clamp(0.0, 1.0);
                v0 + (v1 - v0) * t
            }
        }
    }

    /// The smallest and largest value the schedule takes.
    pub fn bounds(&self) -> (f64, f64) {
        match *self {
            Schedule::Constant(v) => (v, v),
            Schedule::Linear(_, a, b, _) => (a.min(b), a.max(b)),
        }
    }
}

/// The learning-rate multiplier: linear warm-up from `warmup_start` to 1 over `warmup_steps`,
/// constant until `constant_steps`, then exponential decay reaching `final_factor` at
/// `max_steps` (instant-nsr-pl `configs/neus-dtu-wmask.yaml`: ConstantLR for 5000 steps then
/// ExponentialLR with `gamma = 0.1^(1/(max_steps - 5000))`; the warm-up follows NeuS's
/// `warm_up_end`, and is off (0 steps) in the reference configuration).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LrSchedule {
    /// Steps of linear warm-up (0 = none).
    pub warmup_steps: u64,
    /// Multiplier at step 0 when warming up.
    pub warmup_start: f64,
    /// Last step of the constant phase (counted from 0, warm-up included).
    pub constant_steps: u64,
    /// The step at which the decay reaches `final_factor`.
    pub max_steps: u64,
    /// Multiplier at `max_steps` (0.1 in the reference).
    pub final_factor: f64,
}

impl LrSchedule {
    /// The multiplier of the base learning rate at `step`.
    pub fn factor(&self, step: u64) -> f64 {
        let warm = if step < self.warmup_steps {
            self.warmup_start + (1.0 - self.warmup_start) * step as f64 / self.warmup_steps as f64
        } else {
            1.0
        };
        let decay = if step <= self.constant_steps || self.max_steps <= self.constant_steps {
            1.0
        } else {
            let span = (self.max_steps - self.constant_steps) as f64;
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
    fn four_number_schedule_matches_the_reference_rule() {
        let s = Schedule::Linear(100, 1.0, 3.0, 300);
        assert_eq!(s.at(0), 1.0);
        assert_eq!(s.at(100), 1.0);
        assert_eq!(s.at(200), 2.0);
        assert_eq!(s.at(300), 3.0);
        assert_eq!(s.at(10_000), 3.0);
        assert_eq!(Schedule::Constant(0.1).at(7), 0.1);
        assert_eq!(Schedule::Linear(5, 1.0, 2.0, 5).at(4), 1.0);
        assert_eq!(Schedule::Linear(5, 1.0, 2.0, 5).at(5), 2.0);
    }

    #[test]
    fn schedules_parse_from_toml_as_number_or_quadruple() {
        #[derive(Deserialize)]
        struct T {
            a: Schedule,
            b: Schedule,
        }
        let t: T = toml::from_str("a = 0.5\nb = [0, 1.0, 0.0, 10]").unwrap();
        assert_eq!(t.a, Schedule::Constant(0.5));
        assert_eq!(t.b, Schedule::Linear(0, 1.0, 0.0, 10));
    }

    #[test]
    fn lr_is_constant_then_decays_to_the_final_factor() {
        let s = LrSchedule {
            warmup_steps: 0,
            warmup_start: 0.0,
            constant_steps: 5000,
            max_steps: 20000,
            final_factor: 0.1,
        };
        assert_eq!(s.factor(0), 1.0);
        assert_eq!(s.factor(5000), 1.0);
        assert!((s.factor(20000) - 0.1).abs() < 1e-12);
        // Exponential: halfway through the decay the factor is sqrt(0.1).
        assert!((s.factor(12500) - 0.1f64.sqrt()).abs() < 1e-12);
        let w = LrSchedule {
            warmup_steps: 10,
            warmup_start: 0.0,
            ..s
        };
        assert_eq!(w.factor(0), 0.0);
        assert!((w.factor(5) - 0.5).abs() < 1e-12);
        assert_eq!(w.factor(10), 1.0);
    }
}
