//! neus-aug: NeuS surface reconstruction on the CPU with colour-only image augmentations.
//!
//! Modules in layer order, each importing only from those before it: the `dtu_eval` crate (the DTU
//! Chamfer protocol; the ground floor) and [`util`] (shared helpers that import nothing) →
//! [`scene`] (DTU-layout I/O, cameras, rays) → [`augment`] (colour manipulations, degradations,
//! SIA/DIA) → [`field`] → [`render`] → [`mvs`] → [`train`] → [`mesh`] → [`export`] (coloured and
//! textured meshes, turntables) → [`sim`] (the simulator: uses `scene`,
//! `augment`, `mesh` and `dtu_eval`) → [`import`] (COLMAP and transforms.json data into the DTU
//! layout: uses `scene`) → [`reconstruct`] → [`study`] → the `neus-aug` binary's `cli`. Nothing low
//! in the stack knows about what sits above it.

pub mod augment;
pub mod export;
pub mod field;
pub mod import;
pub mod mesh;
pub mod mvs;
pub mod reconstruct;
pub mod render;
pub mod scene;
pub mod sim;
pub mod study;
pub mod train;
pub mod util;
