//! Error-map ray sampling: a share of each batch's pixels is drawn where the colour error has
//! been high, instead of uniformly.
//!
//! The idea is instant-ngp's (`src/testbed_nerf.cu`: a per-image error map at reduced
//! resolution, filled from the training loss of the rays that landed in each cell and sampled
//! through its cumulative distribution; also neuralsim's `ImpSampler`). Here:
//!
//! - each training view is cut into cells of `cell_px × cell_px` pixels (the last row and
//!   column may be smaller);
//! - after a step, each ray's mean absolute colour error over the three channels,
//!   `e = Σ_k |c_k − ĉ_k| / 3` (rendered against the target, composited on the background where
//!   masks exist), moves its cell's value by `err ← err + ema·(e − err)`, in ray order;
//! - every `rebuild_every` steps the per-view distribution is rebuilt with cell weights
//!   `w = max(err, floor)^power`: `floor` keeps every cell reachable, `power` sharpens the focus;
//!   then capped at `cap` times the view's mean weight, so that a few cells whose error the rays
//!   do not remove (silhouette edges a pixel off) do not take the view's rays;
//! - a ray still draws its view uniformly (the view balance of the uniform sampler is kept);
//!   with probability `share` its pixel comes from that view's distribution (a cell, then a
//!   uniform pixel inside the cell), otherwise uniformly from the whole view.
//!
//! Every cell starts at [`INITIAL_ERROR`], so cells no ray has visited yet keep a high weight and
//! are explored early. The map (errors and the distribution in use) is part of the checkpoint, so
//! a resumed run samples the same pixels as an uninterrupted one.
//!
//! Why: the inner walls of a cavity seen through its opening are seen only by the far end of the
//! rig and receive few uniform rays; this sampler sends rays where the rendering is still wrong.
//! At share 0.5 it lowers the mean ratio to the floor over the built-in scenes, but leaves
//! sub-millimetre tunnels through thin sheets and at the rim of a small ring (measured:
//! docs/recipe.md). The `fast` preset turns it on together with the closing at extraction that
//! fills those tunnels (`mesh::closing`).

use rand::Rng;
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicU32, Ordering};

/// The error every cell starts with (a colour error in `[0, 1]` units that any trained cell
/// falls below, so unvisited cells are preferred until visited).
pub const INITIAL_ERROR: f32 = 0.1;

/// The default of [`ErrorMapConfig::cap`].
pub const CAP: f32 = 32.0;

/// Settings of error-map sampling (`[train.error_map]`). Absent from a config's text while it is
/// the default (off), so configs and training hashes of runs without it are unchanged.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ErrorMapConfig {
    /// Probability that a ray's pixel is drawn from the error map (0: off, the uniform sampler,
    /// the default of every preset but `fast`; 0.5 in `fast`, whose `mesh.close_radius = 1` fills
    /// the sub-millimetre tunnels it leaves through thin parts; measured: docs/recipe.md).
    pub share: f32,
    /// Exponent of the cell weights `max(err, floor)^power` (2).
    pub power: f32,
    /// Cell edge in pixels (8; instant-ngp's map is 128² per image at any resolution).
    pub cell_px: u32,
    /// Step of the moving average of a cell's error per ray that lands in it (0.3).
    pub ema: f32,
    /// Smallest weighted error, so that no cell's probability is 0 (0.005).
    pub floor: f32,
    /// Steps between rebuilds of the distributions (8).
    pub rebuild_every: u64,
    /// Largest weight of a cell, as a multiple of its view's mean weight before the cap (32;
    /// 0: no cap). Without it, single silhouette cells took up to half of a view's draws
    /// (measured: docs/recipe.md).
    pub cap: f32,
}

impl Default for ErrorMapConfig {
    fn default() -> Self {
        Self {
            share: 0.0,
            power: 2.0,
            cell_px: 8,
            ema: 0.3,
            floor: 0.005,
            rebuild_every: 8,
            cap: CAP,
        }
    }
}

impl ErrorMapConfig {
    /// Whether every field is at its default (the map off).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// Whether the error map is used at all.
    pub fn enabled(&self) -> bool {
        self.share > 0.0
    }

    /// The first invalid field, as `(key, value, why)`.
    pub fn invalid(&self) -> Option<(&'static str, String, &'static str)> {
        if !(0.0..=1.0).contains(&self.share) {
            return Some((
                "train.error_map.share",
                self.share.to_string(),
                "must be in [0, 1]",
            ));
        }
        if !(self.power.is_finite() && self.power > 0.0 && self.power <= 8.0) {
            return Some((
                "train.error_map.power",
                self.power.to_string(),
                "must be in (0, 8]",
            ));
        }
        if !(1..=512).contains(&self.cell_px) {
            return Some((
                "train.error_map.cell_px",
                self.cell_px.to_string(),
                "must be in 1..=512",
            ));
        }
        if !(self.ema > 0.0 && self.ema <= 1.0) {
            return Some((
                "train.error_map.ema",
                self.ema.to_string(),
                "must be in (0, 1]",
            ));
        }
        if !(self.floor > 0.0 && self.floor <= 1.0) {
            return Some((
                "train.error_map.floor",
                self.floor.to_string(),
                "must be in (0, 1]",
            ));
        }
        if self.rebuild_every == 0 {
            return Some((
                "train.error_map.rebuild_every",
                "0".into(),
                "must be at least 1",
            ));
        }
        if !(self.cap == 0.0 || (self.cap.is_finite() && self.cap >= 1.0)) {
            return Some((
                "train.error_map.cap",
                self.cap.to_string(),
                "must be 0 (no cap) or at least 1",
            ));
        }
        None
    }
}

/// Why a stored error map cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ErrorMapError {
    /// The map was made for views of other sizes or another cell size.
    #[error("the error map was made for {found}, this run has {expected}")]
    Mismatch { found: String, expected: String },
    /// The stored values are not usable.
    #[error("the error map is damaged: {0}")]
    Damaged(String),
}

/// The error map of every training view: cell errors and the sampling distributions.
///
/// Cells of view `v` are row-major `[cells_y][cells_x]` at `offsets[v]..offsets[v + 1]` of
/// `err` and `cdf`; `cdf` holds, per view, the running sum of the cell weights from the last
/// rebuild.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorMap {
    config: ErrorMapConfig,
    /// `[n_views]` image sizes `(width, height)` in pixels.
    sizes: Vec<(u32, u32)>,
    /// `[n_views + 1]` start of each view's cells.
    offsets: Vec<usize>,
    /// `[n_cells]` moving average of the colour error per cell.
    pub err: Vec<f32>,
    /// `[n_cells]` per-view cumulative weights in use for sampling.
    pub cdf: Vec<f32>,
}

impl ErrorMap {
    /// A fresh map for views of `sizes` (`(width, height)` in pixels, training-view order), every
    /// cell at [`INITIAL_ERROR`], its distribution built.
    pub fn new(config: &ErrorMapConfig, sizes: &[(u32, u32)]) -> Self {
        let offsets = cell_offsets(config.cell_px, sizes);
        let n = offsets[sizes.len()];
        let mut m = Self {
            config: config.clone(),
            sizes: sizes.to_vec(),
            offsets,
            err: vec![INITIAL_ERROR; n],
            cdf: vec![0.0; n],
        };
        m.rebuild();
        m
    }

    /// The map restored from stored `err` and `cdf` (a checkpoint), checked against the views.
    pub fn restore(
        config: &ErrorMapConfig,
        sizes: &[(u32, u32)],
        err: Vec<f32>,
        cdf: Vec<f32>,
    ) -> Result<Self, ErrorMapError> {
        let offsets = cell_offsets(config.cell_px, sizes);
        let n = offsets[sizes.len()];
        if err.len() != n || cdf.len() != n {
            return Err(ErrorMapError::Mismatch {
                found: format!("{} and {} cells", err.len(), cdf.len()),
                expected: format!(
                    "{n} cells ({} views, cells of {} px)",
                    sizes.len(),
                    config.cell_px
                ),
            });
        }
        if let Some(i) = err.iter().position(|e| !(e.is_finite() && *e >= 0.0)) {
            return Err(ErrorMapError::Damaged(format!(
                "cell {i} has error {}",
                err[i]
            )));
        }
        for v in 0..sizes.len() {
            let c = &cdf[offsets[v]..offsets[v + 1]];
            let ok = c.iter().all(|x| x.is_finite())
                && c.windows(2).all(|p| p[0] <= p[1])
                && c.last().is_none_or(|&t| t > 0.0);
            if !ok {
                return Err(ErrorMapError::Damaged(format!(
                    "the distribution of view {v} is not a non-decreasing positive running sum"
                )));
            }
        }
        Ok(Self {
            config: config.clone(),
            sizes: sizes.to_vec(),
            offsets,
            err,
            cdf,
        })
    }

    /// The settings the map was made with.
    pub fn config(&self) -> &ErrorMapConfig {
        &self.config
    }

    /// Number of cells over all views.
    pub fn n_cells(&self) -> usize {
        self.err.len()
    }

    /// Cells per row and per column of view `v`.
    pub fn cells_of(&self, v: usize) -> (u32, u32) {
        let (w, h) = self.sizes[v];
        let c = self.config.cell_px;
        (w.div_ceil(c), h.div_ceil(c))
    }

    /// The cell of pixel `(x, y)` of view `v` (an index into `err`).
    pub fn cell(&self, v: usize, x: u32, y: u32) -> usize {
        let (cw, _) = self.cells_of(v);
        let c = self.config.cell_px;
        self.offsets[v] + ((y / c) * cw + x / c) as usize
    }

    /// Rebuilds every view's distribution from the current errors.
    pub fn rebuild(&mut self) {
        let (floor, power, cap) = (self.config.floor, self.config.power, self.config.cap);
        for v in 0..self.sizes.len() {
            let r = self.offsets[v]..self.offsets[v + 1];
            let cdf = &mut self.cdf[r.clone()];
            // The weights first (in `cdf`), then their running sum in place.
            for (q, &e) in cdf.iter_mut().zip(&self.err[r]) {
                // A non-finite error cannot enter (`record` skips it), but a cell must never
                // leave the distribution, so it is read as the floor.
                let e = if e.is_finite() { e.max(floor) } else { floor };
                *q = e.powf(power);
            }
            let limit = if cap > 0.0 {
                cap * cdf.iter().sum::<f32>() / cdf.len() as f32
            } else {
                f32::INFINITY
            };
            let mut acc = 0.0f32;
            for q in cdf.iter_mut() {
                acc += q.min(limit);
                *q = acc;
            }
        }
    }

    /// Whether step `step` starts with a rebuild (every `rebuild_every` steps, not at step 0,
    /// whose distribution [`ErrorMap::new`] built).
    pub fn rebuilds_at(&self, step: u64) -> bool {
        step > 0 && step.is_multiple_of(self.config.rebuild_every)
    }

    /// A pixel `(x, y)` of view `v` drawn from the view's distribution: a cell by its weight,
    /// then a uniform pixel inside the cell (clipped to the image).
    pub fn sample_pixel(&self, v: usize, rng: &mut impl Rng) -> (u32, u32) {
        let cdf = &self.cdf[self.offsets[v]..self.offsets[v + 1]];
        let total = cdf[cdf.len() - 1];
        let u = rng.random::<f32>() * total;
        let i = cdf.partition_point(|&q| q <= u).min(cdf.len() - 1) as u32;
        let (cw, _) = self.cells_of(v);
        let (w, h) = self.sizes[v];
        let c = self.config.cell_px;
        let (x0, y0) = ((i % cw) * c, (i / cw) * c);
        let x = x0 + rng.random_range(0..(w - x0).min(c));
        let y = y0 + rng.random_range(0..(h - y0).min(c));
        (x, y)
    }

    /// Folds one batch's per-ray errors into the map, in ray order: ray `i` went through pixel
    /// `pixels[i]` of view `views[i]` and had error `f32::from_bits(errors[i])`. Non-finite
    /// errors (a skipped step's NaN) are left out.
    pub fn record(&mut self, views: &[u32], pixels: &[[u32; 2]], errors: &[AtomicU32]) {
        let a = self.config.ema;
        for ((&v, &[x, y]), e) in views.iter().zip(pixels).zip(errors) {
            let e = f32::from_bits(e.load(Ordering::Relaxed));
            if !e.is_finite() {
                continue;
            }
            let c = self.cell(v as usize, x, y);
            self.err[c] += a * (e - self.err[c]);
        }
    }

    /// What the map looks like now, for `metrics.json`.
    pub fn summary(&self) -> ErrorMapSummary {
        let n = self.err.len().max(1);
        // Each cell's probability under the distribution in use, views weighted equally (the
        // view is drawn uniformly).
        let mut p: Vec<f64> = Vec::with_capacity(self.cdf.len());
        for v in 0..self.sizes.len() {
            let c = &self.cdf[self.offsets[v]..self.offsets[v + 1]];
            let total = c.last().map_or(1.0, |&t| t as f64);
            let mut prev = 0.0f64;
            for &q in c {
                p.push((q as f64 - prev) / total / self.sizes.len() as f64);
                prev = q as f64;
            }
        }
        p.sort_by(|a, b| b.total_cmp(a));
        ErrorMapSummary {
            cells: self.err.len(),
            mean_error: self.err.iter().map(|&e| e as f64).sum::<f64>() / n as f64,
            unvisited_share: self.err.iter().filter(|&&e| e == INITIAL_ERROR).count() as f64
                / n as f64,
            top_decile_weight: p[..p.len().div_ceil(10)].iter().sum(),
        }
    }
}

/// `[n_views + 1]` start of each view's cells for views of `sizes` cut into cells of `cell_px`.
fn cell_offsets(cell_px: u32, sizes: &[(u32, u32)]) -> Vec<usize> {
    let mut offsets = Vec::with_capacity(sizes.len() + 1);
    let mut n = 0;
    offsets.push(0);
    for &(w, h) in sizes {
        n += (w.div_ceil(cell_px) * h.div_ceil(cell_px)) as usize;
        offsets.push(n);
    }
    offsets
}

/// The error map at the end of training (`metrics.json`, `train.error_map`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ErrorMapSummary {
    /// Cells over all training views.
    pub cells: usize,
    /// Mean of the cells' moving-average colour error (`[0, 1]` units).
    pub mean_error: f64,
    /// Share of cells no ray ever updated (still at the initial error).
    pub unvisited_share: f64,
    /// Share of the error-map draws (views weighted equally, as they are drawn) that go to the
    /// tenth of the cells with the highest probability: 0.1 means the map is uniform, 1 that it
    /// is all on a few cells.
    pub top_decile_weight: f64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_pcg::Pcg64Mcg;

    fn on() -> ErrorMapConfig {
        ErrorMapConfig {
            share: 0.75,
            ..ErrorMapConfig::default()
        }
    }

    fn errs(v: &[f32]) -> Vec<AtomicU32> {
        v.iter().map(|e| AtomicU32::new(e.to_bits())).collect()
    }

    #[test]
    fn config_defaults_are_off_and_bad_values_name_their_key() {
        let c = ErrorMapConfig::default();
        assert!(c.is_default() && !c.enabled() && c.invalid().is_none());
        assert!(on().enabled() && on().invalid().is_none());
        for (bad, key) in [
            (
                ErrorMapConfig { share: 1.5, ..on() },
                "train.error_map.share",
            ),
            (
                ErrorMapConfig {
                    share: f32::NAN,
                    ..on()
                },
                "train.error_map.share",
            ),
            (
                ErrorMapConfig { power: 0.0, ..on() },
                "train.error_map.power",
            ),
            (
                ErrorMapConfig { cell_px: 0, ..on() },
                "train.error_map.cell_px",
            ),
            (ErrorMapConfig { ema: 0.0, ..on() }, "train.error_map.ema"),
            (
                ErrorMapConfig { floor: 0.0, ..on() },
                "train.error_map.floor",
            ),
            (
                ErrorMapConfig {
                    rebuild_every: 0,
                    ..on()
                },
                "train.error_map.rebuild_every",
            ),
            (ErrorMapConfig { cap: 0.5, ..on() }, "train.error_map.cap"),
        ] {
            assert_eq!(bad.invalid().map(|b| b.0), Some(key), "{bad:?}");
        }
    }

    #[test]
    fn cells_cover_partial_edges() {
        // 20 × 9 pixels in cells of 8: 3 × 2 cells, the last column 4 px wide, the last row 1.
        let m = ErrorMap::new(&on(), &[(20, 9), (8, 8)]);
        assert_eq!(m.n_cells(), 6 + 1);
        assert_eq!(m.cells_of(0), (3, 2));
        assert_eq!(m.cell(0, 19, 8), 5);
        assert_eq!(m.cell(0, 7, 7), 0);
        assert_eq!(m.cell(1, 3, 3), 6);
        // Every pixel drawn lies inside its image, and every pixel of view 0 is reachable.
        let mut rng = Pcg64Mcg::seed_from_u64(1);
        let mut hit = [false; 20 * 9];
        for _ in 0..20000 {
            let (x, y) = m.sample_pixel(0, &mut rng);
            assert!(x < 20 && y < 9);
            hit[(y * 20 + x) as usize] = true;
        }
        assert!(hit.iter().all(|&h| h));
    }

    #[test]
    fn the_distribution_follows_the_weighted_errors() {
        // One view of 4 cells; cell 2 has 10× the error of the others: with power 2 its weight is
        // 100×, so without a cap it gets 100/103 of the draws; cells below the floor weigh the
        // floor. A cap of 2× the mean weight (0.010225) holds cell 2 at 0.02045.
        let uncapped = [4e-4, 1e-4, 4e-2, 4e-4];
        let capped = [4e-4, 1e-4, 2.0 * (4e-4 + 1e-4 + 4e-2 + 4e-4) / 4.0, 4e-4];
        for (cap, w) in [(0.0, uncapped), (2.0, capped)] {
            let cfg = ErrorMapConfig {
                cell_px: 4,
                floor: 0.01,
                cap,
                ..on()
            };
            let mut m = ErrorMap::new(&cfg, &[(8, 8)]);
            m.err = vec![0.02, 0.0, 0.2, 0.02];
            m.rebuild();
            let total: f32 = w.iter().sum();
            let mut count = [0usize; 4];
            let mut rng = Pcg64Mcg::seed_from_u64(7);
            let n = 200_000;
            for _ in 0..n {
                let (x, y) = m.sample_pixel(0, &mut rng);
                count[m.cell(0, x, y)] += 1;
            }
            for c in 0..4 {
                let p = w[c] / total;
                let got = count[c] as f32 / n as f32;
                let sd = (p * (1.0 - p) / n as f32).sqrt();
                assert!(
                    (got - p).abs() < 5.0 * sd + 1e-4,
                    "cap {cap} cell {c}: {got} vs {p}"
                );
            }
            // The summary's top decile (one cell of four) is the top cell's probability.
            let top = m.summary().top_decile_weight;
            assert!((top - (w[2] / total) as f64).abs() < 1e-5, "{top}");
        }
    }

    #[test]
    fn record_is_a_moving_average_in_ray_order_and_skips_non_finite_errors() {
        let cfg = ErrorMapConfig {
            cell_px: 4,
            ema: 0.5,
            ..on()
        };
        let mut m = ErrorMap::new(&cfg, &[(8, 4), (4, 4)]);
        let views = [0, 0, 1, 0];
        let pixels = [[1, 1], [2, 3], [0, 0], [5, 0]];
        m.record(&views, &pixels, &errs(&[0.3, 0.5, f32::NAN, 0.0]));
        // Cell 0 of view 0: 0.1 → 0.2 → 0.35. View 1 untouched (NaN). Cell 1 of view 0: 0.05.
        assert!((m.err[0] - 0.35).abs() < 1e-6, "{:?}", m.err);
        assert!((m.err[1] - 0.05).abs() < 1e-6);
        assert_eq!(m.err[2], INITIAL_ERROR);
        // The distribution changes only at a rebuild.
        let before = m.cdf.clone();
        assert_eq!(m.cdf, before);
        m.rebuild();
        assert!(m.cdf[0] > before[0] && m.cdf[1] - m.cdf[0] < before[1] - before[0]);
        assert!(!m.rebuilds_at(0) && m.rebuilds_at(8) && !m.rebuilds_at(9));
        let s = m.summary();
        assert_eq!(s.cells, 3);
        assert!((s.unvisited_share - 1.0 / 3.0).abs() < 1e-9);
        assert!(s.top_decile_weight > 0.1 && s.top_decile_weight < 1.0);
    }

    #[test]
    fn restore_checks_sizes_and_values() {
        let m = ErrorMap::new(&on(), &[(16, 16)]);
        let ok = ErrorMap::restore(&on(), &[(16, 16)], m.err.clone(), m.cdf.clone()).unwrap();
        assert_eq!(ok, m);
        let e = ErrorMap::restore(&on(), &[(24, 16)], m.err.clone(), m.cdf.clone());
        assert!(matches!(e, Err(ErrorMapError::Mismatch { .. })), "{e:?}");
        let mut bad = m.err.clone();
        bad[1] = f32::NAN;
        let e = ErrorMap::restore(&on(), &[(16, 16)], bad, m.cdf.clone());
        assert!(matches!(e, Err(ErrorMapError::Damaged(_))), "{e:?}");
        let mut cdf = m.cdf.clone();
        cdf.reverse();
        let e = ErrorMap::restore(&on(), &[(16, 16)], m.err.clone(), cdf);
        assert!(matches!(e, Err(ErrorMapError::Damaged(_))), "{e:?}");
    }
}
