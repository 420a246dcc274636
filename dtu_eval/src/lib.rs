//! The DTU MVS Chamfer protocol (jzhangbs/DTUeval-python `eval.py`, which follows DTU's MATLAB
//! code): accuracy (mesh → ground truth), completeness (ground truth → mesh), their mean and sum.
//! It knows nothing of NeuS and scores any mesh given in DTU world coordinates (mm).

pub mod gt;
pub mod mesh;
pub mod ply;

pub use mesh::{MeshError, TriMesh};
