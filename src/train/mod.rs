//! Training: the loss ([`loss`]: colour, mask and the regularisers' weights, behind the
//! renderer's `RayLoss` interface), the optimiser ([`adam`]: AdamW with per-group learning rates
//! and a NaN guard), the learning-rate schedule, training rays, checkpoints, the training loop
//! (with the dynamic ray count and error-map sampling, [`error_map`]), the depth prior
//! ([`depth`], on the stereo of `crate::mvs`, with its automatic switch [`depth_auto`]), the
//! visual-hull start ([`hull`]) and image metrics.

pub mod adam;
pub mod checkpoint;
pub mod data;
pub mod depth;
pub mod depth_auto;
pub mod error_map;
pub mod hull;
pub mod loss;
pub mod metrics;
pub mod pose;
pub mod pose_refine;
pub mod schedule;
pub mod trainer;

pub use adam::{AdamW, AdamWConfig, OptimError};
pub use checkpoint::TrainState;
pub use data::{Batch, TrainData};
pub use loss::{LossConfig, MaskBce, PixelLoss, StepOutput, StepSinks, Targets, TrainStep};
pub use trainer::{StepReport, TrainConfig, TrainError, Trainer};
