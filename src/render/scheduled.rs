//! A configuration value that may change with the training step ([`Scheduled`]).

use serde::{Deserialize, Serialize};

/// A value that may change with the training step, as instant-nsr-pl's `C()` helper reads
/// config values (`systems/base.py`): either a constant, or `[start_step, start, end, end_step]`,
/// linear from `start` at `start_step` to `end` at `end_step`, clamped outside. In TOML: `0.1`
/// or `[0, 0.1, 0.0, 5000]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(
    untagged,
    expecting = "a number, or [start_step, start_value, end_value, end_step] with integer steps"
)]
pub enum Scheduled {
    /// The same value at every step.
    Constant(f64),
    /// `[start_step, start_value, end_value, end_step]`. `end_step == start_step` switches from
    /// `start_value` to `end_value` at that step; `end_step < start_step` is invalid
    /// ([`Scheduled::check`]).
    Linear(u64, f64, f64, u64),
}

impl std::fmt::Display for Scheduled {
    /// The TOML spelling: `0.1` or `[0, 0.1, 0, 5000]`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Scheduled::Constant(v) => write!(f, "{v}"),
            Scheduled::Linear(s0, v0, v1, s1) => write!(f, "[{s0}, {v0}, {v1}, {s1}]"),
        }
    }
}

impl Scheduled {
    /// The value at `step`.
    pub fn at(&self, step: u64) -> f64 {
        match *self {
            Scheduled::Constant(v) => v,
            Scheduled::Linear(s0, v0, v1, s1) => {
                if s1 <= s0 {
                    return if step >= s1 { v1 } else { v0 };
                }
                let t = ((step as f64 - s0 as f64) / (s1 - s0) as f64).clamp(0.0, 1.0);
                v0 + (v1 - v0) * t
            }
        }
    }

    /// Checks that every value is finite and ≥ 0 (as loss weights must be) and that the steps are
    /// in order; the error says which.
    pub fn check(&self) -> Result<(), &'static str> {
        let (a, b) = match *self {
            Scheduled::Constant(v) => (v, v),
            Scheduled::Linear(_, a, b, _) => (a, b),
        };
        if !(a.is_finite() && b.is_finite()) {
            return Err("values must be finite");
        }
        if a.min(b) < 0.0 {
            return Err("must be ≥ 0");
        }
        if let Scheduled::Linear(s0, _, _, s1) = *self {
            if s1 < s0 {
                return Err("end_step must not come before start_step");
            }
        }
        Ok(())
    }
}

impl From<f64> for Scheduled {
    fn from(v: f64) -> Self {
        Scheduled::Constant(v)
    }
}
