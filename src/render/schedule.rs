//! Everything in the model's configuration that changes with the training step, in one place:
//! the four-number [`Scheduled`] value (loss weights), and the values at one step
//! ([`Schedule`]: cos anneal, active hash-grid levels, [`LossWeights`]) resolved from a
//! [`ModelConfig`] by [`ModelConfig::schedule`]. The optimiser's learning-rate multiplier is the
//! trainer's own (`train::schedule::LrSchedule`). Nothing here holds state: the step is
//! passed explicitly, so a resumed run sees exactly the values an uninterrupted run would.

use super::config::{LossConfig, ModelConfig};
pub use super::scheduled::Scheduled;

/// The loss weights at one step (from [`LossConfig`] through [`ModelConfig::schedule`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LossWeights {
    pub rgb_l1: f32,
    pub rgb_mse: f32,
    pub eikonal: f32,
    pub mask: f32,
    pub curvature: f32,
}

impl LossConfig {
    /// The weights at `step`.
    pub fn at(&self, step: u64) -> LossWeights {
        LossWeights {
            rgb_l1: self.rgb_l1.at(step) as f32,
            rgb_mse: self.rgb_mse.at(step) as f32,
            eikonal: self.eikonal.at(step) as f32,
            mask: self.mask.at(step) as f32,
            curvature: self.curvature.at(step) as f32,
        }
    }
}

/// Values that change with the training step, passed explicitly (no hidden schedule state).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Schedule {
    /// Cos anneal ratio in `[0,1]` (`min(1, step/cos_anneal_end)`).
    pub cos_anneal: f32,
    /// Active hash-grid levels (progressive mask).
    pub active_levels: usize,
    /// Loss weights.
    pub loss: LossWeights,
    /// Scale of the colour network's view-direction terms (`RenderConfig::view_dependence`).
    pub view_dependence: f32,
}

impl ModelConfig {
    /// The schedule of instant-nsr-pl at `step` (`NeuSModel.update_step`).
    pub fn schedule(&self, step: u64) -> Schedule {
        let end = self.render.cos_anneal_end;
        Schedule {
            cos_anneal: if end == 0 {
                1.0
            } else {
                (step as f64 / end as f64).min(1.0) as f32
            },
            active_levels: self.field.hash_grid.active_levels(step),
            loss: self.loss.at(step),
            view_dependence: self.render.view_dependence.at(step) as f32,
        }
    }

    /// The schedule used for inference: annealed, all scheduled levels at `step`.
    pub fn inference_schedule(&self, step: u64) -> Schedule {
        Schedule {
            cos_anneal: 1.0,
            active_levels: self.field.hash_grid.active_levels(step),
            loss: self.loss.at(step),
            view_dependence: self.render.view_dependence.at(step) as f32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[test]
    fn four_number_schedule_matches_the_reference_rule() {
        let s = Scheduled::Linear(100, 1.0, 3.0, 300);
        assert_eq!(s.at(0), 1.0);
        assert_eq!(s.at(100), 1.0);
        assert_eq!(s.at(200), 2.0);
        assert_eq!(s.at(300), 3.0);
        assert_eq!(s.at(10_000), 3.0);
        assert_eq!(Scheduled::Constant(0.1).at(7), 0.1);
        assert_eq!(Scheduled::Linear(5, 1.0, 2.0, 5).at(4), 1.0);
        assert_eq!(Scheduled::Linear(5, 1.0, 2.0, 5).at(5), 2.0);
    }

    #[test]
    fn schedules_parse_from_toml_as_number_or_quadruple() {
        #[derive(Deserialize)]
        struct T {
            a: Scheduled,
            b: Scheduled,
        }
        let t: T = toml::from_str("a = 0.5\nb = [0, 1.0, 0.0, 10]").unwrap();
        assert_eq!(t.a, Scheduled::Constant(0.5));
        assert_eq!(t.b, Scheduled::Linear(0, 1.0, 0.0, 10));
        let e = toml::from_str::<T>("a = 0.5\nb = [0, 1.0]")
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("start_step, start_value, end_value, end_step"),
            "{e}"
        );
        assert_eq!(t.b.to_string(), "[0, 1, 0, 10]");
        assert_eq!(t.a.to_string(), "0.5");
    }

    #[test]
    fn check_rejects_negative_non_finite_and_reversed_schedules() {
        assert!(Scheduled::Constant(0.0).check().is_ok());
        assert!(Scheduled::Linear(5, 1.0, 2.0, 5).check().is_ok());
        assert_eq!(Scheduled::Constant(-0.1).check(), Err("must be ≥ 0"));
        assert_eq!(
            Scheduled::Linear(0, 0.1, f64::NAN, 10).check(),
            Err("values must be finite")
        );
        assert_eq!(
            Scheduled::Linear(10, 0.1, 0.0, 5).check(),
            Err("end_step must not come before start_step")
        );
    }
}
