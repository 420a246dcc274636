//! The depth prior's automatic switch (`[train.depth.auto]`; on in every preset but `paper`).
//!
//! **Why.** The depth prior ([`super::depth`]) is what removes the false lid that NeuS at the
//! `fast` preset lays across a cavity and paints with what lies behind it, but on other shapes it
//! costs accuracy (thin parts, a smooth object at the `default` preset), so it cannot simply
//! be on (measured: docs/recipe.md). A user with a deep concavity does not know to ask for it.
//! The switch asks the images.
//!
//! **The check**, once, at step `round(at · iterations)` (at least 1): the plane sweep alone
//! ([`super::depth::sweep_depths`], no consistency check, no fill) of `views` training views
//! spread evenly over the list gives depths `t_d` inside the masks; every `stride`-th pixel's
//! ray (`stride = ⌈√(w·h / 30 000)⌉`, so about 30 000 pixels a view are looked at) is marched
//! through the current field in steps of `step` from where it enters the sphere of the render
//! radius to `t_d − margin`. A ray on which the SDF is negative somewhere is **solid in front**
//! of what the stereo matched: free space the field has closed (the visibility constraint of
//! space carving: a point seen through a volume means the volume is empty; Kutulakos & Seitz,
//! IJCV 38(3), 2000, §2). When the share of such rays is at least `share` (and at least
//! `min_rays` rays had a depth) the prior is switched on at `weight` from the next step, with
//! the rest of `[train.depth]` as it stands (its start step: the later of `start_step` and the
//! check's step). The decision is written to `depth_auto.json` in the run folder, so a resumed
//! run makes the same one.
//!
//! **The defaults** (8 views, `margin` 0.2 normalised units, a fifth of the object's bounding
//! radius, `share` 5 %): objects with a cavity seen through its opening show shares several times
//! above the threshold at the check, objects without one a few percent at most; a margin of 0.1
//! let a front still settling cross it. The check comes at a share of the run, not at a fixed
//! step, because a longer run settles later (measured: docs/recipe.md). It costs the sweep of
//! `views` views (a few seconds) and the march (under a second), on every run that has masks.

use crate::scene::Camera;
use serde::{Deserialize, Serialize};

/// Settings of the automatic switch (`[train.depth.auto]`; see the module doc).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DepthAutoConfig {
    /// Whether the check runs (true; `paper` false, as the reference has no prior). It runs only
    /// when `train.depth.weight` is 0 and every training view has a mask.
    pub enabled: bool,
    /// The check's step as a share of the run's steps (0.1: step 200 of `fast`, 800 of
    /// `default`; `quick` 0.25, step 350 of 1400) ...
    pub at: f32,
    /// ... but not before this step (200); a run no longer than it has no check.
    pub min_step: u64,
    /// Training views the check sweeps, spread evenly over the list (8).
    pub views: usize,
    /// Solid counts only this far in front of the stereo's depth, normalised units (0.2).
    pub margin: f32,
    /// The march's step along a ray, normalised units (0.01).
    pub step: f32,
    /// The share of rays with solid in front that switches the prior on (0.05).
    pub share: f32,
    /// Fewer rays with a stereo depth than this decide nothing: the prior stays off (200).
    pub min_rays: usize,
    /// The prior's weight when switched on (10: `train.depth.weight`'s measured value).
    pub weight: f32,
}

impl Default for DepthAutoConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            at: 0.1,
            min_step: 200,
            views: 8,
            margin: 0.2,
            step: 0.01,
            share: 0.05,
            min_rays: 200,
            weight: 10.0,
        }
    }
}

impl DepthAutoConfig {
    /// The step after which the check runs in a run of `iterations` steps: `round(at ·
    /// iterations)`, at least `min_step` and 1; `None` when that is not before the last step.
    pub fn check_step(&self, iterations: u64) -> Option<u64> {
        let s = ((self.at as f64 * iterations as f64).round() as u64)
            .max(self.min_step)
            .max(1);
        (s < iterations).then_some(s)
    }

    /// The first invalid field, as `(key, value, why)`.
    pub fn invalid(&self) -> Option<(&'static str, String, &'static str)> {
        let pos = |v: f32| v.is_finite() && v > 0.0;
        let checks = [
            (
                "train.depth.auto.at",
                self.at.is_finite() && self.at > 0.0 && self.at < 1.0,
                self.at.to_string(),
                "must be in (0, 1) (a share of the run's steps)",
            ),
            (
                "train.depth.auto.views",
                self.views > 0,
                self.views.to_string(),
                "must be at least 1",
            ),
            (
                "train.depth.auto.margin",
                pos(self.margin),
                self.margin.to_string(),
                "must be positive (normalised units)",
            ),
            (
                "train.depth.auto.step",
                pos(self.step) && self.step <= self.margin.max(1e-3),
                self.step.to_string(),
                "must be positive and at most train.depth.auto.margin (normalised units)",
            ),
            (
                "train.depth.auto.share",
                pos(self.share) && self.share <= 1.0,
                self.share.to_string(),
                "must be in (0, 1]",
            ),
            (
                "train.depth.auto.weight",
                pos(self.weight),
                self.weight.to_string(),
                "must be positive",
            ),
        ];
        let (key, _, value, why) = checks.into_iter().find(|c| !c.1)?;
        Some((key, value, why))
    }
}

/// What the check found (`metrics.json` → `train.depth_auto`, and `depth_auto.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AutoCheck {
    /// The step after which it ran.
    pub step: u64,
    /// The training views it swept (indices into the training list).
    pub views: Vec<usize>,
    /// Rays with a stereo depth that it marched.
    pub rays: usize,
    /// Of them, those with solid more than `margin` in front of their depth.
    pub in_front: usize,
    /// `in_front / rays` (0 without rays).
    pub share: f64,
    /// The margin and threshold it used (normalised units; share).
    pub margin: f32,
    pub threshold: f32,
    /// Whether it switched the prior on.
    pub triggered: bool,
    /// Wall time of the sweep and the march, seconds.
    pub seconds: f64,
    /// Pose refinement's corrections at the check (absent when `train.pose_refine` is off):
    /// the check and the stereo it turns on use the cameras they give, and a run resumed past
    /// the check rebuilds the same cameras from this record.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<crate::train::pose_refine::PoseSnapshot>,
}

/// `count` training views out of `n`, spread evenly over the list (`⌊q·n / count⌋`), each once.
pub fn check_views(n: usize, count: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (0..count.min(n)).map(|q| q * n / count.min(n)).collect();
    v.dedup();
    v
}

/// Pixel stride of the march for a `w × h` view: about 30 000 pixels looked at.
pub fn pixel_stride(w: usize, h: usize) -> usize {
    ((w * h) as f64 / 30_000.0).sqrt().ceil().max(1.0) as usize
}

/// `(rays, in_front)`: of the pixels of `maps[q]` (view `cameras[q]`, distance along the unit
/// ray per pixel as [`super::depth::sweep_depths`] gives it, NaN: none) on every `stride`-th
/// row and column, those with a depth, and of them those whose ray has `sdf < 0` at some point
/// from its entry into the sphere `|x| ≤ radius` to `t_d − margin`, sampled every `step` (all
/// normalised units). `sdf` evaluates the field at a batch of points; it is called once per
/// view.
pub fn solid_in_front(
    sdf: &dyn Fn(&[[f32; 3]]) -> Vec<f32>,
    cameras: &[&Camera],
    maps: &[Vec<f32>],
    radius: f64,
    margin: f64,
    step: f64,
) -> (usize, usize) {
    assert_eq!(cameras.len(), maps.len(), "one map per camera");
    assert!(step > 0.0, "the march needs a positive step");
    let (mut rays, mut in_front) = (0usize, 0usize);
    for (cam, map) in cameras.iter().zip(maps) {
        let (w, h) = (cam.width as usize, cam.height as usize);
        assert_eq!(map.len(), w * h, "a map per pixel of its view");
        let stride = pixel_stride(w, h);
        let mut pts: Vec<[f32; 3]> = Vec::new();
        // Per ray, the end of its points in `pts`.
        let mut ends: Vec<usize> = Vec::new();
        for y in (0..h).step_by(stride) {
            for x in (0..w).step_by(stride) {
                let td = map[y * w + x] as f64;
                if !td.is_finite() {
                    continue;
                }
                let (o, d) = cam.ray(x as f64 + 0.5, y as f64 + 0.5);
                // Entry into the sphere: |o + t·d|² = radius², d a unit vector.
                let b = o.dot(&d);
                let disc = b * b - (o.norm_squared() - radius * radius);
                let t0 = if disc > 0.0 {
                    (-b - disc.sqrt()).max(0.0)
                } else {
                    f64::INFINITY
                };
                let mut t = t0;
                while t < td - margin {
                    let p = o + d * t;
                    pts.push([p.x as f32, p.y as f32, p.z as f32]);
                    t += step;
                }
                ends.push(pts.len());
            }
        }
        let f = if pts.is_empty() {
            Vec::new()
        } else {
            sdf(&pts)
        };
        assert_eq!(f.len(), pts.len(), "one SDF value per point");
        let mut start = 0;
        for &end in &ends {
            rays += 1;
            if f[start..end].iter().any(|&v| v < 0.0) {
                in_front += 1;
            }
            start = end;
        }
    }
    (rays, in_front)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};

    /// A 40 × 30 camera at `(0, 0, -4)` looking along `+z` (focal 80 px: the ball of radius 0.5
    /// spans about 10 px of radius).
    fn cam() -> Camera {
        Camera {
            k: Matrix3::new(80.0, 0.0, 20.0, 0.0, 80.0, 15.0, 0.0, 0.0, 1.0),
            r: Matrix3::identity(),
            center: Vector3::new(0.0, 0.0, -4.0),
            width: 40,
            height: 30,
        }
    }

    /// The SDF of a ball of radius 0.5 at the origin.
    fn ball(p: &[[f32; 3]]) -> Vec<f32> {
        p.iter()
            .map(|q| (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt() - 0.5)
            .collect()
    }

    /// The distance along each pixel's unit ray to the ball (NaN where it misses), plus `extra`.
    fn ball_depths(c: &Camera, extra: f64) -> Vec<f32> {
        let mut m = vec![f32::NAN; 40 * 30];
        for y in 0..30 {
            for x in 0..40 {
                let (o, d) = c.ray(x as f64 + 0.5, y as f64 + 0.5);
                let b = o.dot(&d);
                let disc = b * b - (o.norm_squared() - 0.25);
                if disc > 0.0 {
                    m[y * 40 + x] = (-b - disc.sqrt() + extra) as f32;
                }
            }
        }
        m
    }

    #[test]
    fn depths_on_the_surface_have_nothing_in_front_and_depths_behind_it_do() {
        let c = cam();
        let on = ball_depths(&c, 0.0);
        let hits = on.iter().filter(|t| t.is_finite()).count();
        assert!(hits > 100, "the ball fills part of the view: {hits}");
        let (rays, front) = solid_in_front(&ball, &[&c], &[on], 1.0, 0.2, 0.01);
        assert_eq!(
            rays, hits,
            "stride 1 at 40 × 30: every pixel with a depth is marched"
        );
        assert_eq!(front, 0);
        // The stereo saw 0.3 behind the surface: the ball's solid lies in front of it by more
        // than the 0.2 margin wherever the ray crosses 0.1 of solid or more.
        let behind = ball_depths(&c, 0.3);
        let (rays, front) = solid_in_front(&ball, &[&c], &[behind], 1.0, 0.2, 0.01);
        assert_eq!(rays, hits);
        assert!(front * 10 > rays * 9, "{front} of {rays}");
        // 0.15 behind, within the 0.2 margin: the march stops before the surface.
        let near = ball_depths(&c, 0.15);
        assert_eq!(solid_in_front(&ball, &[&c], &[near], 1.0, 0.2, 0.01).1, 0);
    }

    #[test]
    fn no_depth_means_no_rays_and_no_call_of_the_field() {
        let c = cam();
        let none = vec![f32::NAN; 40 * 30];
        let called = std::cell::Cell::new(false);
        let sdf = |p: &[[f32; 3]]| {
            called.set(true);
            ball(p)
        };
        assert_eq!(solid_in_front(&sdf, &[&c], &[none], 1.0, 0.2, 0.01), (0, 0));
        assert!(!called.get());
        // A ray that misses the sphere of the render radius has no points: marched, not in front.
        let mut far = vec![f32::NAN; 40 * 30];
        far[0] = 10.0;
        let (rays, front) = solid_in_front(&ball, &[&c], &[far], 0.01, 0.2, 0.01);
        assert_eq!((rays, front), (1, 0));
    }

    #[test]
    fn the_stride_keeps_about_thirty_thousand_pixels() {
        assert_eq!(pixel_stride(40, 30), 1);
        assert_eq!(pixel_stride(400, 300), 2);
        assert_eq!(pixel_stride(800, 600), 4);
        let s = pixel_stride(1600, 1200);
        assert!((1600 / s) * (1200 / s) <= 30_000 && s == 8, "{s}");
    }

    #[test]
    fn check_views_spread_over_the_list_and_the_step_is_a_share_of_the_run() {
        assert_eq!(check_views(46, 8), vec![0, 5, 11, 17, 23, 28, 34, 40]);
        assert_eq!(check_views(3, 8), vec![0, 1, 2]);
        assert!(check_views(0, 8).is_empty());
        let c = DepthAutoConfig::default();
        assert_eq!(c.check_step(2000), Some(200));
        assert_eq!(c.check_step(8000), Some(800));
        assert_eq!(c.check_step(1400), Some(200), "quick: not before min_step");
        assert_eq!(c.check_step(200), None, "no step left after the check");
        let c = DepthAutoConfig { min_step: 0, ..c };
        assert_eq!(c.check_step(24), Some(2));
        assert_eq!(c.check_step(3), Some(1));
        assert_eq!(c.check_step(1), None);
    }

    #[test]
    fn bad_values_are_named() {
        let ok = DepthAutoConfig::default();
        assert!(ok.invalid().is_none());
        for (c, key) in [
            (
                DepthAutoConfig {
                    at: 1.0,
                    ..ok.clone()
                },
                "train.depth.auto.at",
            ),
            (
                DepthAutoConfig {
                    views: 0,
                    ..ok.clone()
                },
                "train.depth.auto.views",
            ),
            (
                DepthAutoConfig {
                    margin: f32::NAN,
                    ..ok.clone()
                },
                "train.depth.auto.margin",
            ),
            (
                DepthAutoConfig {
                    step: 0.5,
                    ..ok.clone()
                },
                "train.depth.auto.step",
            ),
            (
                DepthAutoConfig {
                    share: 0.0,
                    ..ok.clone()
                },
                "train.depth.auto.share",
            ),
            (
                DepthAutoConfig {
                    weight: -1.0,
                    ..ok.clone()
                },
                "train.depth.auto.weight",
            ),
        ] {
            assert_eq!(c.invalid().map(|x| x.0), Some(key));
        }
    }
}
