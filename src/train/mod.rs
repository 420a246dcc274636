//! Training: the optimiser ([`adam`]: AdamW with per-group learning rates and a NaN guard),
//! step-dependent schedules, training rays, checkpoints, the training loop and image metrics.

pub mod adam;
pub mod checkpoint;
pub mod data;
pub mod metrics;
pub mod schedule;
pub mod trainer;

pub use adam::{AdamW, AdamWConfig, OptimError};
pub use checkpoint::TrainState;
pub use data::{Batch, TrainData};
pub use trainer::{StepReport, TrainConfig, TrainError, Trainer};
