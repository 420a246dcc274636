//! The DTU Chamfer protocol, stage by stage (jzhangbs/DTUeval-python `eval.py`, which follows DTU's
//! MATLAB evaluation code).
//!
//! 1. Sample the mesh ([`crate::sample`]): vertices plus `MeshSupSamp` samples at `density`.
//! 2. Shuffle (seeded) and greedy-downsample at radius `density` ([`crate::downsample`]).
//! 3. Observation filter ([`observation_filter`]): `data_in` = points inside the box `BB` grown
//!    by `patch` below and `2·patch` above; `data_in_obs` = those whose voxel is set in `ObsMask`.
//! 4. `d2s`: distance from each `data_in_obs` point to the nearest of **all** ground-truth points.
//! 5. `s2d`: distance from each ground-truth point above the plane to the nearest `data_in` point
//!    (box-filtered, not mask-filtered).
//! 6. `mean_d2s` = mean of `d2s < max_dist`, `mean_s2d` = mean of `s2d < max_dist` (strict),
//!    `overall` = their mean (DTUeval-python), `chamfer_sum` = their sum (the paper).
//!
//! Steps 4 and 5 search no farther than `max_dist` ([`crate::boxtree`]): a distance at or beyond
//! it, which step 6 leaves out anyway, is recorded as `+inf`, so a mesh far from the reference
//! costs little more than a close one, and the means are those of an unbounded search bit for
//! bit. [`DtuEvaluation::exact_outliers`] computes the left-out distances where they are wanted.
//!
//! Frames and units: everything is DTU world coordinates, millimetres. Coordinates are `f32`;
//! distances and means are `f64` (see [`crate::nn`]).

use crate::boxtree::BoxTree;
use crate::downsample::{radius_downsample, select, shuffle};
use crate::error::EvalError;
use crate::gt::{GtPaths, ObsMask, Plane};
use crate::mesh::{bounds, TriMesh};
use crate::report::{DtuCounts, DtuParams, StageTime, Stopwatch};
use crate::sample::{sample_count_bound, sample_mesh};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Default cap on the number of sampled points (about 4.8 GB of `f32` coordinates).
pub const DEFAULT_MAX_SAMPLES: u64 = 400_000_000;

/// Below this fraction of downsampled points inside the observation box, the mesh is taken to be
/// in the wrong place (or unit) and the evaluation stops with [`EvalError::OutsideBox`].
pub const MIN_IN_BOX_FRACTION: f64 = 0.01;

/// One scan's ground truth: points, observation mask and plane (world mm).
#[derive(Clone, Debug)]
pub struct GroundTruth {
    /// Structured-light reference points `[n][3]`.
    pub points: Vec<[f32; 3]>,
    /// Observation mask, its box and resolution.
    pub obs_mask: ObsMask,
    /// Ground plane; points with `[x, y, z, 1]·P > 0` are above it.
    pub plane: Plane,
}

impl GroundTruth {
    /// Loads scan `scan` under `root` (DTU's file names, [`GtPaths`]). Missing files are reported
    /// together, before anything is read.
    pub fn load(root: &Path, scan: u32) -> Result<Self, EvalError> {
        let paths = GtPaths::new(root, scan);
        let missing: Vec<PathBuf> = [&paths.points, &paths.obs_mask, &paths.plane]
            .into_iter()
            .filter(|p| !p.is_file())
            .cloned()
            .collect();
        if !missing.is_empty() {
            return Err(EvalError::MissingGt {
                root: root.into(),
                scan,
                missing,
            });
        }
        let obs_mask = ObsMask::read(&paths.obs_mask)?;
        let plane = Plane::read(&paths.plane)?;
        let points = crate::ply::read_points(&paths.points)?;
        Ok(Self {
            points,
            obs_mask,
            plane,
        })
    }
}

/// Checks the protocol's parameters.
pub fn check_params(p: &DtuParams) -> Result<(), EvalError> {
    check_positive("density", p.density)?;
    if !(p.patch_size.is_finite() && p.patch_size >= 0.0) {
        return Err(EvalError::BadParam {
            name: "patch_size",
            value: p.patch_size,
            why: "must be finite and >= 0 (mm)",
        });
    }
    if p.max_dist.is_nan() || p.max_dist <= 0.0 {
        return Err(EvalError::BadParam {
            name: "max_dist",
            value: p.max_dist,
            why: "must be > 0 (mm)",
        });
    }
    Ok(())
}

pub(crate) fn check_positive(name: &'static str, value: f64) -> Result<(), EvalError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(EvalError::BadParam {
            name,
            value,
            why: "must be finite and > 0",
        })
    }
}

/// Validates `mesh` (non-empty, finite, indices in range) and refuses sampling beyond
/// `max_samples` points. `what` names the mesh in errors.
pub fn check_mesh(
    mesh: &TriMesh,
    density: f64,
    max_samples: u64,
    what: &str,
) -> Result<(), EvalError> {
    if mesh.vertices.is_empty() {
        return Err(EvalError::EmptyMesh { what: what.into() });
    }
    mesh.validate().map_err(|source| EvalError::BadMesh {
        what: what.into(),
        source,
    })?;
    let bound = sample_count_bound(mesh, density);
    if bound > max_samples {
        return Err(EvalError::TooManySamples {
            what: what.into(),
            density,
            bound,
            limit: max_samples,
        });
    }
    Ok(())
}

/// Stages 1 and the shuffle of 2: the mesh's samples (vertices first) in seeded random order,
/// `[n][3]` world mm. Laps "sample" and "shuffle" on `sw`.
pub fn sample_and_shuffle(
    mesh: &TriMesh,
    density: f64,
    seed: u64,
    max_samples: u64,
    what: &str,
    sw: &mut Stopwatch,
) -> Result<Vec<[f32; 3]>, EvalError> {
    check_positive("density", density)?;
    check_mesh(mesh, density, max_samples, what)?;
    let mut points = sample_mesh(mesh, density);
    sw.lap("sample");
    shuffle(&mut points, seed);
    sw.lap("shuffle");
    Ok(points)
}

/// Stage 3: `(in_box, in_obs)` flags per point (`[n]` each; `in_obs` implies `in_box`).
///
/// As DTUeval-python: `BB` is cast to `f32`; the box bounds `BB0 − patch` and `BB1 + 2·patch`
/// are computed in `f32` (numpy: `float32` array with a Python float); a point is in the box when
/// `p >= BB0 − patch` and `p < BB1 + 2·patch` on all three axes. Its voxel is
/// `round_half_even((p − BB0) / Res)` computed in `f64` (`np.around` rounds half to even), and it
/// is observed when that voxel lies in the grid and its `ObsMask` flag is set (column-major).
pub fn observation_filter(
    points: &[[f32; 3]],
    mask: &ObsMask,
    patch: f64,
) -> (Vec<bool>, Vec<bool>) {
    let bb0 = mask.bb[0].map(|v| v as f32);
    let bb1 = mask.bb[1].map(|v| v as f32);
    let lo: [f32; 3] = std::array::from_fn(|k| bb0[k] - patch as f32);
    let hi: [f32; 3] = std::array::from_fn(|k| bb1[k] + (patch * 2.0) as f32);
    let flags: Vec<(bool, bool)> = points
        .par_iter()
        .with_min_len(4096)
        .map(|p| {
            let inside = (0..3).all(|k| p[k] >= lo[k] && p[k] < hi[k]);
            if !inside {
                return (false, false);
            }
            let idx: [i64; 3] = std::array::from_fn(|k| {
                let v = ((p[k] as f64 - bb0[k] as f64) / mask.res).round_ties_even();
                // Saturating cast: far-outside values stay outside the grid.
                v as i64
            });
            (true, mask.get(idx[0], idx[1], idx[2]))
        })
        .collect();
    flags.into_iter().unzip()
}

/// Stage 5's plane test per point: `[x, y, z, 1]·P > 0`, in `f64`, summed left to right.
pub fn above_plane(points: &[[f32; 3]], plane: &Plane) -> Vec<bool> {
    points
        .par_iter()
        .with_min_len(4096)
        .map(|p| plane.eval(p.map(f64::from)) > 0.0)
        .collect()
}

/// Stage 6 for one direction: the mean of the distances `< max_dist` (f64, summed in order) and
/// how many there were. An empty selection is an error naming `direction`.
pub fn mean_below(
    d: &[f64],
    max_dist: f64,
    direction: &'static str,
) -> Result<(f64, u64), EvalError> {
    let mut sum = 0.0f64;
    let mut n = 0u64;
    for &v in d {
        if v < max_dist {
            sum += v;
            n += 1;
        }
    }
    if n == 0 {
        return Err(EvalError::NoneBelowMaxDist {
            direction,
            n: d.len(),
            max_dist,
            min: d.iter().copied().fold(f64::INFINITY, f64::min),
        });
    }
    Ok((sum / n as f64, n))
}

/// A [`EvalError::NoneBelowMaxDist`] of a bounded search (every distance `+inf`, none searched
/// past `max_dist`) with the smallest distance from `queries` to `points` filled in, so the
/// message says how far apart the sets are; other errors pass through.
pub(crate) fn with_smallest_distance(
    e: EvalError,
    points: &[[f32; 3]],
    queries: &[[f32; 3]],
) -> EvalError {
    match e {
        EvalError::NoneBelowMaxDist {
            direction,
            n,
            max_dist,
            min,
        } if min.is_infinite() && !queries.is_empty() => EvalError::NoneBelowMaxDist {
            direction,
            n,
            max_dist,
            min: BoxTree::new(points)
                .map(|t| t.smallest_distance(queries, max_dist))
                .unwrap_or(min),
        },
        e => e,
    }
}

/// Everything the protocol computed for one mesh.
#[derive(Clone, Debug)]
pub struct DtuEvaluation {
    /// Accuracy (mm).
    pub mean_d2s: f64,
    /// Completeness (mm).
    pub mean_s2d: f64,
    /// Counts at each stage (`mesh_vertices`/`mesh_faces` are filled by the caller when it
    /// started from samples).
    pub counts: DtuCounts,
    /// The downsampled points `[n_down][3]` in shuffled order.
    pub data_down: Vec<[f32; 3]>,
    /// Per `data_down` point: inside the box (`data_in`).
    pub in_box: Vec<bool>,
    /// Per `data_down` point: observed (`data_in_obs`).
    pub in_obs: Vec<bool>,
    /// Per observed point, in `data_down` order: distance to the nearest GT point (mm), or
    /// `+inf` where that distance is `>= max_dist` (the search stops at the outlier cut,
    /// [`BoxTree::nearest_distances_below`]; [`Self::exact_outliers`] fills them in).
    pub d2s: Vec<f64>,
    /// Per GT point: above the plane.
    pub above: Vec<bool>,
    /// Per GT point above the plane, in GT order: distance to the nearest `data_in` point (mm),
    /// or `+inf` where it is `>= max_dist` (as `d2s`).
    pub s2d: Vec<f64>,
    /// Stage timings.
    pub stages: Vec<StageTime>,
}

impl DtuEvaluation {
    /// `(mean_d2s + mean_s2d) / 2`, DTUeval-python's "overall".
    pub fn overall(&self) -> f64 {
        (self.mean_d2s + self.mean_s2d) / 2.0
    }

    /// `mean_d2s + mean_s2d`, the paper's Chamfer figure.
    pub fn chamfer_sum(&self) -> f64 {
        self.mean_d2s + self.mean_s2d
    }

    /// Replaces the `+inf` of `d2s` and `s2d` (distances at or beyond `max_dist`, not searched)
    /// by the exact distances, with an unbounded search of those points only, for output that
    /// lists every distance (`--dump-dir`). `gt` must be the ground truth evaluated against.
    pub fn exact_outliers(&mut self, gt: &GroundTruth) -> Result<(), EvalError> {
        let tree_err = |what: &str| {
            let what = what.to_string();
            move |source| EvalError::Tree { what, source }
        };
        if self.d2s.iter().any(|d| d.is_infinite()) {
            let queries = select(&self.data_down, &self.in_obs);
            BoxTree::new(&gt.points)
                .map_err(tree_err("ground-truth points"))?
                .fill_infinite(&queries, &mut self.d2s);
        }
        if self.s2d.iter().any(|d| d.is_infinite()) {
            let data_in = select(&self.data_down, &self.in_box);
            let gt_above = select(&gt.points, &self.above);
            BoxTree::new(&data_in)
                .map_err(tree_err("mesh points in the box"))?
                .fill_infinite(&gt_above, &mut self.s2d);
        }
        Ok(())
    }
}

/// Stages 2 (downsampling) to 6 on already sampled and shuffled points (`[n][3]`, world mm).
pub fn evaluate_samples(
    samples: &[[f32; 3]],
    gt: &GroundTruth,
    params: &DtuParams,
    mut sw: Stopwatch,
) -> Result<DtuEvaluation, EvalError> {
    check_params(params)?;
    if samples.is_empty() {
        return Err(EvalError::EmptyMesh {
            what: "the sampled mesh".into(),
        });
    }
    let tree_err = |what: &str| {
        let what = what.to_string();
        move |source| EvalError::Tree { what, source }
    };
    let keep = radius_downsample(samples, params.density);
    let data_down = select(samples, &keep);
    sw.lap("downsample");

    let (in_box, in_obs) = observation_filter(&data_down, &gt.obs_mask, params.patch_size);
    let data_in = select(&data_down, &in_box);
    let data_in_obs = select(&data_down, &in_obs);
    let n_in = data_in.len();
    if (n_in as f64) < MIN_IN_BOX_FRACTION * data_down.len() as f64 || n_in == 0 {
        let (mesh_min, mesh_max) = bounds(&data_down).expect("non-empty");
        let p = params.patch_size;
        let bb = &gt.obs_mask.bb;
        return Err(EvalError::OutsideBox {
            in_box: n_in,
            total: data_down.len(),
            mesh_min,
            mesh_max,
            box_min: std::array::from_fn(|k| (bb[0][k] - p) as f32),
            box_max: std::array::from_fn(|k| (bb[1][k] + 2.0 * p) as f32),
        });
    }
    if data_in_obs.is_empty() {
        return Err(EvalError::EmptyStage {
            stage: "observation mask",
            detail: format!(
                "{n_in} mesh points lie in the box, but none in an observed voxel of ObsMask \
                 (Res {} mm); the mesh covers only unobserved space",
                gt.obs_mask.res
            ),
        });
    }
    sw.lap("mask");

    let gt_tree = BoxTree::new(&gt.points).map_err(tree_err("ground-truth points"))?;
    let d2s = gt_tree.nearest_distances_below(&data_in_obs, params.max_dist);
    drop(gt_tree);
    sw.lap("d2s");

    let above = above_plane(&gt.points, &gt.plane);
    let gt_above = select(&gt.points, &above);
    if gt_above.is_empty() {
        return Err(EvalError::EmptyStage {
            stage: "ground plane",
            detail: format!(
                "none of the {} ground-truth points is above the plane P = {:?}",
                gt.points.len(),
                gt.plane.0
            ),
        });
    }
    let data_tree = BoxTree::new(&data_in).map_err(tree_err("mesh points in the box"))?;
    let s2d = data_tree.nearest_distances_below(&gt_above, params.max_dist);
    drop(data_tree);
    sw.lap("s2d");

    let (mean_d2s, d2s_below) = mean_below(&d2s, params.max_dist, "accuracy (d2s, mesh -> GT)")
        .map_err(|e| with_smallest_distance(e, &gt.points, &data_in_obs))?;
    let (mean_s2d, s2d_below) = mean_below(&s2d, params.max_dist, "completeness (s2d, GT -> mesh)")
        .map_err(|e| with_smallest_distance(e, &data_in, &gt_above))?;
    sw.lap("means");

    let counts = DtuCounts {
        mesh_vertices: 0,
        mesh_faces: 0,
        sampled: samples.len() as u64,
        downsampled: data_down.len() as u64,
        in_box: n_in as u64,
        in_obs: data_in_obs.len() as u64,
        gt_points: gt.points.len() as u64,
        gt_above_plane: gt_above.len() as u64,
        d2s_below_max: d2s_below,
        s2d_below_max: s2d_below,
    };
    Ok(DtuEvaluation {
        mean_d2s,
        mean_s2d,
        counts,
        data_down,
        in_box,
        in_obs,
        d2s,
        above,
        s2d,
        stages: sw.into_stages(),
    })
}

/// The whole protocol on a mesh in DTU world mm: sampling, shuffle (`seed`), downsampling,
/// filtering, distances, means.
pub fn evaluate_mesh(
    mesh: &TriMesh,
    gt: &GroundTruth,
    params: &DtuParams,
    seed: u64,
) -> Result<DtuEvaluation, EvalError> {
    check_params(params)?;
    let mut sw = Stopwatch::new();
    let samples = sample_and_shuffle(
        mesh,
        params.density,
        seed,
        DEFAULT_MAX_SAMPLES,
        "mesh",
        &mut sw,
    )?;
    let mut eval = evaluate_samples(&samples, gt, params, sw)?;
    eval.counts.mesh_vertices = mesh.vertices.len() as u64;
    eval.counts.mesh_faces = mesh.faces.len() as u64;
    Ok(eval)
}
