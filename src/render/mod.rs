//! Rendering a NeuS field: rays and box intersection ([`rays`]), the occupancy grid
//! ([`occupancy`]), the NeuS alpha ([`alpha`]), compositing ([`composite`]), and the batched
//! model forward/backward with the loss ([`model`]).
//!
//! The renderer knows nothing about images or cameras: callers pass rays in the normalised space
//! (object inside the unit sphere), f32, origins `[n][3]` and unit directions `[n][3]`.

pub mod alpha;
pub mod composite;
pub mod model;
pub mod occupancy;
pub mod rays;
pub mod scheduled;

pub use model::{
    LossConfig, LossWeights, MaskBce, ModelConfig, ModelError, NeusModel, PhaseTimes, RayBatch,
    RenderConfig, RenderOutput, Schedule, StepOutput, Targets,
};
pub use occupancy::{OccupancyConfig, OccupancyGrid};
pub use scheduled::Scheduled;
