//! Training: for now the optimiser ([`adam`]: AdamW with per-group learning rates and a NaN
//! guard). The training loop, schedules and checkpoints land with a later issue.

pub mod adam;

pub use adam::{lr_factor, AdamW, AdamWConfig, OptimError};
