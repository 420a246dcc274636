//! Depth prior from multi-view stereo (`[train.depth]`, issue 13): off unless asked for
//! (`weight > 0`) or switched on part-way through a run by [`super::depth_auto`], which checks
//! whether the field has closed space the stereo sees through (a cavity's lid).
//!
//! **Why.** On shapes whose concave parts the colour loss cannot pin down (the `cup`'s inside,
//! seen through its opening), NeuS at the `fast` preset closes the cavity with a false sheet that
//! its colour network paints with what lies behind it. Handing the carving of
//! [`super::multiview::CarveConfig`] the *true* depth removes the sheet (`cup`, `fast`:
//! 4.81 → 0.72 mm; `results/geometry/cup-depth-2026-11-27`). This module computes a stand-in for
//! that depth from the training images alone, once, before training.
//!
//! **Depth maps** ([`depth_maps`], [`MvsConfig`]), per training view:
//! 1. *Plane sweep* (Collins, CVPR 1996): `planes` fronto-parallel planes spread evenly in the
//!    view's camera depth `z` over the depths of the sphere of radius `depth_radius` about the
//!    origin (the normalised frame's unit sphere holds the object, `cameras_sphere.npz`). At
//!    each plane every masked pixel's `(2·window_half + 1)²` window is warped into the
//!    `sources` views whose optical axes are nearest, and the cost is `1 − NCC` (box sums over
//!    integral images), averaged over the `top_k` best sources (Kang, Szeliski & Chai, CVPR
//!    2001: the best subset of views drops the ones that see an occluder there). A parabola
//!    through the best plane and its neighbours refines the depth; a depth is kept when its
//!    cost is below `max_cost`. Windows with a grey standard deviation below `min_std` (no
//!    texture) and windows holding a non-finite pixel give no cost.
//!
//!    1b. *Slanted windows* (`slant_iters`, [`slant`]): PatchMatch stereo (Bleyer, Rhemann &
//!    Rother, BMVC 2011) starting from the sweep's depths gives each pixel a plane of its own
//!    orientation, so that a window on a surface the camera grazes is warped as that surface
//!    is. Measured on `cup` against the true depth (all depths after the fills, 3 passes
//!    against none): on the outer wall 95.4 % within 2 mm along the ray against 86.4 %, 1.8 %
//!    more than 2 mm behind against 6.6 %; on the inner wall 93.9 % against 87.0 %; the median
//!    error of the stereo's depths within 2 mm 0.21 against 0.48 mm
//!    (`results/geometry/slanted-stereo-2026-11-29`).
//! 2. *Geometric consistency* (COLMAP, Schönberger et al., ECCV 2016, §4.3 and
//!    `src/colmap/mvs/fusion.cc`): a depth is kept when at least `min_consistent` sources'
//!    depths, at its reprojection, map back within `px_tol` pixels and `rel_tol·z` of it.
//! 3. *Fusion fill*: a window next to an occluding contour holds both sides, so the pixels just
//!    behind a contour get no consistent depth, while another view sees the same points away
//!    from any contour (on `cup`: 62 % of the pixels behind the rim had none). Every kept depth
//!    becomes a world point carrying its grey value; each view splats all other views' points
//!    with radius `fuse_radius` pixels. A pixel without depth takes the nearest cluster of at
//!    least `fuse_support` splats within `fuse_depth_tol` whose mean grey matches its own within
//!    `fuse_grey_tol` (a nearer cluster of another grey is a splat bleeding over the contour, or
//!    an occluder another view reconstructed, and is passed over). Measured on `cup` against
//!    the true depth: the fill takes the masked pixels with a depth from 71 % to 90 %; 70 % of
//!    the filled depths lie within 2 mm of the truth, 7 % more than 2 mm behind it; of the
//!    97 k pixels just behind an occluding contour, 34 k get a depth within 2 mm, against 14 k
//!    without the fill (`results/geometry/depth-prior-2026-11-27`).
//! 4. *Hole fill* (the interpolation of Hirschmüller's semi-global matching, IEEE PAMI 30(2),
//!    2008: an occluded pixel takes the background's disparity found along 8 directions, a
//!    mismatched one their median): what is still missing is mostly a pixel seen by one view
//!    only (the cup's bottom just behind the near rim, which the sources see hidden) and the
//!    inside of a patch without texture. Each masked pixel without a depth takes the nearest
//!    depth within `hole_radius` pixels along each of 8 directions (stopping at the mask's
//!    edge). When they spread by at most `hole_jump` of the farthest they are one surface (a
//!    patch without texture); otherwise the pixel is behind an occluding contour and keeps
//!    the farthest group of at least two depths within `hole_tol` of each other (the
//!    background; two, not one, so that one stray far depth cannot win). The pixel takes the
//!    plane `1/z = a·x + b·y + c` (a plane in the camera frame) fitted to the group, or its
//!    mean for fewer than three. With `hole_grey_tol`, of the groups whose mean grey matches the
//!    pixel's, the best (a pixel on a thin part in front of the object is not background).
//!    Measured on `cup`: the masked pixels with a depth go from 90 % to 99 %, and the cup from
//!    1.70 to 1.27 mm at weight 5, though only about half the filled depths lie within 2 mm of
//!    the truth (a plane through the border of a convex patch lies behind it)
//!    (`results/geometry/depth-holes-2026-11-28`).
//!    *Refit* (`hole_refine` rounds): a group is 2 to 8 depths, often all on one side of the
//!    hole (behind the cup's rim: the floor found only upwards, where it lies farther), so its
//!    plane extrapolates badly. Seeded by it, the plane is refitted to every depth of the
//!    pixel's window within `hole_tol` of it, as RANSAC's consensus step; the result is kept
//!    when it lies beyond the nearest depth found and within 5 % of the farthest. On `cup` the
//!    filled depths within 2 mm of the truth go from 60 % to 79 % (inner wall) and 60 % to
//!    76 % (outer wall); the cup goes from 1.27 to 1.19 mm at weight 5, seed 0, but from
//!    1.24 to 1.27 at seed 1 (`results/geometry/hole-refit-2026-11-28`).
//! 5. *Free-space check and march of the hole fill* (`free_tol`, `cast_radius`): the groups of
//!    step 4 are candidates in order of preference, and a candidate is passed over when at
//!    least `free_views` other views see past its point (their consistent depth from step 2
//!    lies more than `free_tol` of its camera depth beyond it: the free-space constraint of
//!    Merrell et al., ICCV 2007). On `cup` what fails is a pixel of the bottom just behind the
//!    near rim whose window holds no bottom at all: every group is the rim or a wall in front.
//!    When every candidate fails, the pixel's ray is marched from the preferred candidate's
//!    depth outwards through the *surfels* of all views' consistent depths (one per voxel of
//!    `cast_radius / 8`, with the direction they were seen from): at each step the plane
//!    fitted to the surfels within `cast_radius` seen from the ray's side, where the ray
//!    crosses it, is the depth, when the check accepts it. Other views see the bottom around
//!    the strip this view alone sees, so in 3D the strip is a gap to bridge, not a border to
//!    extrapolate past. Measured on `cup` against the true depth: hole-filled bottom pixels
//!    within 2 mm go from 64 % to 91 %, the bottom's pixels more than 10 mm in front of it
//!    from 3 355 to 1 190; the cup goes from 1.190 / 1.271 to 1.118 / 1.211 mm at weight 5
//!    (seeds 0 / 1) and to 0.970 / 1.045 at weight 10. The other scenes of the suite move
//!    both ways by up to a third, as between two seeds (mean ratio to the floor without cup
//!    2.11× → 2.17× at seed 0, 2.01× → 2.19× at seed 1) (`results/geometry/free-space-2026-11-28`).
//!
//! **The loss** ([`DepthPrior`]): from `start_step` to `end_step`, the first `rays` masked rays
//! of each batch whose pixel has a depth `t_d` find the field's first surface crossing `t*`
//! (the multi-view prior's surface search); the span `[t*, t_d − margin]` is held free, points
//! `spacing` apart asked for `f ≥ min(tau, (t_d − t)/2)` (a hinge: free-space carving), and the
//! point at `t_d` is pulled to `f = 0` (the sparse-point SDF loss of Geo-NeuS, Fu et al.,
//! NeurIPS 2022, §3.2) with `surface_weight`. `L = weight · mean over the rays of (mean hinge +
//! surface_weight·|f(x(t_d))|)`: [`super::multiview::carve_loss_grad`], whose gradient a
//! finite-difference test checks (`tests/field_grad.rs`). Distances are in the normalised frame.
//!
//! What it costs: one sweep before training (`cup`, 46 views of 400 × 300, 128 planes, 4
//! sources: 14 s on 2 Zen 5 cores, plus 5 s for the fill), the slanted windows (3 passes: about
//! 45 s on 2 Zen 3 cores, where the rest takes about 40 s) and a surface search of `rays` rays
//! per step.

mod slant;

use super::data::Batch;
use super::multiview::{
    carve_loss_grad, masked_rays, ramp_weight, sdf_f64, surface_hits, CarveConfig, CarvedRay,
};
use crate::augment::luma;
use crate::field::Real;
use crate::render::NeusModel;
use crate::scene::{Camera, GrayImage, RgbImage};
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Settings of the stereo that makes the depth maps (`[train.depth.mvs]`). Defaults: the
/// setting `m3` of `results/geometry/cup-depth-2026-11-27` plus the fusion fill.
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
    /// Fusion fill: splat radius in pixels (1; 0: no fill). At weight 5 the fill takes cup
    /// from 2.16 to 1.70 mm and costs rods, 0.42 to 0.57 mm: it helps cavities and can fill a
    /// thin part's edge with the depth behind it.
    pub fuse_radius: f32,
    /// ... splats a cluster needs (2) ...
    pub fuse_support: usize,
    /// ... the cluster's depth extent, normalised units (0.01) ...
    pub fuse_depth_tol: f32,
    /// ... and how far its mean grey may lie from the pixel's (0.01; grey in `[0, 1]`).
    pub fuse_grey_tol: f32,
    /// Hole fill (step 4 of the module doc): how far, in pixels, a pixel still without a depth
    /// looks along each of 8 directions for one (10; 0: no hole fill). At weight 5 it takes
    /// cup from 1.70 to 1.27 mm and the suite's mean ratio to the floor from 2.73× to 2.51×.
    pub hole_radius: usize,
    /// ... below this spread of the depths found (a share of the farthest) they are one
    /// surface and all of them are fitted (0.02) ...
    pub hole_jump: f32,
    /// ... above it the pixel takes the farthest group of at least two depths within this
    /// share of each other (0.01) ...
    pub hole_tol: f32,
    /// ... or, when this is positive, of the groups whose mean grey lies within it of the
    /// pixel's, the one that matches best, and none when none does (0.1; grey in `[0, 1]`): a
    /// pixel without a depth on a thin part in front of the object is not background. At
    /// weight 5, 0 against 0.1: thin 0.62 against 0.51 mm, blocks 0.79 against 0.72, cup 1.24
    /// against 1.27 (`results/geometry/depth-holes-2026-11-28`).
    pub hole_grey_tol: f32,
    /// ... and the plane through the chosen depths is refitted this many rounds to every depth
    /// of the pixel's `(2·hole_radius + 1)²` window within `hole_tol` of it (2; 0: no refit).
    /// A group holds 2 to 8 depths, all at one side of a hole; the window holds the surface's
    /// many other depths around it. On `cup` the share of filled depths within 2 mm of the
    /// truth goes from 60 % to 79 % on the inner wall and from 60 % to 76 % on the outer wall
    /// (`results/geometry/hole-refit-2026-11-28`).
    pub hole_refine: usize,
    /// Free-space check of the hole fill (step 5 of the module doc): a candidate depth is
    /// passed over when at least `free_views` other views see past its point, their
    /// consistent stereo depth at its pixel lying more than this share of its camera depth
    /// beyond it (0.02; 0: no check, the preferred group's depth is taken as it is).
    pub free_tol: f32,
    /// ... how many views must see past it (2) ...
    pub free_views: usize,
    /// ... and when every candidate fails, the pixel's ray is marched from the preferred
    /// one's depth through the surfels of every view's consistent depths within this radius
    /// (normalised units; 0.25, about a quarter of the object's bounding radius; 0: no
    /// march, the pixel stays empty).
    pub cast_radius: f32,
    /// Slanted windows (step 1b of the module doc, [`slant`]): passes of PatchMatch over each
    /// view after the sweep (3; 0: none, the sweep's fronto-parallel windows alone). On `cup`
    /// (`fast`, weight 10) 3 passes take the Chamfer sum from 0.970 / 1.045 / 1.150 to
    /// 0.886 / 0.950 / 0.933 mm at seeds 0 / 1 / 2, with `surface_weight` 0.2, and cost 45 s
    /// more of the stereo on a 2-core Zen 3 (`results/geometry/slanted-stereo-2026-11-29`).
    /// The automatic switch's check ([`sweep_depths`]) does without them.
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

/// Settings of the depth prior (`[train.depth]`). Absent from a config's text while it is the
/// default (off), so configs and training hashes without it are unchanged.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DepthConfig {
    /// Weight of the loss (0: off, unless `auto` switches it on). Measured at `fast`, seed 0,
    /// with the hole fill: 5 gives the suite a mean ratio to the floor of 2.14× without cup
    /// (2.20× off) and cup 1.27 mm (4.81 off; 1.24 at seed 1); without the hole fill cup
    /// wanted 20–40 (1.37–1.47 mm), which cost the other scenes and their genus
    /// (`results/geometry/depth-prior-2026-11-27`, `results/geometry/depth-holes-2026-11-28`).
    /// With the hole fill's refit and free-space check, cup 1.118 / 1.211 mm at 5 and
    /// 0.970 / 1.045 at 10 (seeds 0 / 1; 1.07 at 20, scratch)
    /// (`results/geometry/free-space-2026-11-28`). Over the rest of the suite 10 costs
    /// nothing against 5 (mean ratio without cup 2.17× / 2.19× at seeds 0 / 1 at both weights),
    /// so 10 is the weight to pass; thin parts lose against off (rods 1.47× → 2.03× at seed 0)
    /// (`results/geometry/w10-suite-2026-11-28`).
    pub weight: f32,
    /// Weight of the `|f(x(t_d))|` term against the hinge's (0.5). With the sweep's
    /// fronto-parallel windows 0.2 was best: without the term (0) the cup gave 1.87 / 1.53 mm
    /// at weight 10, and 0.5 / 1.0 took in the stereo's errors (1.079 at seed 0; 1.09 / 1.10)
    /// (`results/geometry/w10-suite-2026-11-28`, `results/geometry/one-view-2026-11-28`,
    /// `results/geometry/cup-grazing-2026-11-28`). With the slanted windows (`mvs.slant_iters`)
    /// the depths are good enough to pull the surface to: cup 0.876 / 0.854 / 0.891 mm at 0.5
    /// against 0.886 / 0.950 / 0.933 at 0.2 (seeds 0 / 1 / 2;
    /// `results/geometry/slanted-stereo-2026-11-29`).
    pub surface_weight: f32,
    /// First step that applies it (200).
    pub start_step: u64,
    /// Last step that applies it (absent: to the end).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub end_step: Option<u64>,
    /// Weight at the run's last step: the weight goes linearly from `weight` at `start_step`
    /// to this at the last step (absent: constant `weight`), as `train.multiview.final_weight`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_weight: Option<f32>,
    /// Rays per step: the first of the batch inside the mask (256).
    pub rays: usize,
    /// The SDF the hinge asks for in the free span, normalised units (0.01).
    pub tau: f32,
    /// Spacing of the free span's points, normalised units (0.00625).
    pub spacing: f32,
    /// The free span stops this far in front of the depth, normalised units (0.0125).
    pub margin: f32,
    /// Evenly spaced SDF samples of the surface search along each ray (128).
    pub march_samples: usize,
    /// Illinois refinement steps of each bracketed crossing (6).
    pub refine: usize,
    /// The stereo.
    pub mvs: MvsConfig,
    /// The automatic switch: with `weight` 0, whether a check part-way through the run turns
    /// the prior on ([`super::depth_auto`]).
    pub auto: super::depth_auto::DepthAutoConfig,
}

impl Default for DepthConfig {
    fn default() -> Self {
        Self {
            weight: 0.0,
            surface_weight: 0.5,
            start_step: 200,
            end_step: None,
            final_weight: None,
            rays: 256,
            tau: 0.01,
            spacing: 0.00625,
            margin: 0.0125,
            march_samples: 128,
            refine: 6,
            mvs: MvsConfig::default(),
            auto: Default::default(),
        }
    }
}

impl DepthConfig {
    /// Whether this is the default (the section is then left out of the config text).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// Whether the prior runs at all.
    pub fn enabled(&self) -> bool {
        self.weight > 0.0
    }

    /// Whether it applies at `step`.
    pub fn active_at(&self, step: u64) -> bool {
        self.enabled() && step >= self.start_step && self.end_step.is_none_or(|e| step <= e)
    }

    /// The weight at `step` of a run of `iterations` steps (0 where it does not apply).
    pub fn weight_at(&self, step: u64, iterations: u64) -> f32 {
        if !self.active_at(step) {
            return 0.0;
        }
        ramp_weight(
            self.weight,
            self.final_weight,
            self.start_step,
            step,
            iterations,
        )
    }

    /// The first invalid field, as `(key, value, why)`.
    pub fn invalid(&self) -> Option<(&'static str, String, &'static str)> {
        let pos = |v: f32| v.is_finite() && v > 0.0;
        let nonneg = |v: f32| v.is_finite() && v >= 0.0;
        let m = &self.mvs;
        let c = |key, ok, value: &dyn std::fmt::Display, why| (key, ok, value.to_string(), why);
        let checks = [
            c(
                "train.depth.weight",
                nonneg(self.weight),
                &self.weight,
                "must be ≥ 0",
            ),
            c(
                "train.depth.final_weight",
                self.final_weight.is_none_or(nonneg),
                &self.final_weight.map_or("none".into(), |w| w.to_string()),
                "must be ≥ 0",
            ),
            c(
                "train.depth.surface_weight",
                nonneg(self.surface_weight),
                &self.surface_weight,
                "must be ≥ 0",
            ),
            c(
                "train.depth.rays",
                self.rays > 0,
                &self.rays,
                "must be at least 1",
            ),
            c(
                "train.depth.tau",
                pos(self.tau),
                &self.tau,
                "must be positive (normalised units)",
            ),
            c(
                "train.depth.spacing",
                pos(self.spacing),
                &self.spacing,
                "must be positive (normalised units)",
            ),
            c(
                "train.depth.margin",
                nonneg(self.margin),
                &self.margin,
                "must be ≥ 0 (normalised units)",
            ),
            c(
                "train.depth.march_samples",
                self.march_samples >= 2,
                &self.march_samples,
                "must be at least 2",
            ),
            c(
                "train.depth.mvs.planes",
                (2..=4096).contains(&m.planes),
                &m.planes,
                "must be in 2..=4096",
            ),
            c(
                "train.depth.mvs.sources",
                m.sources > 0,
                &m.sources,
                "must be at least 1",
            ),
            c(
                "train.depth.mvs.top_k",
                (1..=m.sources).contains(&m.top_k),
                &m.top_k,
                "must be in 1..=train.depth.mvs.sources",
            ),
            c(
                "train.depth.mvs.window_half",
                (1..=10).contains(&m.window_half),
                &m.window_half,
                "must be in 1..=10",
            ),
            c(
                "train.depth.mvs.max_cost",
                pos(m.max_cost),
                &m.max_cost,
                "must be positive",
            ),
            c(
                "train.depth.mvs.min_std",
                nonneg(m.min_std),
                &m.min_std,
                "must be ≥ 0",
            ),
            c(
                "train.depth.mvs.min_consistent",
                m.min_consistent <= m.sources,
                &m.min_consistent,
                "must be at most train.depth.mvs.sources",
            ),
            c(
                "train.depth.mvs.rel_tol",
                pos(m.rel_tol),
                &m.rel_tol,
                "must be positive",
            ),
            c(
                "train.depth.mvs.px_tol",
                pos(m.px_tol),
                &m.px_tol,
                "must be positive (pixels)",
            ),
            c(
                "train.depth.mvs.depth_radius",
                pos(m.depth_radius),
                &m.depth_radius,
                "must be positive (normalised units)",
            ),
            c(
                "train.depth.mvs.fuse_radius",
                nonneg(m.fuse_radius) && m.fuse_radius <= 8.0,
                &m.fuse_radius,
                "must be in [0, 8] (pixels)",
            ),
            c(
                "train.depth.mvs.fuse_support",
                m.fuse_support > 0,
                &m.fuse_support,
                "must be at least 1",
            ),
            c(
                "train.depth.mvs.fuse_depth_tol",
                pos(m.fuse_depth_tol),
                &m.fuse_depth_tol,
                "must be positive (normalised units)",
            ),
            c(
                "train.depth.mvs.fuse_grey_tol",
                pos(m.fuse_grey_tol),
                &m.fuse_grey_tol,
                "must be positive",
            ),
            c(
                "train.depth.mvs.hole_radius",
                m.hole_radius <= 64,
                &m.hole_radius,
                "must be in 0..=64 (pixels)",
            ),
            c(
                "train.depth.mvs.hole_jump",
                pos(m.hole_jump),
                &m.hole_jump,
                "must be positive",
            ),
            c(
                "train.depth.mvs.hole_tol",
                pos(m.hole_tol),
                &m.hole_tol,
                "must be positive",
            ),
            c(
                "train.depth.mvs.hole_grey_tol",
                nonneg(m.hole_grey_tol),
                &m.hole_grey_tol,
                "must be ≥ 0",
            ),
            c(
                "train.depth.mvs.hole_refine",
                m.hole_refine <= 8,
                &m.hole_refine,
                "must be in 0..=8 (rounds)",
            ),
            c(
                "train.depth.mvs.free_tol",
                nonneg(m.free_tol) && m.free_tol < 1.0,
                &m.free_tol,
                "must be in [0, 1)",
            ),
            c(
                "train.depth.mvs.free_views",
                m.free_views > 0,
                &m.free_views,
                "must be at least 1",
            ),
            c(
                "train.depth.mvs.slant_iters",
                m.slant_iters <= 16,
                &m.slant_iters,
                "must be in 0..=16 (passes)",
            ),
            c(
                "train.depth.mvs.cast_radius",
                nonneg(m.cast_radius) && m.cast_radius <= 1.0,
                &m.cast_radius,
                "must be in [0, 1] (normalised units)",
            ),
        ];
        if let Some((key, _, value, why)) = checks.into_iter().find(|c| !c.1) {
            return Some((key, value, why));
        }
        self.auto.invalid()
    }

    /// This prior as the automatic switch turns it on after step `check_step`: weight
    /// `auto.weight` (to `final_weight` when one is set), from the later of `start_step` and
    /// `check_step` (the first step after the check).
    pub fn switched_on(&self, check_step: u64) -> Self {
        Self {
            weight: self.auto.weight,
            start_step: self.start_step.max(check_step),
            ..self.clone()
        }
    }
}

/// Per view, the distance `t` along the unit ray through each pixel centre to the surface
/// (normalised units; NaN: no depth), and which depths the fusion fill gave.
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
/// (optional) limit the pixels looked at. See the module doc for the three steps.
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
/// [`DepthMaps::t`] gives depths: per view of `which`, the distance along the unit ray through
/// each pixel centre (normalised units; NaN: no depth, or outside the mask). The sources come
/// from every view, as in [`depth_maps`]; only `which` are swept, so this costs
/// `which.len() / cameras.len()` of step 1 (`cup`, 8 of 46 views: 2.1 s on 2 cores, against
/// 14 s). What the depth prior's automatic switch ([`super::depth_auto`]) looks at.
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

/// Step 1 of the module doc for view `i`: its camera `z` per pixel (NaN: none).
fn sweep_view(cfg: &MvsConfig, views: &[View], i: usize, srcs: &[usize]) -> Vec<f32> {
    let vi = &views[i];
    let (w, h, hf) = (vi.w, vi.h, cfg.window_half);
    let mut zmap = vec![f32::NAN; w * h];
    // The mask's bounding box, widened by the window.
    let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
    for (k, _) in vi.mask.iter().enumerate().filter(|m| *m.1) {
        let (x, y) = (k % w, k / w);
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
    }
    if x0 >= x1 || srcs.len() < cfg.top_k {
        return zmap;
    }
    let (bx0, by0) = (x0.saturating_sub(hf), y0.saturating_sub(hf));
    let (bx1, by1) = ((x1 + hf).min(w), (y1 + hf).min(h));
    let (bw, bh) = (bx1 - bx0, by1 - by0);
    let a: Vec<f64> = (0..bw * bh)
        .map(|k| vi.grey[(by0 + k / bw) * w + bx0 + k % bw] as f64)
        .collect();
    let finite = |v: f64| if v.is_finite() { v } else { 0.0 };
    let a_bad = integral(bw, bh, |k| if a[k].is_finite() { 0.0 } else { 1.0 });
    let sa = integral(bw, bh, |k| finite(a[k]));
    let saa = integral(bw, bh, |k| finite(a[k]) * finite(a[k]));
    // Camera depths of the bounding sphere.
    let zc = vi.r.row(2).transpose().dot(&(-vi.c));
    let rad = cfg.depth_radius as f64;
    let (zn, zf) = ((zc - rad).max(1e-3 * rad), zc + rad);
    let dz = (zf - zn) / cfg.planes as f64;
    // Per source: `A·p` per pixel and `b`, so that pixel `p` at depth `z` maps to `z·A·p + b`.
    let setups: Vec<(Vec<Vector3<f64>>, Vector3<f64>)> = srcs
        .iter()
        .map(|&j| {
            let (am, b) = vi.warp_to(&views[j]);
            let ap = (0..bw * bh)
                .map(|k| {
                    let (x, y) = ((bx0 + k % bw) as f64 + 0.5, (by0 + k / bw) as f64 + 0.5);
                    am * Vector3::new(x, y, 1.0)
                })
                .collect();
            (ap, b)
        })
        .collect();
    let nwin = ((2 * hf + 1) * (2 * hf + 1)) as f64;
    let min_var = (cfg.min_std as f64).powi(2) * nwin;
    // The masked pixels whose window lies inside the box.
    let pix: Vec<(usize, usize)> = (y0.max(by0 + hf)..y1.min(by1 - hf))
        .flat_map(|y| (x0.max(bx0 + hf)..x1.min(bx1 - hf)).map(move |x| (x, y)))
        .filter(|&(x, y)| vi.mask[y * w + x])
        .collect();
    let np = pix.len();
    let ns = srcs.len();
    // Per pixel, streamed over the planes (no `pixels × planes` table: 1 GB for a 1600 × 1200
    // view): the best cost, its plane, the costs of the planes either side, and the last cost.
    let mut best = vec![(f32::INFINITY, usize::MAX, f32::NAN, f32::NAN); np];
    let mut prev = vec![f32::NAN; np];
    let mut per = vec![f32::NAN; np * ns];
    let mut wv = vec![0f64; bw * bh];
    for pl in 0..cfg.planes {
        let zp = zn + (pl as f64 + 0.5) * dz;
        for (s, (ap, b)) in setups.iter().enumerate() {
            let vj = &views[srcs[s]];
            for (k, out) in wv.iter_mut().enumerate() {
                let hh = ap[k] * zp + b;
                *out = if hh.z > 1e-9 {
                    vj.bilinear(hh.x / hh.z, hh.y / hh.z) as f64
                } else {
                    f64::NAN
                };
            }
            let bad = integral(bw, bh, |k| if wv[k].is_finite() { 0.0 } else { 1.0 });
            let sb = integral(bw, bh, |k| finite(wv[k]));
            let sbb = integral(bw, bh, |k| finite(wv[k]) * finite(wv[k]));
            let sab = integral(bw, bh, |k| finite(wv[k]) * finite(a[k]));
            for (q, &(x, y)) in pix.iter().enumerate() {
                let (lx, ly) = (x - bx0, y - by0);
                let (xa, ya, xb, yb) = (lx - hf, ly - hf, lx + hf + 1, ly + hf + 1);
                let c = if box_sum(&bad, bw, xa, ya, xb, yb) > 0.5
                    || box_sum(&a_bad, bw, xa, ya, xb, yb) > 0.5
                {
                    f32::NAN
                } else {
                    let s_a = box_sum(&sa, bw, xa, ya, xb, yb);
                    let s_b = box_sum(&sb, bw, xa, ya, xb, yb);
                    let va = box_sum(&saa, bw, xa, ya, xb, yb) - s_a * s_a / nwin;
                    let vb = box_sum(&sbb, bw, xa, ya, xb, yb) - s_b * s_b / nwin;
                    if va < min_var || vb < min_var || va <= 0.0 || vb <= 0.0 {
                        f32::NAN
                    } else {
                        let cov = box_sum(&sab, bw, xa, ya, xb, yb) - s_a * s_b / nwin;
                        (1.0 - cov / (va * vb).sqrt()) as f32
                    }
                };
                per[q * ns + s] = c;
            }
        }
        let mut cs = Vec::with_capacity(ns);
        for q in 0..np {
            cs.clear();
            cs.extend(
                per[q * ns..(q + 1) * ns]
                    .iter()
                    .copied()
                    .filter(|c| c.is_finite()),
            );
            let c = top_k_mean(&mut cs, cfg.top_k);
            let b = &mut best[q];
            if c < b.0 {
                *b = (c, pl, prev[q], f32::NAN);
            } else if pl > 0 && b.1 == pl - 1 {
                b.3 = c;
            }
            prev[q] = c;
        }
    }
    for (q, &(x, y)) in pix.iter().enumerate() {
        let (bc, bp, cm, cp) = best[q];
        if bp == usize::MAX || bc > cfg.max_cost {
            continue;
        }
        let mut off = 0.0;
        if bp > 0 && bp + 1 < cfg.planes {
            let den = cm - 2.0 * bc + cp;
            if cm.is_finite() && cp.is_finite() && den > 1e-6 {
                off = (0.5 * (cm - cp) / den).clamp(-0.5, 0.5) as f64;
            }
        }
        zmap[y * w + x] = (zn + (bp as f64 + 0.5 + off) * dz) as f32;
    }
    zmap
}

/// The mean of the `k` smallest of `costs` (sorted in place): a plane's cost over its sources
/// (step 1). NaN when `costs` holds fewer than `k`.
fn top_k_mean(costs: &mut [f32], k: usize) -> f32 {
    if costs.len() < k {
        return f32::NAN;
    }
    costs.sort_by(|a, b| a.total_cmp(b));
    costs[..k].iter().sum::<f32>() / k as f32
}

/// Step 2 of the module doc: the camera-`z` maps keeping the depths at least
/// `min_consistent` sources agree with.
fn consistent(
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
fn fuse(cfg: &MvsConfig, views: &[View], z: &[Vec<f32>]) -> (Vec<Vec<f32>>, Vec<Vec<bool>>) {
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

/// A depth the hole fill found: `(camera z, dx, dy, grey there)`, offsets in pixels.
type Found = (f64, f64, f64, f64);

/// Steps 4 and 5 of the module doc for one view of `w × h` pixels: its camera-`z` map `z` with
/// the holes inside `mask` filled, and which pixels the fill gave. `grey`: `[y * w + x]`, as
/// the view's. `free(k, z)`: whether pixel `k`'s point at camera depth `z` passes the
/// free-space check (the candidates are tried in order of preference); `cast(k, z0)`: the
/// march's depth for pixel `k` from the preferred candidate's `z0`, asked only when every
/// candidate fails. Without the check: `|_, _| true` and `|_, _| None`.
#[allow(clippy::too_many_arguments)]
fn fill_holes(
    cfg: &MvsConfig,
    w: usize,
    h: usize,
    mask: &[bool],
    grey: &[f32],
    z: &[f32],
    free: impl Fn(usize, f64) -> bool,
    cast: impl Fn(usize, f64) -> Option<f64>,
) -> (Vec<f32>, Vec<bool>) {
    const DIRS: [(isize, isize); 8] = [
        (1, 0),
        (-1, 0),
        (0, 1),
        (0, -1),
        (1, 1),
        (-1, -1),
        (1, -1),
        (-1, 1),
    ];
    let (wi, hi) = (w as isize, h as isize);
    let (jump, tol) = (cfg.hole_jump as f64, cfg.hole_tol as f64);
    let gtol = cfg.hole_grey_tol as f64;
    let mut out = z.to_vec();
    let mut filled = vec![false; z.len()];
    // Per direction the nearest depth: (z, dx, dy, grey there), farthest first once sorted.
    let mut found: Vec<Found> = Vec::with_capacity(8);
    // The candidate groups of `found`: (start, end, grey distance), preferred first.
    let mut groups: Vec<(usize, usize, f64)> = Vec::with_capacity(8);
    for k in 0..z.len() {
        if !mask[k] || z[k].is_finite() {
            continue;
        }
        let (x, y) = ((k % w) as isize, (k / w) as isize);
        found.clear();
        for (dx, dy) in DIRS {
            for s in 1..=cfg.hole_radius as isize {
                let (xx, yy) = (x + dx * s, y + dy * s);
                if xx < 0 || yy < 0 || xx >= wi || yy >= hi {
                    break;
                }
                let q = (yy * wi + xx) as usize;
                if !mask[q] {
                    break;
                }
                if z[q].is_finite() {
                    let (ox, oy) = ((dx * s) as f64, (dy * s) as f64);
                    found.push((z[q] as f64, ox, oy, grey[q] as f64));
                    break;
                }
            }
        }
        if found.len() < 2 {
            continue;
        }
        found.sort_by(|a, b| b.0.total_cmp(&a.0));
        let far = found[0].0;
        let near = found[found.len() - 1].0;
        groups.clear();
        if far - near <= jump * far {
            groups.push((0, found.len(), 0.0));
        } else {
            // Farthest first; with the grey test only those whose mean grey lies within it of
            // the pixel's, the nearest in grey first (on a tie, the farther).
            let mut a = 0;
            while a + 1 < found.len() {
                let n = found[a..]
                    .iter()
                    .take_while(|f| found[a].0 - f.0 <= tol * found[a].0)
                    .count();
                if n < 2 {
                    a += 1;
                    continue;
                }
                let g = &found[a..a + n];
                let gm = g.iter().map(|f| f.3).sum::<f64>() / n as f64;
                let d = (gm - grey[k] as f64).abs();
                if gtol <= 0.0 {
                    groups.push((a, a + n, 0.0));
                } else if d < gtol {
                    groups.push((a, a + n, d));
                }
                a += n;
            }
            groups.sort_by(|a, b| a.2.total_cmp(&b.2));
        }
        let mut preferred = None;
        let mut pick = None;
        for &(g0, g1, _) in &groups {
            let group = &found[g0..g1];
            let fit = fit_inverse_plane(group);
            let mut zk = plane_through(group, fit);
            if cfg.hole_refine > 0 {
                let seed = fit.unwrap_or(Vector3::new(0.0, 0.0, 1.0 / zk));
                if let Some(zr) = refit_plane(cfg, w, h, mask, z, (x, y), seed) {
                    // A background depth lies beyond the occluder's, and no fill lies far
                    // behind everything it was found from.
                    if zr > near && zr < 1.05 * far {
                        zk = zr;
                    }
                }
            }
            preferred.get_or_insert(zk);
            if free(k, zk) {
                pick = Some(zk);
                break;
            }
        }
        let Some(zk) = pick.or_else(|| cast(k, preferred?)) else {
            continue;
        };
        out[k] = zk as f32;
        filled[k] = true;
    }
    (out, filled)
}

/// Step 5 of the module doc: whether fewer than `cfg.free_views` views other than `i` see
/// past the world point `x` (normalised frame): their depth in `evidence[j]` (camera `z`, NaN:
/// none) at the pixel `x` falls in lies beyond `x`'s camera depth by more than `cfg.free_tol`
/// of it. The free-space constraint of visibility-based depth-map fusion (Merrell et al.,
/// ICCV 2007, §4: a point that another view's depth ray passes through is not on a surface).
fn free_of_others(
    cfg: &MvsConfig,
    views: &[View],
    evidence: &[Vec<f32>],
    i: usize,
    x: &Vector3<f64>,
) -> bool {
    let mut past = 0;
    for (j, vj) in views.iter().enumerate() {
        if j == i {
            continue;
        }
        let (u, v, zj) = vj.project(x);
        if !(u >= 0.0 && v >= 0.0 && zj > 0.0) {
            continue;
        }
        let (xj, yj) = (u as usize, v as usize);
        if xj >= vj.w || yj >= vj.h {
            continue;
        }
        if evidence[j][yj * vj.w + xj] as f64 > zj * (1.0 + cfg.free_tol as f64) {
            past += 1;
            if past >= cfg.free_views {
                return false;
            }
        }
    }
    true
}

/// Surfels a plane fit of [`SurfelCloud::plane_depth`] needs.
const CAST_MIN_SURFELS: usize = 10;

/// The world points of every view's consistent depths (normalised frame), thinned to one
/// per voxel of `radius / 8` (the mean of the voxel's points), each with the mean unit
/// direction towards the cameras that saw it, in a hash grid of cells of `radius`: what the
/// march of the hole fill (step 5) intersects its rays with.
struct SurfelCloud {
    /// `[surfel]` position.
    p: Vec<Vector3<f64>>,
    /// `[surfel]` unit direction towards the cameras that saw it.
    seen_from: Vec<Vector3<f64>>,
    radius: f64,
    /// Cell `floor(x / radius)` → the surfels in it.
    grid: std::collections::HashMap<[i64; 3], Vec<u32>>,
}

impl SurfelCloud {
    fn cell(x: &Vector3<f64>, size: f64) -> [i64; 3] {
        [
            (x.x / size).floor() as i64,
            (x.y / size).floor() as i64,
            (x.z / size).floor() as i64,
        ]
    }

    /// `z[j]`: view `j`'s camera-`z` map (NaN: none).
    fn new(views: &[View], z: &[Vec<f32>], radius: f64) -> Self {
        let voxel = radius / 8.0;
        let mut acc: std::collections::HashMap<[i64; 3], (Vector3<f64>, Vector3<f64>, u32)> =
            Default::default();
        for (v, m) in views.iter().zip(z) {
            for (k, &zz) in m.iter().enumerate() {
                if !zz.is_finite() {
                    continue;
                }
                let p = v.point(k, zz as f64);
                let e = acc.entry(Self::cell(&p, voxel)).or_insert((
                    Vector3::zeros(),
                    Vector3::zeros(),
                    0,
                ));
                e.0 += p;
                e.1 += (v.c - p).normalize();
                e.2 += 1;
            }
        }
        // Sorted voxels: the same surfels in the same order whatever the map's hashing.
        let mut voxels: Vec<_> = acc.into_iter().filter(|(_, a)| a.2 >= 2).collect();
        voxels.sort_unstable_by_key(|(key, _)| *key);
        let mut cloud = SurfelCloud {
            p: Vec::with_capacity(voxels.len()),
            seen_from: Vec::with_capacity(voxels.len()),
            radius,
            grid: Default::default(),
        };
        for (_, (sp, sd, n)) in voxels {
            let p = sp / n as f64;
            cloud
                .grid
                .entry(Self::cell(&p, radius))
                .or_default()
                .push(cloud.p.len() as u32);
            cloud.p.push(p);
            cloud.seen_from.push(sd.normalize());
        }
        cloud
    }

    /// The camera `z` where the ray of pixel `k` of `v` (direction `d`, camera `z` = 1)
    /// crosses the plane fitted to the surfels within `radius` of its point at camera depth
    /// `z` that were seen from the ray's side (their direction towards the cameras against
    /// the ray's: cosine below −0.2). `None` with fewer than [`CAST_MIN_SURFELS`] of them,
    /// when they do not lie on a plane (the smallest eigenvalue of their scatter above 5 % of
    /// the middle one), or when the ray runs along the plane.
    fn plane_depth(&self, v: &View, d: &Vector3<f64>, z: f64) -> Option<f64> {
        let du = d.normalize();
        let x0 = v.c + d * z;
        let [cx, cy, cz] = Self::cell(&x0, self.radius);
        // Sums of the offsets from `x0` (within the radius: no cancellation to speak of).
        let (mut n, mut s1, mut s2) = (0usize, Vector3::zeros(), Matrix3::zeros());
        for a in -1..=1 {
            for b in -1..=1 {
                for c in -1..=1 {
                    for &i in self
                        .grid
                        .get(&[cx + a, cy + b, cz + c])
                        .into_iter()
                        .flatten()
                    {
                        let (q, s) = (self.p[i as usize] - x0, self.seen_from[i as usize]);
                        if q.norm_squared() <= self.radius * self.radius && s.dot(&du) < -0.2 {
                            n += 1;
                            s1 += q;
                            s2 += q * q.transpose();
                        }
                    }
                }
            }
        }
        if n < CAST_MIN_SURFELS {
            return None;
        }
        let m = s1 / n as f64;
        let c = x0 + m;
        let eig = (s2 - m * s1.transpose()).symmetric_eigen();
        let mut order = [0, 1, 2];
        order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        if eig.eigenvalues[order[0]] > 0.05 * eig.eigenvalues[order[1]] {
            return None;
        }
        let n: Vector3<f64> = eig.eigenvectors.column(order[0]).into();
        let den = n.dot(d);
        if den.abs() < 1e-9 {
            return None;
        }
        let zn = n.dot(&(c - v.c)) / den;
        zn.is_finite().then_some(zn)
    }

    /// Marches the ray of pixel `k` of `v` outwards from 2 % beyond camera depth `z0`, in steps
    /// of half the radius (at most 64), and returns the first [`Self::plane_depth`] that lies
    /// beyond that start, within the radius of the march point, and that `ok` accepts.
    fn cast(&self, v: &View, k: usize, z0: f64, ok: &dyn Fn(f64) -> bool) -> Option<f64> {
        let d = v.dir((k % v.w) as f64 + 0.5, (k / v.w) as f64 + 0.5);
        let (len, start) = (d.norm(), 1.02 * z0);
        let step = 0.5 * self.radius / len;
        (0..64).find_map(|s| {
            let z = start + s as f64 * step;
            let zn = self.plane_depth(v, &d, z)?;
            (zn > start && (zn - z).abs() * len <= self.radius && ok(zn)).then_some(zn)
        })
    }
}

/// Depths a refit needs inside its window.
const REFIT_MIN_DEPTHS: usize = 8;

/// The least-squares plane `1/z = a·dx + b·dy + c` (as `(a, b, c)`) through `samples` `(z, dx,
/// dy, _)`, when there are three or more and they span a plane.
fn fit_inverse_plane(samples: &[Found]) -> Option<Vector3<f64>> {
    if samples.len() < 3 {
        return None;
    }
    let mut ata = Matrix3::<f64>::zeros();
    let mut atb = Vector3::<f64>::zeros();
    for &(zz, dx, dy, _) in samples {
        let r = Vector3::new(dx, dy, 1.0);
        ata += r * r.transpose();
        atb += r / zz;
    }
    if ata.determinant().abs() <= 1e-6 {
        return None;
    }
    ata.try_inverse().map(|m| m * atb)
}

/// The camera `z` at pixel `(x, y)` of the plane `seed` (`1/z = a·dx + b·dy + c`, offsets from
/// `(x, y)` in pixels) refitted `cfg.hole_refine` rounds to the depths of `z` (camera `z`, NaN:
/// none) inside `mask` within `cfg.hole_radius` pixels (a square window) that lie within
/// `cfg.hole_tol` of the current plane: a consensus refit, as RANSAC's final step (Fischler &
/// Bolles, CACM 1981). `None` when a round finds fewer than [`REFIT_MIN_DEPTHS`] or they do
/// not span a plane.
fn refit_plane(
    cfg: &MvsConfig,
    w: usize,
    h: usize,
    mask: &[bool],
    z: &[f32],
    (x, y): (isize, isize),
    seed: Vector3<f64>,
) -> Option<f64> {
    let (wi, hi) = (w as isize, h as isize);
    let (r, tol) = (cfg.hole_radius as isize, cfg.hole_tol as f64);
    let mut p = seed;
    for _ in 0..cfg.hole_refine {
        let mut ata = Matrix3::<f64>::zeros();
        let mut atb = Vector3::<f64>::zeros();
        let mut n = 0;
        for yy in (y - r).max(0)..=(y + r).min(hi - 1) {
            for xx in (x - r).max(0)..=(x + r).min(wi - 1) {
                let q = (yy * wi + xx) as usize;
                let zq = z[q] as f64;
                if !zq.is_finite() || !mask[q] {
                    continue;
                }
                let row = Vector3::new((xx - x) as f64, (yy - y) as f64, 1.0);
                let zp = 1.0 / p.dot(&row);
                if zp > 0.0 && (zp - zq).abs() <= tol * zq {
                    ata += row * row.transpose();
                    atb += row / zq;
                    n += 1;
                }
            }
        }
        if n < REFIT_MIN_DEPTHS || ata.determinant().abs() <= 1e-6 {
            return None;
        }
        p = ata.try_inverse()? * atb;
    }
    let zz = 1.0 / p.z;
    zz.is_finite().then_some(zz)
}

/// The camera `z` at offset `(0, 0)` of `fit`, the plane [`fit_inverse_plane`] gives for
/// `samples` `(z, dx, dy, _)`, when there is one and the result lies within 1 % of their depth
/// range; the samples' mean depth otherwise.
fn plane_through(samples: &[Found], fit: Option<Vector3<f64>>) -> f64 {
    let mean = samples.iter().map(|s| s.0).sum::<f64>() / samples.len() as f64;
    let Some(p) = fit else {
        return mean;
    };
    let zz = 1.0 / p.z;
    let lo = samples.iter().map(|s| s.0).fold(f64::INFINITY, f64::min);
    let hi = samples.iter().map(|s| s.0).fold(0.0, f64::max);
    if zz.is_finite() && zz >= 0.99 * lo && zz <= 1.01 * hi {
        zz
    } else {
        mean
    }
}

/// A ray: origin and unit direction (normalised frame).
type Line = ([f64; 3], [f64; 3]);

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

/// What the depth prior did in one step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DepthStep {
    /// Rays looked at (masked, first of the batch).
    pub rays: usize,
    /// Of them, rays whose pixel has a depth.
    pub with_depth: usize,
    /// Of them, rays with a non-empty free span (the field crosses in front of the depth).
    pub carved: usize,
    /// The weighted loss.
    pub loss: f64,
}

/// The depth prior during training: the depth maps and the rays' cameras.
pub struct DepthPrior {
    cfg: DepthConfig,
    maps: DepthMaps,
    cameras: Vec<Camera>,
}

impl DepthPrior {
    /// The prior over `cameras` (normalised frame) with depth maps already made.
    pub fn new(cfg: DepthConfig, cameras: Vec<Camera>, maps: DepthMaps) -> Self {
        assert_eq!(cameras.len(), maps.t.len(), "one depth map per camera");
        Self { cfg, maps, cameras }
    }

    /// The depth maps.
    pub fn maps(&self) -> &DepthMaps {
        &self.maps
    }

    /// The rays' plan: for each of `rays` (`(view, [x, y])`) with a depth, its free span and
    /// surface point ([`CarvedRay`]; `t` the field's first crossing in the box `[-r, r]³`, or
    /// `t_d` when it has none). `sdf` evaluates the field; `eps` the normal's difference step.
    pub fn plan(
        &self,
        r: f32,
        sdf: &dyn Fn(&[[f64; 3]]) -> Vec<f64>,
        eps: f64,
        rays: &[(usize, [u32; 2])],
    ) -> (DepthStep, Vec<CarvedRay>) {
        let cfg = &self.cfg;
        let with: Vec<(Line, f64)> = rays
            .iter()
            .filter_map(|&(v, [x, y])| {
                let td = self.maps.get(v, x, y)?;
                let (o, d) = self.cameras[v].ray(x as f64 + 0.5, y as f64 + 0.5);
                Some(((o.into(), d.into()), td))
            })
            .collect();
        let lines: Vec<Line> = with.iter().map(|w| w.0).collect();
        let hits = surface_hits(sdf, &lines, r, cfg.march_samples, cfg.refine, eps);
        let (sp, mg, tau) = (cfg.spacing as f64, cfg.margin as f64, cfg.tau as f64);
        let plan: Vec<CarvedRay> = with
            .iter()
            .zip(&hits)
            .map(|(&((o, d), td), hit)| {
                let at = |s: f64| [0, 1, 2].map(|q| o[q] + s * d[q]);
                let t0 = hit.as_ref().map_or(td, |h| h.t);
                let mut free = Vec::new();
                let mut s = t0;
                while s <= td - mg {
                    free.push((at(s), tau.min(0.5 * (td - s))));
                    s += sp;
                }
                CarvedRay {
                    t: t0,
                    t_b: td,
                    free,
                    surface: at(td),
                }
            })
            .collect();
        let step = DepthStep {
            rays: rays.len(),
            with_depth: plan.len(),
            carved: plan.iter().filter(|c| !c.free.is_empty()).count(),
            loss: 0.0,
        };
        (step, plan)
    }

    /// The loss on `plan` at the weight `weight` ([`super::multiview::carve_loss_grad`] with
    /// this prior's surface weight and `tau`), its gradient added into `grads`.
    #[allow(clippy::too_many_arguments)]
    pub fn loss_grad<T: Real>(
        &self,
        weight: f32,
        model: &NeusModel,
        params: &[T],
        sdf: &dyn Fn(&[[f64; 3]]) -> Vec<f64>,
        plan: &[CarvedRay],
        active: usize,
        grads: &mut [T],
    ) -> f64 {
        let cv = CarveConfig {
            weight,
            surface_weight: self.cfg.surface_weight,
            tau: self.cfg.tau,
            ..CarveConfig::default()
        };
        carve_loss_grad(&cv, model, params, sdf, plan, active, grads)
    }

    /// One training step's part (step `step` of `iterations`): `None` outside
    /// `[start_step, end_step]`.
    #[allow(clippy::too_many_arguments)]
    pub fn add_grad(
        &self,
        model: &NeusModel,
        params: &[f32],
        step: u64,
        iterations: u64,
        active: usize,
        batch: &Batch,
        grads: &mut [f32],
    ) -> Option<DepthStep> {
        if !self.cfg.active_at(step) {
            return None;
        }
        let rays = masked_rays(batch, self.cfg.rays);
        let sdf = sdf_f64(model, params, active);
        let eps = model.fd_eps(active);
        let (mut out, plan) = self.plan(model.config.render.radius, &sdf, eps, &rays);
        let weight = self.cfg.weight_at(step, iterations);
        out.loss = self.loss_grad(weight, model, params, &sdf, &plan, active, grads);
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::train::multiview::tests::{look_at, render_plane, true_t as plane_t};

    /// Five cameras about 1.9 above the plane, looking at the origin.
    fn rig() -> (Vec<Camera>, Vec<RgbImage>) {
        let cams: Vec<Camera> = [
            Vector3::new(0.0, -0.4, 1.9),
            Vector3::new(0.5, -0.3, 1.8),
            Vector3::new(-0.5, -0.2, 1.8),
            Vector3::new(0.1, 0.5, 1.8),
            Vector3::new(-0.3, 0.4, 1.85),
        ]
        .into_iter()
        .map(|c| look_at(c, Vector3::zeros(), 96, 80, 90.0))
        .collect();
        let imgs = cams.iter().map(render_plane).collect();
        (cams, imgs)
    }

    /// The stereo for this coarse rig: one plane step (2 / 128) is about 0.2 px of disparity
    /// here, so depths agree to 1 % (`rel_tol`), not the 0.2 % of a 400 × 300 scene, and a
    /// depth counts as right within `TOL` (about 0.3 px).
    fn rig_cfg() -> MvsConfig {
        MvsConfig {
            rel_tol: 0.01,
            ..Default::default()
        }
    }

    const TOL: f64 = 0.03;

    /// The stereo's view of `img` from `c` (grey = the red channel), every pixel masked.
    fn view(c: &Camera, img: &RgbImage) -> View {
        View {
            w: img.width,
            h: img.height,
            grey: img.data.chunks_exact(3).map(|q| q[0]).collect(),
            k: c.k,
            kinv: c.k.try_inverse().unwrap(),
            r: c.r,
            c: c.center,
            mask: vec![true; img.width * img.height],
        }
    }

    /// The hole fill without the free-space check (every candidate passes).
    fn fill_plain(
        cfg: &MvsConfig,
        w: usize,
        h: usize,
        mask: &[bool],
        grey: &[f32],
        z: &[f32],
    ) -> (Vec<f32>, Vec<bool>) {
        fill_holes(cfg, w, h, mask, grey, z, |_, _| true, |_, _| None)
    }

    fn no_fill() -> MvsConfig {
        MvsConfig {
            fuse_radius: 0.0,
            hole_radius: 0,
            ..rig_cfg()
        }
    }

    /// A `w × h` camera-`z` map from `f(x, y)`, NaN where `hole(x, y)`.
    fn zmap(
        w: usize,
        h: usize,
        f: impl Fn(f64, f64) -> f64,
        hole: impl Fn(usize, usize) -> bool,
    ) -> Vec<f32> {
        (0..w * h)
            .map(|k| {
                let (x, y) = (k % w, k / w);
                if hole(x, y) {
                    f32::NAN
                } else {
                    f(x as f64, y as f64) as f32
                }
            })
            .collect()
    }

    /// Asserts that every pixel `(x, y)` of `xs × ys` in a `w`-wide map was filled (when
    /// `must_fill`; otherwise every filled one) and lies within `rel` of `want(x, y)`.
    #[allow(clippy::too_many_arguments)]
    fn assert_fills(
        w: usize,
        out: &[f32],
        filled: &[bool],
        xs: std::ops::Range<usize>,
        ys: std::ops::Range<usize>,
        want: impl Fn(f64, f64) -> f64,
        rel: f64,
        must_fill: bool,
    ) {
        for y in ys {
            for x in xs.clone() {
                let k = y * w + x;
                assert!(filled[k] || !must_fill, "({x}, {y}) filled");
                let want = want(x as f64, y as f64);
                assert!(
                    !filled[k] || (out[k] as f64 - want).abs() < rel * want,
                    "({x}, {y}): {} against {want}",
                    out[k]
                );
            }
        }
    }

    /// The slanted background of [`occluder_scene`] at pixel `(x, y)`.
    fn far(x: f64, y: f64) -> f64 {
        1.0 / (0.3 + 0.0005 * x + 0.0002 * y)
    }

    /// A `40 × 21` map: an occluder at z = 2 left of x = 15; the slanted background [`far`]
    /// right of x = 20; the columns 15..=20 between them (just behind the contour) empty.
    fn occluder_scene() -> (usize, usize, Vec<f32>) {
        let (w, h) = (40, 21);
        let z = zmap(
            w,
            h,
            |x, y| if x < 15.0 { 2.0 } else { far(x, y) },
            |x, _| (15..=20).contains(&x),
        );
        (w, h, z)
    }

    #[test]
    fn the_hole_fill_takes_the_background_behind_an_occluder() {
        let (w, h, z) = occluder_scene();
        let cfg = MvsConfig::default();
        let (out, filled) = fill_plain(&cfg, w, h, &vec![true; w * h], &vec![0.5; w * h], &z);
        assert_fills(w, &out, &filled, 15..21, 5..16, far, 0.02, true);
        assert!(
            (0..w * h).all(|k| !filled[k] || z[k].is_nan()),
            "only missing pixels are filled"
        );
        assert!((0..w * h)
            .filter(|&k| z[k].is_finite())
            .all(|k| out[k] == z[k]));
    }

    #[test]
    fn the_free_space_check_passes_over_the_background_and_marches_when_all_fail() {
        // The check refuses every depth beyond 2.5 (the background), as other views seeing
        // past it would.
        let (w, h, z) = occluder_scene();
        let cfg = MvsConfig::default();
        let (mask, grey) = (vec![true; w * h], vec![0.5; w * h]);
        let near_only = |_: usize, zz: f64| zz < 2.5;
        let (out, filled) = fill_holes(&cfg, w, h, &mask, &grey, &z, near_only, |_, _| None);
        // Where the occluder's group was found too, it is the next candidate.
        assert!(filled.iter().filter(|&&f| f).count() > 20, "some filled");
        assert!((0..w * h)
            .filter(|&k| filled[k])
            .all(|k| (out[k] - 2.0).abs() < 1e-4));
        // With every candidate refused, the march is asked from the preferred one's depth
        // (the background's, > 2.5) and its answer taken.
        let asked = std::sync::Mutex::new(Vec::new());
        let cast = |k: usize, z0: f64| {
            asked.lock().unwrap().push((k, z0));
            Some(7.0)
        };
        let (out, filled) = fill_holes(&cfg, w, h, &mask, &grey, &z, |_, _| false, cast);
        let asked = asked.into_inner().unwrap();
        assert_eq!(asked.len(), filled.iter().filter(|&&f| f).count());
        assert!(asked
            .iter()
            .all(|&(k, z0)| filled[k] && out[k] == 7.0 && z0 > 2.5));
        assert!(
            asked.len() >= 6 * 11,
            "every pixel between the contours: {}",
            asked.len()
        );
        // A march that finds nothing leaves the pixel empty.
        let (out, filled) = fill_holes(&cfg, w, h, &mask, &grey, &z, |_, _| false, |_, _| None);
        assert!(!filled.iter().any(|&f| f));
        assert_eq!(
            out.iter().filter(|v| v.is_nan()).count(),
            z.iter().filter(|v| v.is_nan()).count()
        );
    }

    /// Per view, the camera-`z` map of the plane `z = 0` (NaN where `gap` holds at the hit).
    fn plane_z(views: &[View], gap: impl Fn(&Vector3<f64>) -> bool) -> Vec<Vec<f32>> {
        views
            .iter()
            .map(|v| {
                (0..v.w * v.h)
                    .map(|k| {
                        let d = v.dir((k % v.w) as f64 + 0.5, (k / v.w) as f64 + 0.5);
                        let z = -v.c.z / d.z;
                        if gap(&(v.c + d * z)) {
                            f32::NAN
                        } else {
                            z as f32
                        }
                    })
                    .collect()
            })
            .collect()
    }

    fn rig_views() -> Vec<View> {
        let (cams, imgs) = rig();
        cams.iter().zip(&imgs).map(|(c, i)| view(c, i)).collect()
    }

    #[test]
    fn the_free_space_check_refuses_a_point_other_views_see_past() {
        let views = rig_views();
        let ev = plane_z(&views, |_| false);
        let cfg = MvsConfig::default();
        let at = |h: f64| Vector3::new(0.1, -0.05, h);
        assert!(
            free_of_others(&cfg, &views, &ev, 0, &at(0.0)),
            "on the plane"
        );
        assert!(
            free_of_others(&cfg, &views, &ev, 0, &at(0.01)),
            "within free_tol"
        );
        assert!(!free_of_others(&cfg, &views, &ev, 0, &at(0.3)), "in front");
        assert!(
            free_of_others(&cfg, &views, &ev, 0, &at(-0.3)),
            "hidden behind"
        );
        // With depths in one other view only, two views cannot see past it; one may be enough.
        let mut one = ev.clone();
        for m in &mut one[2..] {
            m.fill(f32::NAN);
        }
        assert!(free_of_others(&cfg, &views, &one, 0, &at(0.3)));
        let cfg1 = MvsConfig {
            free_views: 1,
            ..cfg
        };
        assert!(!free_of_others(&cfg1, &views, &one, 0, &at(0.3)));
        // The view's own depths are not evidence.
        for m in &mut one[1..] {
            m.fill(f32::NAN);
        }
        assert!(free_of_others(&cfg1, &views, &one, 0, &at(0.3)));
    }

    #[test]
    fn the_march_crosses_the_plane_across_a_gap_narrower_than_its_radius() {
        let views = rig_views();
        let v = &views[0];
        // The centre pixel looks at the origin (the rig's target).
        let k = (v.h / 2) * v.w + v.w / 2;
        let d = v.dir((k % v.w) as f64 + 0.5, (k / v.w) as f64 + 0.5);
        let truth = -v.c.z / d.z;
        let gap = |r: f64| move |p: &Vector3<f64>| p.x.hypot(p.y) < r;
        let cloud = SurfelCloud::new(&views, &plane_z(&views, gap(0.1)), 0.25);
        let got = cloud
            .cast(v, k, 0.5 * truth, &|_| true)
            .expect("a crossing");
        assert!((got - truth).abs() < 1e-3 * truth, "{got} against {truth}");
        // What `ok` refuses is passed over; nothing lies beyond the plane.
        assert_eq!(cloud.cast(v, k, 0.5 * truth, &|_| false), None);
        assert_eq!(cloud.cast(v, k, 1.1 * truth, &|_| true), None);
        // A gap wider than the radius is left alone.
        let wide = SurfelCloud::new(&views, &plane_z(&views, gap(0.5)), 0.25);
        assert_eq!(wide.cast(v, k, 0.5 * truth, &|_| true), None);
        // Surfels seen only from the other side of the plane are not this ray's surface.
        let (cams, imgs) = rig();
        let below: Vec<View> = cams
            .iter()
            .zip(&imgs)
            .map(|(c, i)| {
                let m = Vector3::new(c.center.x, c.center.y, -c.center.z);
                view(&look_at(m, Vector3::zeros(), 96, 80, 90.0), i)
            })
            .collect();
        let under = SurfelCloud::new(&below, &plane_z(&below, |_| false), 0.25);
        assert!(under.p.len() > 100, "{} surfels", under.p.len());
        assert_eq!(under.cast(v, k, 0.5 * truth, &|_| true), None);
    }

    #[test]
    fn the_refit_extends_a_receding_background_to_the_occluder() {
        // A background whose depth grows upwards (smaller y) above an occluder (z = 1.5, rows
        // 25 and below); rows 18..=24 have no depth. From (20, 22) the background is found
        // only along the three upward directions, all at row 17: collinear, so the group
        // gives row 17's depth, farther than the truth. The refit fits the window's rows
        // 12..=17 instead and continues the plane down to row 22.
        let (w, h) = (40, 40);
        let far = |_: f64, y: f64| 1.0 / (0.25 + 0.002 * y);
        let z = zmap(
            w,
            h,
            |x, y| if y >= 25.0 { 1.5 } else { far(x, y) },
            |_, y| (18..=24).contains(&y),
        );
        let (mask, grey) = (vec![true; w * h], vec![0.5; w * h]);
        let k = 22 * w + 20;
        let want = far(20.0, 22.0);
        let plain = MvsConfig {
            hole_refine: 0,
            ..MvsConfig::default()
        };
        let (group, f0) = fill_plain(&plain, w, h, &mask, &grey, &z);
        assert!(f0[k]);
        assert!(
            (group[k] as f64 - far(20.0, 17.0)).abs() < 1e-5 * want,
            "without the refit, row 17's depth: {} against {}",
            group[k],
            far(20.0, 17.0)
        );
        assert!(
            (group[k] as f64 - want) > 0.03 * want,
            "and behind the truth"
        );
        let cfg = MvsConfig::default();
        assert_eq!(cfg.hole_refine, 2, "the refit is the default");
        let (out, filled) = fill_plain(&cfg, w, h, &mask, &grey, &z);
        assert!(filled[k]);
        assert!(
            (out[k] as f64 - want).abs() < 1e-5 * want,
            "with the refit: {} against {want}",
            out[k]
        );
        // Every filled pixel of the band lies on the background's plane.
        assert_fills(w, &out, &filled, 5..35, 18..25, far, 1e-4, false);
    }

    #[test]
    fn with_a_grey_tolerance_the_hole_fill_keeps_a_thin_part_in_front() {
        // A bar (z = 2, grey 0.8) over x = 17..=22 in front of a background (z = 3, grey 0.2);
        // the bar's right edge, x = 20..=22, has no depth.
        let (w, h) = (40, 21);
        let bar = |x: usize| (17..=22).contains(&x);
        let z = zmap(
            w,
            h,
            |x, _| if bar(x as usize) { 2.0 } else { 3.0 },
            |x, _| (20..=22).contains(&x),
        );
        let grey: Vec<f32> = (0..w * h)
            .map(|k| if bar(k % w) { 0.8 } else { 0.2 })
            .collect();
        let mask = vec![true; w * h];
        let k = 10 * w + 21;
        let plain_cfg = MvsConfig {
            hole_grey_tol: 0.0,
            ..MvsConfig::default()
        };
        let (plain, _) = fill_plain(&plain_cfg, w, h, &mask, &grey, &z);
        assert!(
            (plain[k] - 3.0).abs() < 1e-6,
            "background rule: {}",
            plain[k]
        );
        let cfg = MvsConfig::default();
        assert_eq!(cfg.hole_grey_tol, 0.1, "the grey rule is the default");
        let (out, filled) = fill_plain(&cfg, w, h, &mask, &grey, &z);
        assert!(
            filled[k] && (out[k] - 2.0).abs() < 1e-6,
            "grey rule: {}",
            out[k]
        );
        // A grey that matches no group leaves the pixel empty.
        let mut odd = grey.clone();
        odd[k] = 0.5;
        let (none, f) = fill_plain(&cfg, w, h, &mask, &odd, &z);
        assert!(none[k].is_nan() && !f[k]);
    }

    #[test]
    fn the_hole_fill_recovers_a_slanted_plane_inside_a_patch() {
        // 1/z affine in the pixel coordinates is a plane in the camera frame.
        let (w, h) = (40, 40);
        let plane = |x: f64, y: f64| 1.0 / (0.3 + 0.0002 * x - 0.0001 * y);
        let z = zmap(w, h, plane, |x, y| {
            (17..24).contains(&x) && (17..24).contains(&y)
        });
        let (out, filled) = fill_plain(
            &MvsConfig::default(),
            w,
            h,
            &vec![true; w * h],
            &vec![0.5; w * h],
            &z,
        );
        assert_fills(w, &out, &filled, 17..24, 17..24, plane, 1e-5, true);
    }

    #[test]
    fn the_hole_fill_leaves_what_it_cannot_reach_and_stays_in_the_mask() {
        let (w, h) = (40, 40);
        let cfg = MvsConfig {
            hole_radius: 5,
            ..MvsConfig::default()
        };
        // A 20 × 20 hole: its centre is more than 5 px from every depth.
        let z = zmap(
            w,
            h,
            |_, _| 3.0,
            |x, y| (10..30).contains(&x) && (10..30).contains(&y),
        );
        // The right half is outside the mask: nothing there is filled, and nothing is
        // looked for across it.
        let mask: Vec<bool> = (0..w * h).map(|k| k % w < 20).collect();
        let (out, filled) = fill_plain(&cfg, w, h, &mask, &vec![0.5; w * h], &z);
        assert!(
            out[20 * w + 19].is_nan() && !filled[20 * w + 19],
            "beyond reach"
        );
        assert!(filled[11 * w + 11] && (out[11 * w + 11] - 3.0).abs() < 1e-6);
        assert!((0..w * h).all(|k| mask[k] || !filled[k]));
        // One direction alone is not enough: a pixel whose only depth within reach lies
        // in one direction stays empty.
        let z1 = zmap(w, h, |_, _| 3.0, |x, _| x >= 1);
        let (out1, _) = fill_plain(&cfg, w, h, &vec![true; w * h], &vec![0.5; w * h], &z1);
        assert!(
            out1[20 * w + 3].is_finite(),
            "left, up-left and down-left reach x = 0"
        );
        let z2 = zmap(w, h, |_, _| 3.0, |x, y| !(x == 0 && y == 20));
        let (out2, _) = fill_plain(&cfg, w, h, &vec![true; w * h], &vec![0.5; w * h], &z2);
        assert!(out2[20 * w + 3].is_nan(), "one depth in one direction");
        assert!(
            fill_plain(
                &cfg,
                w,
                h,
                &vec![true; w * h],
                &vec![0.5; w * h],
                &vec![f32::NAN; w * h]
            )
            .1
            .iter()
            .all(|f| !f),
            "no depth anywhere: nothing filled"
        );
    }

    /// `(pixels with a depth, of them within tol of the plane)` in view `v`.
    fn score(maps: &DepthMaps, cams: &[Camera], v: usize, tol: f64) -> (usize, usize) {
        let c = &cams[v];
        let (mut n, mut good) = (0, 0);
        for y in 0..c.height {
            for x in 0..c.width {
                if let Some(t) = maps.get(v, x, y) {
                    n += 1;
                    if (t - plane_t(c, x as f64 + 0.5, y as f64 + 0.5)).abs() < tol {
                        good += 1;
                    }
                }
            }
        }
        (n, good)
    }

    #[test]
    fn the_sweep_finds_the_plane_in_every_view() {
        let (cams, imgs) = rig();
        let maps = depth_maps(&no_fill(), &cams, &imgs, None);
        // A plane step is 2 / 128 ≈ 0.016; the parabola refines within it.
        for v in 0..cams.len() {
            let (n, good) = score(&maps, &cams, v, TOL);
            assert!(n > 96 * 80 / 2, "view {v}: {n} depths");
            assert!(
                good as f64 > 0.95 * n as f64,
                "view {v}: {good} of {n} within {TOL}"
            );
        }
        assert_eq!(maps.considered, 5 * 96 * 80);
        assert_eq!(maps.counts().1, 0, "no fill asked");
    }

    /// Five cameras low over the plane (about 25° above it, so their rays meet it at about 65°
    /// from its normal), masked to where the plane lies within 0.8 of the origin.
    pub(super) fn grazing_rig() -> (Vec<Camera>, Vec<RgbImage>, Vec<GrayImage>) {
        let cams: Vec<Camera> = [-0.3f64, -0.15, 0.0, 0.15, 0.3]
            .into_iter()
            .map(|a| {
                let c = Vector3::new(1.9 * a.sin(), -1.9 * a.cos(), 0.9);
                look_at(c, Vector3::zeros(), 96, 80, 90.0)
            })
            .collect();
        let imgs = cams.iter().map(render_plane).collect();
        let masks = cams
            .iter()
            .map(|c| {
                let mut m = GrayImage::new(c.width as usize, c.height as usize);
                for y in 0..c.height as usize {
                    for x in 0..c.width as usize {
                        let (o, d) = c.ray(x as f64 + 0.5, y as f64 + 0.5);
                        let t = plane_t(c, x as f64 + 0.5, y as f64 + 0.5);
                        let p = o + t * d;
                        let inside = t > 0.0 && p.x.hypot(p.y) < 0.8;
                        m.data[y * c.width as usize + x] = if inside { 1.0 } else { 0.0 };
                    }
                }
                m
            })
            .collect();
        (cams, imgs, masks)
    }

    #[test]
    fn slanted_windows_find_more_of_a_plane_seen_at_grazing_incidence() {
        let (cams, imgs, masks) = grazing_rig();
        let flat_cfg = MvsConfig {
            slant_iters: 0,
            ..no_fill()
        };
        let flat = depth_maps(&flat_cfg, &cams, &imgs, Some(&masks));
        let slanted = depth_maps(&no_fill(), &cams, &imgs, Some(&masks));
        assert_eq!(no_fill().slant_iters, 3, "the default");
        // Measured: the sweep keeps about 1 100 depths per view, 35–40 % of them within TOL;
        // the slanted windows about 1 870, all within TOL.
        for v in 0..cams.len() {
            let (n0, g0) = score(&flat, &cams, v, TOL);
            let (n1, g1) = score(&slanted, &cams, v, TOL);
            assert!(
                (g0 as f64) < 0.6 * n0 as f64,
                "view {v}: the sweep alone already finds {g0} of {n0}"
            );
            assert!(
                g1 as f64 > 0.95 * n1 as f64 && g1 > 2 * g0,
                "view {v}: slanted {g1} of {n1} within {TOL}, fronto-parallel {g0} of {n0}"
            );
        }
    }

    #[test]
    fn consistency_drops_the_depths_of_a_view_with_a_wrong_pose() {
        let (mut cams, imgs) = rig();
        let before = depth_maps(&no_fill(), &cams, &imgs, None);
        let (n0, _) = score(&before, &cams, 0, TOL);
        // View 0's images stay; its camera moves 0.06 sideways (a bad pose estimate).
        cams[0].center.x += 0.06;
        let after = depth_maps(&no_fill(), &cams, &imgs, None);
        let (n1, _) = score(&after, &cams, 0, TOL);
        assert!(n1 * 5 < n0, "view 0 kept {n1} of {n0} depths");
        // The other views drop view 0 as a source (top_k of 4) or lose only what it backed.
        for v in 1..cams.len() {
            let (n, good) = score(&after, &cams, v, TOL);
            assert!(n > 96 * 80 / 3, "view {v}: {n} depths");
            assert!(good as f64 > 0.95 * n as f64, "view {v}: {good} of {n}");
        }
        // Without the check, view 0 keeps a depth at most pixels, mostly wrong.
        let raw = depth_maps(
            &MvsConfig {
                min_consistent: 0,
                ..no_fill()
            },
            &cams,
            &imgs,
            None,
        );
        let (nr, goodr) = score(&raw, &cams, 0, TOL);
        assert!(nr > 2 * n1 && goodr * 2 < nr, "raw: {goodr} of {nr} right");
    }

    #[test]
    fn the_fill_takes_other_views_points_where_the_grey_matches() {
        let (cams, imgs) = rig();
        let cfg = MvsConfig::default();
        let views: Vec<View> = cams.iter().zip(&imgs).map(|(c, i)| view(c, i)).collect();
        // Exact camera depths everywhere, but none in a block of view 0.
        let mut z: Vec<Vec<f32>> = views
            .iter()
            .zip(&cams)
            .map(|(v, c)| {
                (0..v.w * v.h)
                    .map(|k| {
                        let (u, vv) = ((k % v.w) as f64 + 0.5, (k / v.w) as f64 + 0.5);
                        (plane_t(c, u, vv) / v.dir(u, vv).norm()) as f32
                    })
                    .collect()
            })
            .collect();
        let block = |k: usize| (30..50).contains(&(k % 96)) && (30..45).contains(&(k / 96));
        let truth0 = z[0].clone();
        for (k, t) in z[0].iter_mut().enumerate() {
            if block(k) {
                *t = f32::NAN;
            }
        }
        let (out, filled) = fuse(&cfg, &views, &z);
        let nb = (0..96 * 80).filter(|&k| block(k)).count();
        let mut got = 0;
        for k in (0..96 * 80).filter(|&k| block(k)) {
            if filled[0][k] {
                got += 1;
                assert!((out[0][k] - truth0[k]).abs() < 0.01, "pixel {k}");
            }
        }
        assert!(got * 10 > nb * 9, "{got} of {nb} filled");
        assert!(
            (0..96 * 80).all(|k| (!filled[0][k] || block(k)) && !filled[1][k]),
            "only the missing pixels are filled"
        );
        // A pixel whose grey no point shares is left empty.
        let mut views = views;
        for k in (0..96 * 80).filter(|&k| block(k)) {
            views[0].grey[k] = 5.0;
        }
        let (out, filled) = fuse(&cfg, &views, &z);
        assert!((0..96 * 80)
            .filter(|&k| block(k))
            .all(|k| !filled[0][k] && out[0][k].is_nan()));
    }

    #[test]
    fn the_fill_passes_over_a_nearer_cluster_of_another_grey() {
        // View 0 misses a pixel; nearer points (an occluder another view saw) project onto it
        // with another grey, the plane's points behind with its grey: the plane is taken.
        let (cams, imgs) = rig();
        let cfg = MvsConfig::default();
        let mk = view;
        let views: Vec<View> = vec![mk(&cams[0], &imgs[0]), mk(&cams[0], &imgs[0])];
        let k0 = 40 * 96 + 48;
        let t_plane = plane_t(&cams[0], 48.5, 40.5);
        let dn = views[0].dir(48.5, 40.5).norm();
        let mut z = vec![vec![f32::NAN; 96 * 80]; 2];
        // View 1 (the same pose) holds, at the same pixel, the plane's depth; the occluder is a
        // second copy of the pixel at half the depth with another grey (duplicated for support).
        z[1][k0] = (t_plane / dn) as f32;
        z[1][k0 + 1] = (t_plane / dn) as f32;
        let mut v1 = mk(&cams[0], &imgs[0]);
        v1.grey[k0 + 1] = views[0].grey[k0];
        let mut views = views;
        views[1] = v1;
        let occl = vec![f32::NAN; 96 * 80];
        let mut v2 = mk(&cams[0], &imgs[0]);
        let mut z2 = occl;
        z2[k0] = (0.5 * t_plane / dn) as f32;
        z2[k0 + 1] = (0.5 * t_plane / dn) as f32;
        v2.grey[k0] = views[0].grey[k0] + 0.3;
        v2.grey[k0 + 1] = views[0].grey[k0] + 0.3;
        views.push(v2);
        z.push(z2);
        let cfg = MvsConfig {
            fuse_radius: 1.5,
            fuse_grey_tol: 0.05,
            ..cfg
        };
        let (out, filled) = fuse(&cfg, &views, &z);
        assert!(filled[0][k0], "filled");
        let t = out[0][k0] as f64 * dn;
        assert!(
            (t - t_plane).abs() < 1e-4,
            "{t} against the plane's {t_plane}"
        );
        // With the occluder's grey equal to the pixel's, it is taken instead (nearest first).
        views[2].grey[k0] = views[0].grey[k0];
        views[2].grey[k0 + 1] = views[0].grey[k0];
        let (out, _) = fuse(&cfg, &views, &z);
        assert!((out[0][k0] as f64 * dn - 0.5 * t_plane).abs() < 1e-4);
    }

    #[test]
    fn empty_masks_and_nan_pixels_give_no_depth_there_and_nothing_non_finite() {
        let (cams, mut imgs) = rig();
        let empty: Vec<GrayImage> = cams
            .iter()
            .map(|c| GrayImage::new(c.width as usize, c.height as usize))
            .collect();
        let maps = depth_maps(&MvsConfig::default(), &cams, &imgs, Some(&empty));
        assert_eq!((maps.considered, maps.counts()), (0, (0, 0)));
        // NaN pixels in a block of view 0: no depth within the window of them, depths elsewhere.
        for y in 30..40 {
            for x in 40..50 {
                imgs[0].set(x, y, [f32::NAN; 3]);
            }
        }
        let maps = depth_maps(&no_fill(), &cams, &imgs, None);
        for y in 28..42u32 {
            for x in 38..52u32 {
                assert!(
                    maps.get(0, x, y).is_none(),
                    "depth next to NaN at ({x}, {y})"
                );
            }
        }
        let (n, good) = score(&maps, &cams, 0, TOL);
        assert!(
            n > 96 * 80 / 3 && good as f64 > 0.95 * n as f64,
            "{good} of {n}"
        );
        assert!(maps
            .t
            .iter()
            .flatten()
            .all(|t| t.is_nan() || (t.is_finite() && *t > 0.0)));
        let filled = depth_maps(&rig_cfg(), &cams, &imgs, None);
        assert!(filled
            .t
            .iter()
            .flatten()
            .all(|t| t.is_nan() || t.is_finite()));
        assert!(
            filled.get(0, 45, 35).is_none(),
            "a NaN pixel is never filled"
        );
    }

    /// A prior over the rig with the exact plane depth at every pixel except view 0's column 10.
    fn plane_prior(cfg: DepthConfig) -> (DepthPrior, Vec<Camera>) {
        let (cams, _) = rig();
        let t = cams
            .iter()
            .enumerate()
            .map(|(v, c)| {
                (0..c.width * c.height)
                    .map(|k| {
                        let (x, y) = (k % c.width, k / c.width);
                        if v == 0 && x == 10 {
                            f32::NAN
                        } else {
                            plane_t(c, x as f64 + 0.5, y as f64 + 0.5) as f32
                        }
                    })
                    .collect()
            })
            .collect();
        let maps = DepthMaps {
            width: cams.iter().map(|c| c.width as usize).collect(),
            filled: cams
                .iter()
                .map(|c| vec![false; (c.width * c.height) as usize])
                .collect(),
            hole_filled: cams
                .iter()
                .map(|c| vec![false; (c.width * c.height) as usize])
                .collect(),
            t,
            considered: 0,
        };
        (DepthPrior::new(cfg, cams.clone(), maps), cams)
    }

    #[test]
    fn the_plan_frees_the_span_in_front_of_the_depth_and_pins_the_surface() {
        let cfg = DepthConfig {
            weight: 1.0,
            ..Default::default()
        };
        let (p, cams) = plane_prior(cfg.clone());
        let rays: Vec<(usize, [u32; 2])> = (0..5)
            .flat_map(|v| (0..6).map(move |i| (v, [10 + 12 * i, 20 + 8 * i])))
            .collect();
        // A false sheet at z = 0.8 in front of the plane z = 0.
        let sheet = |pts: &[[f64; 3]]| pts.iter().map(|x| x[2] - 0.8).collect::<Vec<_>>();
        let (out, plan) = p.plan(3.0, &sheet, 1e-5, &rays);
        assert_eq!(
            (out.rays, out.with_depth),
            (30, 29),
            "view 0's column 10 has no depth"
        );
        assert_eq!(out.carved, 29);
        for c in &plan {
            assert!(
                c.surface[2].abs() < 1e-5,
                "surface point at z {}",
                c.surface[2]
            );
            assert!(c.t < c.t_b, "{c:?}");
            let first = c.free.first().unwrap().0;
            assert!(
                (first[2] - 0.8).abs() < 1e-4,
                "the span starts on the sheet: {first:?}"
            );
            for &(x, tau) in &c.free {
                assert!(
                    x[2] > 0.0 && x[2] <= 0.8 + 1e-4,
                    "freed point at z {}",
                    x[2]
                );
                assert!(tau > 0.0 && tau <= cfg.tau as f64 + 1e-12);
            }
            // The last freed point lies at least `margin` in front of the depth.
            let last = c.free.last().unwrap().0;
            let o = plan_origin(&cams, &rays, &plan, c);
            let tl = (0..3).map(|q| (last[q] - o[q]).powi(2)).sum::<f64>().sqrt();
            assert!(
                tl <= c.t_b - cfg.margin as f64 + 1e-9,
                "{tl} against {}",
                c.t_b
            );
        }
        // The truth: nothing to free, only the surface term.
        let truth = |pts: &[[f64; 3]]| pts.iter().map(|x| x[2]).collect::<Vec<_>>();
        let (out, plan) = p.plan(3.0, &truth, 1e-5, &rays);
        assert_eq!((out.with_depth, out.carved), (29, 0));
        assert!(plan
            .iter()
            .all(|c| c.free.is_empty() && (c.t - c.t_b).abs() < 1e-4));
    }

    /// The camera centre of the ray behind `c` (every plan entry is one of `rays` with a depth).
    fn plan_origin(
        cams: &[Camera],
        rays: &[(usize, [u32; 2])],
        plan: &[CarvedRay],
        c: &CarvedRay,
    ) -> [f64; 3] {
        let i = plan.iter().position(|q| std::ptr::eq(q, c)).unwrap();
        let v = rays
            .iter()
            .filter(|r| !(r.0 == 0 && r.1[0] == 10))
            .nth(i)
            .unwrap()
            .0;
        cams[v].center.into()
    }

    #[test]
    fn config_defaults_are_off_and_checks_name_the_key() {
        let d = DepthConfig::default();
        assert!(d.is_default() && !d.enabled() && !d.active_at(1000));
        assert!(d.invalid().is_none());
        let on = DepthConfig {
            weight: 5.0,
            end_step: Some(900),
            ..Default::default()
        };
        assert!(!on.active_at(199) && on.active_at(200) && on.active_at(900) && !on.active_at(901));
        // A ramp from 5 at step 200 to 1 at the last step (1000 of 1001), cut at `end_step`.
        let ramp = DepthConfig {
            final_weight: Some(1.0),
            ..on.clone()
        };
        assert_eq!(ramp.weight_at(199, 1001), 0.0);
        assert_eq!(ramp.weight_at(200, 1001), 5.0);
        assert!((ramp.weight_at(600, 1001) - 3.0).abs() < 1e-6);
        assert_eq!(ramp.weight_at(901, 1001), 0.0, "after end_step");
        assert_eq!(on.weight_at(600, 1001), 5.0, "constant without a ramp");
        let bad = |f: &dyn Fn(&mut DepthConfig)| {
            let mut c = on.clone();
            f(&mut c);
            c.invalid().map(|x| x.0)
        };
        assert_eq!(bad(&|c| c.weight = f32::NAN), Some("train.depth.weight"));
        assert_eq!(bad(&|c| c.rays = 0), Some("train.depth.rays"));
        assert_eq!(
            bad(&|c| c.final_weight = Some(-1.0)),
            Some("train.depth.final_weight")
        );
        assert_eq!(bad(&|c| c.margin = -1.0), Some("train.depth.margin"));
        assert_eq!(bad(&|c| c.mvs.top_k = 5), Some("train.depth.mvs.top_k"));
        assert_eq!(bad(&|c| c.mvs.planes = 1), Some("train.depth.mvs.planes"));
        type Mutate = fn(&mut DepthConfig);
        let cases: [(Mutate, &str); 12] = [
            (|c| c.mvs.min_consistent = 9, "min_consistent"),
            (|c| c.mvs.slant_iters = 17, "slant_iters"),
            (|c| c.mvs.fuse_radius = 9.0, "fuse_radius"),
            (|c| c.mvs.fuse_support = 0, "fuse_support"),
            (|c| c.mvs.hole_radius = 65, "hole_radius"),
            (|c| c.mvs.hole_jump = 0.0, "hole_jump"),
            (|c| c.mvs.hole_tol = f32::NAN, "hole_tol"),
            (|c| c.mvs.hole_refine = 9, "hole_refine"),
            (|c| c.mvs.hole_grey_tol = -0.1, "hole_grey_tol"),
            (|c| c.mvs.free_tol = 1.0, "free_tol"),
            (|c| c.mvs.free_views = 0, "free_views"),
            (|c| c.mvs.cast_radius = f32::NAN, "cast_radius"),
        ];
        for (f, key) in cases {
            let want = format!("train.depth.mvs.{key}");
            assert_eq!(bad(&f), Some(want.as_str()));
        }
        // TOML: a section with one key keeps every other default.
        let t: DepthConfig = toml::from_str("weight = 5.0\n[mvs]\nplanes = 64\n").unwrap();
        assert_eq!(t.mvs.planes, 64);
        assert_eq!(t.mvs.top_k, 2);
        assert!(t.enabled());
        assert!(toml::from_str::<DepthConfig>("wieght = 5.0\n").is_err());
    }
}
