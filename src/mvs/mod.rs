//! Multi-view stereo: a depth map per view from the posed images alone, for the depth prior of
//! training (`train::depth`). It reads cameras, images and masks (`scene`) and nothing else.
//!
//! Where the colour loss cannot pin a concave part down (the inside of a cavity seen through its
//! opening), NeuS closes the cavity with a false sheet that its colour network paints with what
//! lies behind it. Stereo depth sees through such a sheet; the depth prior carves the span in
//! front of it. Distances are in the normalised frame (the unit sphere of
//! `cameras_sphere.npz`).
//!
//! Per view ([`depth_maps`], [`MvsConfig`]):
//! 1. *Plane sweep* (Collins, CVPR 1996; [`sweep`]): `planes` fronto-parallel planes spread
//!    evenly in camera depth over the sphere of radius `depth_radius`. Each masked pixel's
//!    `(2·window_half + 1)²` window is warped into the `sources` views whose optical axes are
//!    nearest; the cost is `1 − NCC` (box sums over integral images) averaged over the `top_k`
//!    best sources (Kang, Szeliski & Chai, CVPR 2001: the best subset drops views that see an
//!    occluder). A parabola through the best plane and its neighbours refines the depth, kept
//!    below `max_cost`. Windows without texture (grey deviation below `min_std`) or with a
//!    non-finite pixel give no cost.
//! 2. *Slanted windows* (`slant_iters`, [`slant`]): PatchMatch stereo (Bleyer, Rhemann & Rother,
//!    BMVC 2011) gives each pixel a plane of its own orientation, so that a window on a surface
//!    the camera grazes is warped as that surface is.
//! 3. *Geometric consistency* (COLMAP, Schönberger et al., ECCV 2016, §4.3,
//!    `src/colmap/mvs/fusion.cc`): a depth is kept when at least `min_consistent` sources'
//!    depths, at its reprojection, map back within `px_tol` pixels and `rel_tol·z` of it.
//! 4. *Fusion fill* ([`fuse`]): a window next to an occluding contour holds both sides, so the
//!    pixels just behind a contour get no consistent depth while another view sees the same
//!    points away from any contour. Every kept depth becomes a world point carrying its grey;
//!    each view splats the other views' points (radius `fuse_radius` pixels), and a pixel
//!    without depth takes the nearest cluster of at least `fuse_support` splats within
//!    `fuse_depth_tol` whose mean grey matches its own within `fuse_grey_tol`.
//! 5. *Hole fill* ([`holes`]; the interpolation of Hirschmüller's semi-global matching, IEEE
//!    PAMI 30(2), 2008): a masked pixel still without depth looks for the nearest depth within
//!    `hole_radius` pixels along 8 directions. Depths that spread by at most `hole_jump` are one
//!    surface (a patch without texture); otherwise the pixel lies behind an occluding contour
//!    and takes the farthest group of at least two depths within `hole_tol` (with
//!    `hole_grey_tol`, the group whose grey matches). The pixel takes the plane
//!    `1/z = a·x + b·y + c` fitted to the group, refitted `hole_refine` rounds to every depth of
//!    its window within `hole_tol` (RANSAC's consensus step).
//! 6. *Free-space check and march* (`free_tol`, `free_views`, `cast_radius`): a hole-fill
//!    candidate is passed over when `free_views` other views see past its point (Merrell et al.,
//!    ICCV 2007, §4); when every candidate fails, the pixel's ray is marched through the surfels
//!    of all views' consistent depths, taking the plane fitted to the surfels seen from the
//!    ray's side where the check accepts it.
//!
//! [`sweep_depths`] runs step 1 alone on a few views: the check of the depth prior's automatic
//! switch (`train::depth_auto`). The random numbers of step 2 come from a generator seeded by the
//! view's index, so a scene gives the same depth maps at every run, on any number of threads.

mod fuse;
mod holes;
mod photo;
mod slant;
mod sweep;
#[cfg(test)]
pub(crate) mod tests;

use crate::scene::image::luma;
use crate::scene::{Camera, GrayImage, RgbImage};
use fuse::{consistent, fuse};
use holes::{fill_holes, free_of_others, SurfelCloud};
use nalgebra::{Matrix3, Vector3};
pub use photo::PhotoCost;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sweep::sweep_view;

/// Settings of the stereo (`[train.depth.mvs]` in a run's configuration). The module doc
/// describes each step; defaults in parentheses.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MvsConfig {
    /// Depth planes per view (128).
    pub planes: usize,
    /// Source views per view: the nearest by the angle of the optical axes (4).
    pub sources: usize,
    /// A plane's cost is the mean of the `top_k` best sources' (2).
    pub top_k: usize,
    /// NCC window half-width `h`, pixels: `(2h + 1)²` pixels (2).
    pub window_half: usize,
    /// A depth is kept only below this cost `1 − NCC` (0.5).
    pub max_cost: f32,
    /// Windows with a grey standard deviation below this give no cost (0.005).
    pub min_std: f32,
    /// Sources that must agree with a depth (2).
    pub min_consistent: usize,
    /// Agreement: depth within this share of the depth (0.002) ...
    pub rel_tol: f32,
    /// ... and reprojection within this many pixels (1).
    pub px_tol: f32,
    /// Radius of the sphere about the origin that bounds the sweep, normalised units (1).
    pub depth_radius: f32,
    /// Fusion fill: splat radius in pixels (1; 0: no fill). It fills cavities behind
    /// occluding contours, and can fill a thin part's edge with the depth behind it.
    pub fuse_radius: f32,
    /// ... splats a cluster needs (2) ...
    pub fuse_support: usize,
    /// ... the cluster's depth extent, normalised units (0.01) ...
    pub fuse_depth_tol: f32,
    /// ... and how far its mean grey may lie from the pixel's (0.01; grey in `[0, 1]`).
    pub fuse_grey_tol: f32,
    /// Hole fill: how far, in pixels, a pixel still without a depth looks along each of 8
    /// directions for one (10; 0: no hole fill).
    pub hole_radius: usize,
    /// ... below this spread of the depths found (a share of the farthest) they are one
    /// surface and all of them are fitted (0.02) ...
    pub hole_jump: f32,
    /// ... above it the pixel takes the farthest group of at least two depths within this
    /// share of each other (0.01) ...
    pub hole_tol: f32,
    /// ... or, when this is positive, of the groups whose mean grey lies within it of the
    /// pixel's, the one that matches best, and none when none does (0.1; grey in `[0, 1]`): a
    /// pixel without a depth on a thin part in front of the object is not background.
    pub hole_grey_tol: f32,
    /// ... and the plane through the chosen depths is refitted this many rounds to every depth
    /// of the pixel's `(2·hole_radius + 1)²` window within `hole_tol` of it (2; 0: no refit): a
    /// group holds 2 to 8 depths, all at one side of a hole, and extrapolates badly alone.
    pub hole_refine: usize,
    /// Free-space check of the hole fill: a candidate depth is passed over when at least
    /// `free_views` other views see past its point, their consistent depth at its pixel lying
    /// more than this share of its camera depth beyond it (0.02; 0: no check).
    pub free_tol: f32,
    /// ... how many views must see past it (2) ...
    pub free_views: usize,
    /// ... and when every candidate fails, the pixel's ray is marched from the preferred
    /// one's depth through the surfels of every view's consistent depths within this radius
    /// (normalised units; 0.25, about a quarter of the object's bounding radius; 0: no
    /// march, the pixel stays empty).
    pub cast_radius: f32,
    /// Slanted windows ([`slant`]): passes of PatchMatch over each view after the sweep (3; 0:
    /// the sweep's fronto-parallel windows alone). [`sweep_depths`] does without them.
    pub slant_iters: usize,
}

impl Default for MvsConfig {
    fn default() -> Self {
        Self {
            planes: 128,
            sources: 4,
            top_k: 2,
            window_half: 2,
            max_cost: 0.5,
            min_std: 0.005,
            min_consistent: 2,
            rel_tol: 0.002,
            px_tol: 1.0,
            depth_radius: 1.0,
            fuse_radius: 1.0,
            fuse_support: 2,
            fuse_depth_tol: 0.01,
            fuse_grey_tol: 0.01,
            hole_radius: 10,
            hole_jump: 0.02,
            hole_tol: 0.01,
            hole_grey_tol: 0.1,
            hole_refine: 2,
            free_tol: 0.02,
            free_views: 2,
            cast_radius: 0.25,
            slant_iters: 3,
        }
    }
}

impl MvsConfig {
    /// The first invalid field, as `(field, value, why)`; `field` is the bare name (the caller
    /// knows where the section sits in its configuration).
    pub fn invalid(&self) -> Option<(&'static str, String, &'static str)> {
        let pos = |v: f32| v.is_finite() && v > 0.0;
        let nonneg = |v: f32| v.is_finite() && v >= 0.0;
        let c = |key, ok, value: &dyn std::fmt::Display, why| (key, ok, value.to_string(), why);
        let checks = [
            c(
                "planes",
                (2..=4096).contains(&self.planes),
                &self.planes,
                "must be in 2..=4096",
            ),
            c(
                "sources",
                self.sources > 0,
                &self.sources,
                "must be at least 1",
            ),
            c(
                "top_k",
                (1..=self.sources).contains(&self.top_k),
                &self.top_k,
                "must be in 1..=sources",
            ),
            c(
                "window_half",
                (1..=10).contains(&self.window_half),
                &self.window_half,
                "must be in 1..=10",
            ),
            c(
                "max_cost",
                pos(self.max_cost),
                &self.max_cost,
                "must be positive",
            ),
            c(
                "min_std",
                nonneg(self.min_std),
                &self.min_std,
                "must be ≥ 0",
            ),
            c(
                "min_consistent",
                self.min_consistent <= self.sources,
                &self.min_consistent,
                "must be at most sources",
            ),
            c(
                "rel_tol",
                pos(self.rel_tol),
                &self.rel_tol,
                "must be positive",
            ),
            c(
                "px_tol",
                pos(self.px_tol),
                &self.px_tol,
                "must be positive (pixels)",
            ),
            c(
                "depth_radius",
                pos(self.depth_radius),
                &self.depth_radius,
                "must be positive (normalised units)",
            ),
            c(
                "fuse_radius",
                nonneg(self.fuse_radius) && self.fuse_radius <= 8.0,
                &self.fuse_radius,
                "must be in [0, 8] (pixels)",
            ),
            c(
                "fuse_support",
                self.fuse_support > 0,
                &self.fuse_support,
                "must be at least 1",
            ),
            c(
                "fuse_depth_tol",
                pos(self.fuse_depth_tol),
                &self.fuse_depth_tol,
                "must be positive (normalised units)",
            ),
            c(
                "fuse_grey_tol",
                pos(self.fuse_grey_tol),
                &self.fuse_grey_tol,
                "must be positive",
            ),
            c(
                "hole_radius",
                self.hole_radius <= 64,
                &self.hole_radius,
                "must be in 0..=64 (pixels)",
            ),
            c(
                "hole_jump",
                pos(self.hole_jump),
                &self.hole_jump,
                "must be positive",
            ),
            c(
                "hole_tol",
                pos(self.hole_tol),
                &self.hole_tol,
                "must be positive",
            ),
            c(
                "hole_grey_tol",
                nonneg(self.hole_grey_tol),
                &self.hole_grey_tol,
                "must be ≥ 0",
            ),
            c(
                "hole_refine",
                self.hole_refine <= 8,
                &self.hole_refine,
                "must be in 0..=8 (rounds)",
            ),
            c(
                "free_tol",
                nonneg(self.free_tol) && self.free_tol < 1.0,
                &self.free_tol,
                "must be in [0, 1)",
            ),
            c(
                "free_views",
                self.free_views > 0,
                &self.free_views,
                "must be at least 1",
            ),
            c(
                "slant_iters",
                self.slant_iters <= 16,
                &self.slant_iters,
                "must be in 0..=16 (passes)",
            ),
            c(
                "cast_radius",
                nonneg(self.cast_radius) && self.cast_radius <= 1.0,
                &self.cast_radius,
                "must be in [0, 1] (normalised units)",
            ),
        ];
        let (key, _, value, why) = checks.into_iter().find(|c| !c.1)?;
        Some((key, value, why))
    }
}

/// Per view, the distance `t` along the unit ray through each pixel centre to the surface
/// (normalised units; NaN: no depth), and which depths the fills gave.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthMaps {
    /// `[view]` image width in pixels.
    pub width: Vec<usize>,
    /// `[view][y * width + x]` distance along the unit ray (NaN: none).
    pub t: Vec<Vec<f32>>,
    /// `[view][y * width + x]` whether the fusion fill gave the depth.
    pub filled: Vec<Vec<bool>>,
    /// `[view][y * width + x]` whether the hole fill gave the depth.
    pub hole_filled: Vec<Vec<bool>>,
    /// Pixels the stereo looked at (inside the masks): the denominator of the coverage.
    pub considered: usize,
}

impl DepthMaps {
    /// The depth of pixel `(x, y)` of `view`, if any.
    pub fn get(&self, view: usize, x: u32, y: u32) -> Option<f64> {
        let w = self.width[view];
        if x as usize >= w {
            return None;
        }
        let v = *self.t[view].get(y as usize * w + x as usize)?;
        v.is_finite().then_some(v as f64)
    }

    /// `(pixels with a depth, of them from the fusion fill)`.
    pub fn counts(&self) -> (usize, usize) {
        let with = self.t.iter().flatten().filter(|t| t.is_finite()).count();
        let filled = self.filled.iter().flatten().filter(|&&f| f).count();
        (with, filled)
    }

    /// Pixels whose depth the hole fill gave.
    pub fn hole_count(&self) -> usize {
        self.hole_filled.iter().flatten().filter(|&&f| f).count()
    }
}

/// What the stereo gave (`train_summary.depth_maps` in `metrics.json`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DepthMapsSummary {
    /// Pixels the stereo looked at (inside the masks; every pixel without masks).
    pub considered: usize,
    /// Of them, pixels with a depth ...
    pub with_depth: usize,
    /// ... of which the fusion fill gave these ...
    pub filled: usize,
    /// ... and the hole fill these.
    #[serde(default)]
    pub hole_filled: usize,
    /// Wall time of the stereo, seconds.
    pub seconds: f64,
}

impl DepthMaps {
    /// The summary, with the stereo's wall time `seconds`.
    pub fn summary(&self, seconds: f64) -> DepthMapsSummary {
        let (with_depth, filled) = self.counts();
        DepthMapsSummary {
            considered: self.considered,
            with_depth,
            filled,
            hole_filled: self.hole_count(),
            seconds,
        }
    }
}

/// A view as the stereo sees it.
struct View {
    w: usize,
    h: usize,
    /// `[y * w + x]` grey (luma) in `[0, 1]`; non-finite where the image is.
    grey: Vec<f32>,

    k: Matrix3<f64>,
    kinv: Matrix3<f64>,
    r: Matrix3<f64>,
    c: Vector3<f64>,
    /// `[y * w + x]` inside the mask (all when there are no masks).
    mask: Vec<bool>,
}

impl View {
    /// Bilinear grey at pixel coordinates `(u, v)` (pixel centres at `+0.5`); NaN outside.
    fn bilinear(&self, u: f64, v: f64) -> f32 {
        let (x, y) = (u - 0.5, v - 0.5);
        if !(x >= 0.0 && y >= 0.0) {
            return f32::NAN;
        }
        let (x0, y0) = (x as usize, y as usize);
        if x0 + 1 >= self.w || y0 + 1 >= self.h {
            return f32::NAN;
        }
        let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
        let i = y0 * self.w + x0;
        let g = &self.grey;
        let a = g[i] + fx * (g[i + 1] - g[i]);
        let b = g[i + self.w] + fx * (g[i + self.w + 1] - g[i + self.w]);
        a + fy * (b - a)
    }

    /// The ray direction through pixel coordinates `(u, v)`, scaled so its camera `z` is 1.
    fn dir(&self, u: f64, v: f64) -> Vector3<f64> {
        self.r.transpose() * (self.kinv * Vector3::new(u, v, 1.0))
    }

    /// The distance along the unit ray through the centre of pixel `k` of the point at camera
    /// depth `z`, NaN for a `z` that is not finite (no depth): what [`DepthMaps::t`] holds.
    fn ray_distance(&self, k: usize, z: f32) -> f32 {
        if !z.is_finite() {
            return f32::NAN;
        }
        let d = self.dir((k % self.w) as f64 + 0.5, (k / self.w) as f64 + 0.5);
        (z as f64 * d.norm()) as f32
    }

    /// The world point at camera depth `z` through the centre of pixel `k`.
    fn point(&self, k: usize, z: f64) -> Vector3<f64> {
        self.c + self.dir((k % self.w) as f64 + 0.5, (k / self.w) as f64 + 0.5) * z
    }

    /// The warp into view `vj`: `(A, b)` with `A = K_j R_j R_iᵀ K_i⁻¹` and
    /// `b = K_j R_j (c_i − c_j)`, so that pixel coordinates `p = (u, v, 1)` of this view at
    /// camera depth `z` land at `z·A·p + b` (homogeneous) in `vj`.
    fn warp_to(&self, vj: &View) -> (Matrix3<f64>, Vector3<f64>) {
        (
            vj.k * vj.r * self.r.transpose() * self.kinv,
            vj.k * vj.r * (self.c - vj.c),
        )
    }

    /// `(u, v, z)`: pixel coordinates and camera depth of `x`.
    fn project(&self, x: &Vector3<f64>) -> (f64, f64, f64) {
        let h = self.k * (self.r * (x - self.c));
        (h.x / h.z, h.y / h.z, h.z)
    }
}

/// Summed-area table of `f` over a `w × h` grid: `s[(y)(w+1) + x]` sums `[0, x) × [0, y)`.
fn integral(w: usize, h: usize, f: impl Fn(usize) -> f64) -> Vec<f64> {
    let mut s = vec![0.0; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0.0;
        for x in 0..w {
            row += f(y * w + x);
            s[(y + 1) * (w + 1) + x + 1] = s[y * (w + 1) + x + 1] + row;
        }
    }
    s
}

/// The sum over `[x0, x1) × [y0, y1)` of a table from [`integral`] of width `w`.
fn box_sum(s: &[f64], w: usize, x0: usize, y0: usize, x1: usize, y1: usize) -> f64 {
    let ww = w + 1;
    s[y1 * ww + x1] - s[y0 * ww + x1] - s[y1 * ww + x0] + s[y0 * ww + x0]
}

/// The depth maps of every view: `cameras[i]` (normalised frame) took `images[i]`; `masks`
/// (optional) limit the pixels looked at. See the module doc for the steps.
pub fn depth_maps(
    cfg: &MvsConfig,
    cameras: &[Camera],
    images: &[RgbImage],
    masks: Option<&[GrayImage]>,
) -> DepthMaps {
    assert_eq!(cameras.len(), images.len(), "one image per camera");
    let views = stereo_views(cameras, images, masks);
    let n = views.len();
    let sources = nearest_sources(&views, cfg.sources);
    let z: Vec<Vec<f32>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let z0 = sweep_view(cfg, &views, i, &sources[i]);
            // The sweep's plane step where the sphere lies wholly in front of the camera; it
            // only sizes the refinement's depth perturbations.
            let dz = 2.0 * cfg.depth_radius as f64 / cfg.planes as f64;
            slant::refine(cfg, &views, i, &sources[i], &z0, dz)
        })
        .collect();
    let z = consistent(cfg, &views, &sources, &z);
    // Step 5's evidence: the consistent stereo depths, before any fill.
    let checked = cfg.hole_radius > 0 && cfg.free_tol > 0.0;
    let evidence = if checked { z.clone() } else { Vec::new() };
    let cloud = (checked && cfg.cast_radius > 0.0)
        .then(|| SurfelCloud::new(&views, &evidence, cfg.cast_radius as f64));
    let (z, filled) = if cfg.fuse_radius > 0.0 {
        fuse(cfg, &views, &z)
    } else {
        let f = z.iter().map(|m| vec![false; m.len()]).collect();
        (z, f)
    };
    let (z, hole_filled): (Vec<Vec<f32>>, Vec<Vec<bool>>) = if cfg.hole_radius > 0 {
        z.par_iter()
            .zip(&views)
            .enumerate()
            .map(|(i, (m, v))| {
                let ok: Vec<bool> = v
                    .mask
                    .iter()
                    .zip(&v.grey)
                    .map(|(m, g)| *m && g.is_finite())
                    .collect();
                let free = |k: usize, zz: f64| {
                    !checked || free_of_others(cfg, &views, &evidence, i, &v.point(k, zz))
                };
                let cast = |k: usize, z0: f64| cloud.as_ref()?.cast(v, k, z0, &|zz| free(k, zz));
                fill_holes(cfg, v.w, v.h, &ok, &v.grey, m, free, cast)
            })
            .unzip()
    } else {
        let f = z.iter().map(|m| vec![false; m.len()]).collect();
        (z, f)
    };
    let t = z
        .iter()
        .zip(&views)
        .map(|(m, v)| {
            m.iter()
                .enumerate()
                .map(|(k, &zz)| v.ray_distance(k, zz))
                .collect()
        })
        .collect();
    DepthMaps {
        width: views.iter().map(|v| v.w).collect(),
        t,
        filled,
        hole_filled,
        considered: views
            .iter()
            .map(|v| v.mask.iter().filter(|&&m| m).count())
            .sum(),
    }
}

/// The views as the stereo sees them: grey images, cameras, masks (all pixels without).
fn stereo_views(cameras: &[Camera], images: &[RgbImage], masks: Option<&[GrayImage]>) -> Vec<View> {
    cameras
        .iter()
        .zip(images)
        .enumerate()
        .map(|(i, (c, img))| View {
            w: img.width,
            h: img.height,
            grey: img
                .data
                .chunks_exact(3)
                .map(|q| luma([q[0], q[1], q[2]]))
                .collect(),
            k: c.k,
            kinv: c.k.try_inverse().expect("K has a positive diagonal"),
            r: c.r,
            c: c.center,
            mask: match masks {
                Some(m) => m[i].data.iter().map(|&v| v > 0.5).collect(),
                None => vec![true; img.width * img.height],
            },
        })
        .collect()
}

/// Per view, its `count` source views: the nearest by the angle of the optical axes (ties by
/// index).
fn nearest_sources(views: &[View], count: usize) -> Vec<Vec<usize>> {
    let n = views.len();
    (0..n)
        .map(|i| {
            let ai = views[i].r.row(2).transpose();
            let mut o: Vec<(f64, usize)> = (0..n)
                .filter(|&j| j != i)
                .map(|j| (-ai.dot(&views[j].r.row(2).transpose()), j))
                .collect();
            o.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            o.iter().take(count).map(|x| x.1).collect()
        })
        .collect()
}

/// Step 1 alone (the plane sweep, no consistency check and no fill) for the views `which`, as
/// [`DepthMaps::t`] gives depths: per view of `which`, the distance along the unit ray through each
/// pixel centre (normalised units; NaN: no depth, or outside the mask). The sources come from every
/// view, as in [`depth_maps`]; only `which` are swept, so this costs `which.len() / cameras.len()`
/// of step 1. What the depth prior's automatic switch ([`super::depth_auto`]) looks at.
pub fn sweep_depths(
    cfg: &MvsConfig,
    cameras: &[Camera],
    images: &[RgbImage],
    masks: Option<&[GrayImage]>,
    which: &[usize],
) -> Vec<Vec<f32>> {
    assert_eq!(cameras.len(), images.len(), "one image per camera");
    let views = stereo_views(cameras, images, masks);
    let sources = nearest_sources(&views, cfg.sources);
    which
        .par_iter()
        .map(|&i| {
            let v = &views[i];
            sweep_view(cfg, &views, i, &sources[i])
                .iter()
                .enumerate()
                .map(|(k, &z)| {
                    if v.mask[k] {
                        v.ray_distance(k, z)
                    } else {
                        f32::NAN
                    }
                })
                .collect()
        })
        .collect()
}
