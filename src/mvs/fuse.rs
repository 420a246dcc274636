//! Steps 2 and 3 of the module doc of [`super`]: geometric consistency and the fusion fill.

use super::{MvsConfig, View};
use nalgebra::Vector3;
use rayon::prelude::*;

/// Step 2 of the module doc: the camera-`z` maps keeping the depths at least
/// `min_consistent` sources agree with.
pub(super) fn consistent(
    cfg: &MvsConfig,
    views: &[View],
    sources: &[Vec<usize>],
    z: &[Vec<f32>],
) -> Vec<Vec<f32>> {
    (0..views.len())
        .into_par_iter()
        .map(|i| {
            let vi = &views[i];
            let mut out = vec![f32::NAN; vi.w * vi.h];
            for (k, o) in out.iter_mut().enumerate() {
                let zi = z[i][k] as f64;
                if !zi.is_finite() {
                    continue;
                }
                let (u, v) = ((k % vi.w) as f64 + 0.5, (k / vi.w) as f64 + 0.5);
                let xw = vi.point(k, zi);
                let mut good = 0;
                for &j in &sources[i] {
                    let vj = &views[j];
                    let (uj, vj_, zj0) = vj.project(&xw);
                    if !(uj >= 0.0 && vj_ >= 0.0 && zj0 > 0.0) {
                        continue;
                    }
                    let (xj, yj) = (uj as usize, vj_ as usize);
                    if xj >= vj.w || yj >= vj.h {
                        continue;
                    }
                    let kj = yj * vj.w + xj;
                    let zj = z[j][kj] as f64;
                    if !zj.is_finite() {
                        continue;
                    }
                    let (ub, vb, zb) = vi.project(&vj.point(kj, zj));
                    let pe = ((ub - u).powi(2) + (vb - v).powi(2)).sqrt();
                    if pe < cfg.px_tol as f64 && (zb - zi).abs() < cfg.rel_tol as f64 * zi {
                        good += 1;
                    }
                }
                if good >= cfg.min_consistent {
                    *o = zi as f32;
                }
            }
            out
        })
        .collect()
}

/// Step 3 of the module doc: the camera-`z` maps with the fill, and which pixels it filled.
pub(super) fn fuse(
    cfg: &MvsConfig,
    views: &[View],
    z: &[Vec<f32>],
) -> (Vec<Vec<f32>>, Vec<Vec<bool>>) {
    // World points with their view and grey.
    let pts: Vec<(usize, Vector3<f64>, f32)> = views
        .iter()
        .enumerate()
        .flat_map(|(j, vj)| {
            z[j].iter()
                .enumerate()
                .filter(|(_, zz)| zz.is_finite())
                .map(move |(k, &zz)| (j, vj.point(k, zz as f64), vj.grey[k]))
        })
        .collect();
    let r = cfg.fuse_radius as f64;
    let ri = r.ceil() as isize;
    (0..views.len())
        .into_par_iter()
        .map(|i| {
            let vi = &views[i];
            let (w, h) = (vi.w as isize, vi.h as isize);
            let mut out = z[i].clone();
            let mut filled = vec![false; out.len()];
            let need: Vec<bool> = (0..out.len())
                .map(|k| vi.mask[k] && !out[k].is_finite() && vi.grey[k].is_finite())
                .collect();
            let mut splats: Vec<Vec<(f32, f32)>> = vec![Vec::new(); out.len()];
            for (j, x, g) in &pts {
                if *j == i {
                    continue;
                }
                let (u, v, zz) = vi.project(x);
                if !(zz > 0.0 && u.is_finite() && v.is_finite()) {
                    continue;
                }
                let (cx, cy) = (u.floor() as isize, v.floor() as isize);
                for yy in (cy - ri).max(0)..=(cy + ri).min(h - 1) {
                    for xx in (cx - ri).max(0)..=(cx + ri).min(w - 1) {
                        let (dx, dy) = (xx as f64 + 0.5 - u, yy as f64 + 0.5 - v);
                        let k = (yy * w + xx) as usize;
                        if dx * dx + dy * dy <= r * r && need[k] {
                            splats[k].push((zz as f32, *g));
                        }
                    }
                }
            }
            // The depth tolerance is normalised units along the ray: per pixel, in camera z.
            for (k, l) in splats.iter_mut().enumerate() {
                if l.len() < cfg.fuse_support {
                    continue;
                }
                let d = vi.dir((k % vi.w) as f64 + 0.5, (k / vi.w) as f64 + 0.5);
                let tol = (cfg.fuse_depth_tol as f64 / d.norm()) as f32;
                l.sort_by(|a, b| a.0.total_cmp(&b.0));
                let mut a = 0;
                while a < l.len() {
                    let b = a + l[a..].iter().take_while(|s| s.0 <= l[a].0 + tol).count();
                    if b - a >= cfg.fuse_support {
                        let nc = (b - a) as f32;
                        let grey = l[a..b].iter().map(|s| s.1).sum::<f32>() / nc;
                        if (grey - vi.grey[k]).abs() < cfg.fuse_grey_tol {
                            out[k] = l[a..b].iter().map(|s| s.0).sum::<f32>() / nc;
                            filled[k] = true;
                            break;
                        }
                    }
                    a += 1;
                }
            }
            (out, filled)
        })
        .unzip()
}
