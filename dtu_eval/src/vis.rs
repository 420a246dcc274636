//! Error-coloured point clouds for looking at where a mesh is wrong, with the colour code of
//! DTUeval-python's visualisation (`vis_{scan:03}_d2s.ply`, `vis_{scan:03}_s2d.ply`):
//! - blue: not evaluated (outside the observation mask, or ground truth below the plane);
//! - white → red: distance from 0 to `vis_threshold` (clipped), red = `vis_threshold` or more;
//! - green: at or beyond `max_dist`, i.e. left out of the mean as an outlier.

use crate::error::EvalError;
use crate::plain::PlainEvaluation;
use crate::ply::write_points;
use crate::protocol::DtuEvaluation;
use std::path::{Path, PathBuf};

/// Colour of points that were not evaluated.
pub const NOT_EVALUATED: [u8; 3] = [0, 0, 255];
/// Colour of outliers (`d >= max_dist`).
pub const OUTLIER: [u8; 3] = [0, 255, 0];

/// The colour of a point at distance `d`: `R·a + W·(1−a)` with `a = min(d, vis_threshold) /
/// vis_threshold`, or [`OUTLIER`] when `d >= max_dist`.
pub fn error_colour(d: f64, vis_threshold: f64, max_dist: f64) -> [u8; 3] {
    if d >= max_dist {
        return OUTLIER;
    }
    let a = (d.min(vis_threshold) / vis_threshold).clamp(0.0, 1.0);
    let gb = (255.0 * (1.0 - a)).round() as u8;
    [255, gb, gb]
}

/// Colours `[n]` for `n` points of which those with `evaluated[i]` carry, in order, the distances
/// `d` (`d.len()` = number of evaluated points).
fn colours(evaluated: &[bool], d: &[f64], vis_threshold: f64, max_dist: f64) -> Vec<[u8; 3]> {
    let mut it = d.iter();
    evaluated
        .iter()
        .map(|&e| match (e, e.then(|| it.next()).flatten()) {
            (true, Some(&v)) => error_colour(v, vis_threshold, max_dist),
            _ => NOT_EVALUATED,
        })
        .collect()
}

/// Writes `vis_{scan:03}_d2s.ply` (the downsampled mesh points) and `vis_{scan:03}_s2d.ply` (the
/// ground-truth points) into `dir`; returns their paths.
pub fn write_dtu(
    dir: &Path,
    scan: u32,
    eval: &DtuEvaluation,
    gt_points: &[[f32; 3]],
    vis_threshold: f64,
    max_dist: f64,
) -> Result<[PathBuf; 2], EvalError> {
    create_dir(dir)?;
    let d2s_path = dir.join(format!("vis_{scan:03}_d2s.ply"));
    let c = colours(&eval.in_obs, &eval.d2s, vis_threshold, max_dist);
    write_points(&d2s_path, &eval.data_down, Some(&c))?;
    let s2d_path = dir.join(format!("vis_{scan:03}_s2d.ply"));
    let c = colours(&eval.above, &eval.s2d, vis_threshold, max_dist);
    write_points(&s2d_path, gt_points, Some(&c))?;
    Ok([d2s_path, s2d_path])
}

/// Plain mode: writes `vis_d2s.ply` (data points) and `vis_s2d.ply` (reference points).
pub fn write_plain(
    dir: &Path,
    eval: &PlainEvaluation,
    vis_threshold: f64,
    max_dist: Option<f64>,
) -> Result<[PathBuf; 2], EvalError> {
    create_dir(dir)?;
    let max = max_dist.unwrap_or(f64::INFINITY);
    let d2s_path = dir.join("vis_d2s.ply");
    let c: Vec<_> = eval
        .d2s
        .iter()
        .map(|&d| error_colour(d, vis_threshold, max))
        .collect();
    write_points(&d2s_path, &eval.data, Some(&c))?;
    let s2d_path = dir.join("vis_s2d.ply");
    let c: Vec<_> = eval
        .s2d
        .iter()
        .map(|&d| error_colour(d, vis_threshold, max))
        .collect();
    write_points(&s2d_path, &eval.reference, Some(&c))?;
    Ok([d2s_path, s2d_path])
}

pub(crate) fn create_dir(dir: &Path) -> Result<(), EvalError> {
    if dir.exists() && !dir.is_dir() {
        return Err(EvalError::Usage(format!(
            "{} exists and is not a folder; name a folder for the output files",
            dir.display()
        )));
    }
    std::fs::create_dir_all(dir).map_err(|source| EvalError::Io {
        path: dir.into(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_code() {
        assert_eq!(error_colour(0.0, 10.0, 20.0), [255, 255, 255]);
        assert_eq!(error_colour(5.0, 10.0, 20.0), [255, 128, 128]);
        assert_eq!(error_colour(12.0, 10.0, 20.0), [255, 0, 0]);
        assert_eq!(error_colour(20.0, 10.0, 20.0), OUTLIER);
        let c = colours(&[false, true, true, false], &[0.0, 30.0], 10.0, 20.0);
        assert_eq!(
            c,
            vec![NOT_EVALUATED, [255, 255, 255], OUTLIER, NOT_EVALUATED]
        );
    }
}
