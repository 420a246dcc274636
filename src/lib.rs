//! neus-aug: NeuS surface reconstruction on the CPU with colour-only image augmentations.
//!
//! Modules in data-flow order (../shared/DESIGN.md §1): [`scene`] (DTU-layout I/O, cameras, rays,
//! the simulator; [`import`] brings COLMAP and transforms.json data into that layout) →
//! [`augment`] → [`field`] → [`render`] → [`train`] → [`mesh`] → evaluation (the
//! `dtu_eval` crate). Nothing low in the stack knows about what sits above it.

pub mod augment;
pub mod field;
pub mod import;
pub mod mesh;
pub mod reconstruct;
pub mod render;
pub mod scene;
pub mod study;
pub mod train;
