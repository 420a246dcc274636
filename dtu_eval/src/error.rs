//! The evaluation's error type. Every variant names the file, stage or value at fault and, where
//! the cause is usually a mistake upstream, says what to check. Underlying causes are chained
//! through `source()`, not repeated in the message: print errors with their chain
//! ([`error_chain`], or anyhow's `{:#}`).

use crate::gt::GtError;
use crate::mesh::MeshError;
use crate::nn::TreeError;
use crate::ply::PlyError;
use std::path::PathBuf;

/// Errors of the evaluation (DTU protocol and plain mode).
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A PLY file could not be read or written.
    #[error(transparent)]
    Ply(#[from] PlyError),
    /// A ground-truth `.mat` file could not be read.
    #[error(transparent)]
    Gt(#[from] GtError),
    /// Ground-truth files are missing under the root.
    #[error(
        "DTU ground truth for scan {scan} is incomplete under {root}: missing {}. Expected DTU's \
         'SampleSet/MVS Data' layout: Points/stl/stl{scan:03}_total.ply, \
         ObsMask/ObsMask{scan}_10.mat, ObsMask/Plane{scan}.mat",
        .missing.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
    )]
    MissingGt {
        root: PathBuf,
        scan: u32,
        missing: Vec<PathBuf>,
    },
    /// The mesh (or point cloud) is unusable.
    #[error("{what} is not a usable mesh")]
    BadMesh {
        what: String,
        #[source]
        source: MeshError,
    },
    /// The mesh or point cloud has no vertices.
    #[error("{what} has no vertices: there is nothing to evaluate")]
    EmptyMesh { what: String },
    /// Sampling would produce more points than allowed.
    #[error(
        "{what}: sampling at {density} mm would produce up to {bound} points (limit {limit}); \
         the mesh is probably in the wrong unit (DTU meshes are in mm, spanning a few hundred mm)"
    )]
    TooManySamples {
        what: String,
        density: f64,
        bound: u64,
        limit: u64,
    },
    /// A k-d tree could not be built over a point set.
    #[error("cannot build a k-d tree over the {what}")]
    Tree {
        what: String,
        #[source]
        source: TreeError,
    },
    /// (Almost) no mesh point lies in the observation box.
    #[error("{}", outside_box_message(.in_box, .total, .mesh_min, .mesh_max, .box_min, .box_max))]
    OutsideBox {
        in_box: usize,
        total: usize,
        mesh_min: [f32; 3],
        mesh_max: [f32; 3],
        box_min: [f32; 3],
        box_max: [f32; 3],
    },
    /// A filtering stage left no point.
    #[error("{stage}: no point left ({detail})")]
    EmptyStage { stage: &'static str, detail: String },
    /// Every distance of one direction is at or beyond the outlier cut.
    #[error(
        "{direction}: none of the {n} distances is below max_dist = {max_dist} mm (smallest \
         {min:.3} mm), so the mean is undefined; the mesh and the reference do not overlap"
    )]
    NoneBelowMaxDist {
        direction: &'static str,
        n: usize,
        max_dist: f64,
        min: f64,
    },
    /// A parameter is out of its domain.
    #[error("invalid {name} = {value}: {why}")]
    BadParam {
        name: &'static str,
        value: f64,
        why: &'static str,
    },
    /// The command-line arguments do not describe one evaluation.
    #[error("{0}")]
    Usage(String),
    /// An output file could not be written.
    #[error("cannot write {path}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// Whether a mesh with these bounds looks like it is still in the normalised space of NeuS-style
/// training (inside a sphere of radius ~1), or is tiny next to the observation box.
pub fn looks_normalised(
    mesh_min: [f32; 3],
    mesh_max: [f32; 3],
    box_min: [f32; 3],
    box_max: [f32; 3],
) -> bool {
    let reach = mesh_min
        .iter()
        .chain(&mesh_max)
        .fold(0.0f32, |m, c| m.max(c.abs()));
    let diag = |a: [f32; 3], b: [f32; 3]| {
        (0..3)
            .map(|k| ((b[k] - a[k]) as f64).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    reach <= 2.0 || diag(mesh_min, mesh_max) < 0.05 * diag(box_min, box_max)
}

fn outside_box_message(
    in_box: &usize,
    total: &usize,
    mesh_min: &[f32; 3],
    mesh_max: &[f32; 3],
    box_min: &[f32; 3],
    box_max: &[f32; 3],
) -> String {
    let mut m = format!(
        "only {in_box} of {total} mesh points lie in the observation box (ObsMask BB with its \
         patch margin) [{box_min:?} .. {box_max:?}] mm; the mesh spans [{mesh_min:?} .. \
         {mesh_max:?}]. "
    );
    if looks_normalised(*mesh_min, *mesh_max, *box_min, *box_max) {
        m.push_str(
            "The mesh is most likely still in the normalised (unit-sphere) space the network \
             trains in: map it to world mm with the scene's scale_mat (X_world = s·X_norm + c, \
             `scale_mat_0` in cameras_sphere.npz; TriMesh::scale_translate) before evaluating.",
        );
    } else {
        m.push_str(
            "Check that the mesh and the ground truth belong to the same scan and are in the \
             same frame (DTU world coordinates, mm).",
        );
    }
    m
}

/// `err` and its `source()` chain, joined with ": " (as anyhow's `{:#}` prints), each cause once:
/// a cause whose text the message already contains (an error that shows its source in its own
/// message and also returns it from `source()`) is not repeated.
pub fn error_chain(err: &dyn std::error::Error) -> String {
    let mut s = err.to_string();
    let mut cur = err.source();
    while let Some(e) = cur {
        let text = e.to_string();
        if !s.contains(&text) {
            s.push_str(": ");
            s.push_str(&text);
        }
        cur = e.source();
    }
    s
}
