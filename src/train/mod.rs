//! Training: the optimiser ([`adam`]: AdamW with per-group learning rates and a NaN guard),
//! step-dependent schedules, image metrics, checkpoints and the training loop.

pub mod adam;
pub mod metrics;
pub mod schedule;

pub use adam::{lr_factor, AdamW, AdamWConfig, OptimError};
