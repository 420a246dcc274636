//! Two-pass mesh extraction (instant-nsr-pl `models/geometry.py`, `BaseImplicitGeometry.isosurface`)
//! and the mapping of meshes from normalised space to world millimetres.
//!
//! Pass 1 runs marching cubes over the whole box (instant-nsr-pl: `[-radius, radius]^3`). Pass 2
//! runs again over the coarse mesh's bounds, padded on each side by 10 % of their extent and
//! clamped to the box, so the same resolution spends its cells where the surface is. Deviation
//! from the reference: the padding is at least one coarse cell, so the refined box strictly
//! contains the coarse mesh and never collapses (a flat coarse mesh would give `min == max`).

use super::{marching_cubes, GridSpec, McError, McOptions, TriMesh};
use crate::scene::Normalization;

/// Settings of [`extract_two_pass`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwoPassOptions {
    /// Lower corner of the coarse box (normalised space).
    pub min: [f32; 3],
    /// Upper corner of the coarse box (normalised space).
    pub max: [f32; 3],
    /// Points per axis of the coarse pass.
    pub coarse_res: usize,
    /// Points per axis of the refined pass.
    pub fine_res: usize,
    /// Padding of the refined box, as a fraction of the coarse mesh's extent on each axis
    /// (instant-nsr-pl: 0.1).
    pub pad_fraction: f32,
    /// Iso level, SDF batch and slab sizes of both passes.
    pub mc: McOptions,
}

impl Default for TwoPassOptions {
    /// instant-nsr-pl's DTU setting: the box `[-1, 1]^3` (radius 1), 512 points per axis in both
    /// passes (`isosurface.resolution`), iso 0.
    fn default() -> Self {
        Self {
            min: [-1.0; 3],
            max: [1.0; 3],
            coarse_res: 512,
            fine_res: 512,
            pad_fraction: 0.1,
            mc: McOptions::default(),
        }
    }
}

/// Output of [`extract_two_pass`].
#[derive(Clone, Debug, PartialEq)]
pub struct TwoPass {
    /// The refined mesh (or the empty coarse mesh), normalised space.
    pub mesh: TriMesh,
    /// Grid of the coarse pass.
    pub coarse_grid: GridSpec,
    /// Faces of the coarse mesh.
    pub coarse_faces: usize,
    /// Grid of the refined pass; `None` when the coarse mesh was empty.
    pub fine_grid: Option<GridSpec>,
}

/// The refined box for a coarse mesh: its bounds padded by `pad_fraction` of their extent (at
/// least one coarse cell) and clamped to the coarse box. `None` for an empty mesh.
pub fn refined_grid(
    coarse: &TriMesh,
    coarse_grid: &GridSpec,
    opts: &TwoPassOptions,
) -> Option<GridSpec> {
    let (lo, hi) = coarse.bounds()?;
    let cell = coarse_grid.cell_size();
    let mut min = [0.0f32; 3];
    let mut max = [0.0f32; 3];
    for a in 0..3 {
        let pad = (opts.pad_fraction * (hi[a] - lo[a])).max(cell[a]);
        min[a] = (lo[a] - pad).max(coarse_grid.min[a]);
        max[a] = (hi[a] + pad).min(coarse_grid.max[a]);
    }
    Some(GridSpec {
        min,
        max,
        res: [opts.fine_res; 3],
    })
}

/// Coarse pass over the box, refined pass over the coarse mesh's padded bounds (module docs).
/// `sdf` takes batches of normalised-space points, negative inside. An SDF that never crosses the
/// iso level gives an empty mesh.
pub fn extract_two_pass<F>(sdf: &F, opts: &TwoPassOptions) -> Result<TwoPass, McError>
where
    F: Fn(&[[f32; 3]]) -> Vec<f32> + Sync,
{
    let coarse_grid = GridSpec::cube(opts.min, opts.max, opts.coarse_res);
    let coarse = marching_cubes(sdf, &coarse_grid, &opts.mc)?;
    let coarse_faces = coarse.faces.len();
    let Some(fine_grid) = refined_grid(&coarse, &coarse_grid, opts) else {
        return Ok(TwoPass {
            mesh: coarse,
            coarse_grid,
            coarse_faces,
            fine_grid: None,
        });
    };
    drop(coarse);
    let mesh = marching_cubes(sdf, &fine_grid, &opts.mc)?;
    Ok(TwoPass {
        mesh,
        coarse_grid,
        coarse_faces,
        fine_grid: Some(fine_grid),
    })
}

/// Maps a mesh from normalised space to world millimetres: `X_world = s·X_norm + c` (the scene's
/// `scale_mat`, Totoro97/NeuS `models/dataset.py`), computed in f64. `s > 0`, so the orientation is
/// kept.
pub fn to_world(mesh: &mut TriMesh, norm: &Normalization) {
    for v in &mut mesh.vertices {
        for (x, c) in v.iter_mut().zip(norm.center) {
            *x = (norm.scale * *x as f64 + c) as f32;
        }
    }
}
