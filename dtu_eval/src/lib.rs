//! The DTU MVS Chamfer protocol (jzhangbs/DTUeval-python `eval.py`, which follows DTU's MATLAB
//! code): accuracy (mesh → ground truth), completeness (ground truth → mesh), their mean and sum.
//! It knows nothing of NeuS and scores any mesh given in DTU world coordinates (mm).
//!
//! Modules in data-flow order: [`ply`] and [`gt`] read the inputs; [`sample`] samples the mesh
//! surface; [`downsample`] shuffles and thins it; [`nn`] answers nearest-neighbour queries on a
//! k-d tree, and [`boxtree`] the distances below the outlier cut on a tree of tight boxes;
//! [`protocol`] chains DTU's stages ([`plain`] is the mask-free variant); [`report`]
//! holds the figures; [`vis`] writes error-coloured clouds; [`cli`] is the shared command line;
//! [`atomic`] is the one atomic file writer of the workspace.
//!
//! ```no_run
//! use dtu_eval::protocol::{evaluate_mesh, GroundTruth};
//! use dtu_eval::report::DtuParams;
//! let gt = GroundTruth::load("data/SampleSet/MVS Data".as_ref(), 24)?;
//! let mesh = dtu_eval::ply::read_mesh("mesh_world_mm.ply".as_ref())?;
//! let e = evaluate_mesh(&mesh, &gt, &DtuParams::default(), 0)?;
//! println!("acc {:.3} comp {:.3} chamfer {:.3}", e.mean_d2s, e.mean_s2d, e.chamfer_sum());
//! # Ok::<(), dtu_eval::EvalError>(())
//! ```

pub mod atomic;
pub mod boxtree;
pub mod cli;
pub mod downsample;
pub mod error;
pub mod gt;
pub mod mesh;
pub mod nn;
pub mod plain;
pub mod ply;
pub mod protocol;
pub mod report;
pub mod sample;
pub mod vis;

pub use error::EvalError;
pub use mesh::{MeshError, TriMesh};
