//! Rendering a NeuS field: rays and box intersection ([`rays`]), the occupancy grid
//! ([`occupancy`]), the NeuS alpha ([`alpha`]), compositing ([`composite`]), the learned
//! background for training without masks ([`background`]), the model's
//! configuration ([`config`]) and its step-dependent values ([`schedule`]), and the model
//! ([`model`]: public API, shard orchestration and reduction) whose batched forward/backward runs
//! chunk by chunk, one function per phase (`step.rs`), on reused buffers (`workspace.rs`).
//! The loss enters through the [`ray_loss::RayLoss`] interface; its implementation lives in
//! `train::loss`, so nothing here knows about training.
//!
//! The renderer knows nothing about images or cameras: callers pass rays in the normalised space
//! (object inside the unit sphere), f32, origins `[n][3]` and unit directions `[n][3]`.

pub mod alpha;
pub mod background;
pub mod composite;
pub mod config;
mod error;
pub mod model;
mod neus;
pub mod occupancy;
pub mod ray_loss;
pub mod rays;
pub mod schedule;
pub mod scheduled;
mod sdf_fit;
mod step;
mod workspace;

pub use config::{
    BackgroundConfig, BackgroundKind, LossConfig, MaskBce, ModelConfig, RenderConfig,
};
pub use model::{
    mark_ray_grad, ray_grad, BackwardOutput, ModelError, NeusModel, PhaseTimes, RayBatch,
    RayGradCell, RenderOutput, RAY_GRAD_SKIP,
};
pub use occupancy::{OccupancyConfig, OccupancyGrid};
pub use ray_loss::{BatchCounts, RayLoss, SampleWeights};
pub use schedule::{LossWeights, Schedule, Scheduled};
