//! Training: optimiser, schedules, metrics, checkpoints and the training loop.

pub mod metrics;
pub mod schedule;
