//! Plain mode: accuracy and completeness between two point sets without DTU's masks.
//!
//! Inputs with faces are sampled as in the DTU protocol ([`crate::sample`], at `density`);
//! point clouds are used as they are. With a `downsample` radius both sets are shuffled (seeded)
//! and greedily downsampled; without one, point order is the input order, so the per-point
//! distances line up with the files. `max_dist` (if any) leaves distances `>= max_dist` out of
//! the means, as DTU's 20 mm cut.

use crate::boxtree::BoxTree;
use crate::downsample::{radius_downsample, select, shuffle};
use crate::error::EvalError;
use crate::protocol::{check_positive, mean_below, with_smallest_distance};
use crate::report::{PlainCounts, PlainParams, StageTime, Stopwatch};

/// Seed offset for the reference set's shuffle, so the two sets do not share a permutation.
const REF_SEED_XOR: u64 = 0x9e37_79b9_7f4a_7c15;

/// Everything the plain mode computed.
#[derive(Clone, Debug)]
pub struct PlainEvaluation {
    /// Mean distance data → reference (over distances below `max_dist`, if set).
    pub mean_d2s: f64,
    /// Mean distance reference → data.
    pub mean_s2d: f64,
    pub counts: PlainCounts,
    /// The data points used, `[n][3]`.
    pub data: Vec<[f32; 3]>,
    /// The reference points used.
    pub reference: Vec<[f32; 3]>,
    /// Per data point: distance to the nearest reference point, or `+inf` where a `max_dist`
    /// is set and the distance is `>= max_dist` (not searched further;
    /// [`Self::exact_outliers`] fills them in).
    pub d2s: Vec<f64>,
    /// Per reference point: distance to the nearest data point (`+inf` as `d2s`).
    pub s2d: Vec<f64>,
    pub stages: Vec<StageTime>,
}

impl PlainEvaluation {
    /// Replaces the `+inf` of `d2s` and `s2d` by the exact distances (unbounded search of those
    /// points only), for output that lists every distance (`--dump-dir`).
    pub fn exact_outliers(&mut self) -> Result<(), EvalError> {
        let tree_err = |what: &'static str| {
            move |source| EvalError::Tree {
                what: what.into(),
                source,
            }
        };
        if self.d2s.iter().any(|d| d.is_infinite()) {
            BoxTree::new(&self.reference)
                .map_err(tree_err("reference points"))?
                .fill_infinite(&self.data, &mut self.d2s);
        }
        if self.s2d.iter().any(|d| d.is_infinite()) {
            BoxTree::new(&self.data)
                .map_err(tree_err("data points"))?
                .fill_infinite(&self.reference, &mut self.s2d);
        }
        Ok(())
    }
}

/// Checks the plain mode's parameters.
pub fn check_params(p: &PlainParams) -> Result<(), EvalError> {
    check_positive("density", p.density)?;
    if let Some(r) = p.downsample {
        check_positive("downsample", r)?;
    }
    if let Some(m) = p.max_dist {
        if m.is_nan() || m <= 0.0 {
            return Err(EvalError::BadParam {
                name: "max_dist",
                value: m,
                why: "must be > 0",
            });
        }
    }
    Ok(())
}

/// Evaluates `data` against `reference` (both `[n][3]`, same frame and unit; already sampled).
pub fn evaluate_points(
    mut data: Vec<[f32; 3]>,
    mut reference: Vec<[f32; 3]>,
    params: &PlainParams,
    seed: u64,
    mut sw: Stopwatch,
) -> Result<PlainEvaluation, EvalError> {
    check_params(params)?;
    let (data_points, ref_points) = (data.len() as u64, reference.len() as u64);
    let tree_err = |what: &'static str| {
        move |source| EvalError::Tree {
            what: what.into(),
            source,
        }
    };
    if let Some(r) = params.downsample {
        shuffle(&mut data, seed);
        shuffle(&mut reference, seed ^ REF_SEED_XOR);
        let keep = radius_downsample(&data, r);
        data = select(&data, &keep);
        let keep = radius_downsample(&reference, r);
        reference = select(&reference, &keep);
        sw.lap("downsample");
    }
    let max = params.max_dist.unwrap_or(f64::INFINITY);
    let ref_tree = BoxTree::new(&reference).map_err(tree_err("reference points"))?;
    let d2s = ref_tree.nearest_distances_below(&data, max);
    drop(ref_tree);
    sw.lap("d2s");
    let data_tree = BoxTree::new(&data).map_err(tree_err("data points"))?;
    let s2d = data_tree.nearest_distances_below(&reference, max);
    drop(data_tree);
    sw.lap("s2d");
    let (mean_d2s, d2s_below) = mean_below(&d2s, max, "accuracy (d2s, data -> reference)")
        .map_err(|e| with_smallest_distance(e, &reference, &data))?;
    let (mean_s2d, s2d_below) = mean_below(&s2d, max, "completeness (s2d, reference -> data)")
        .map_err(|e| with_smallest_distance(e, &data, &reference))?;
    sw.lap("means");
    Ok(PlainEvaluation {
        mean_d2s,
        mean_s2d,
        counts: PlainCounts {
            data_points,
            data_used: data.len() as u64,
            ref_points,
            ref_used: reference.len() as u64,
            d2s_below_max: d2s_below,
            s2d_below_max: s2d_below,
        },
        data,
        reference,
        d2s,
        s2d,
        stages: sw.into_stages(),
    })
}
