//! The depth prior (`[train.depth]`): a loss that carves the span in front of the stereo's
//! depth (`crate::mvs`) and pulls the surface to it. Off unless asked for (`weight > 0`) or
//! switched on part-way through a run by [`super::depth_auto`], which checks whether the field
//! has closed space the stereo sees through (a cavity's lid).
//!
//! **The loss** ([`DepthPrior`]): from `start_step` on, the first `rays` masked rays of each
//! batch whose pixel has a depth `t_d` find the field's first surface crossing `t*`
//! ([`surface_hits`]); the span `[t*, t_d − margin]` is held free, points `spacing` apart asked
//! for `f ≥ min(tau, (t_d − t)/2)` (a hinge: free-space carving), and the point at `t_d` is
//! pulled to `f = 0` (the sparse-point SDF loss of Geo-NeuS, Fu et al., NeurIPS 2022, §3.2) with
//! `surface_weight`. `L = weight · mean over the rays of (mean hinge +
//! surface_weight·|f(x(t_d))|)`: [`carve_loss_grad`], whose gradient a finite-difference test
//! checks (`tests/field_grad.rs`). Distances are in the normalised frame. With
//! `confirm_views > 0` a span point is carved only where other views' measured depths see past
//! it too (the mean still divides by the whole span), and the surface is pulled only to depths
//! other views' measured depths agree with. With `veto_band > 0` a span point is dropped only
//! where another view's measured depth puts a surface just in front of it (the point is in a
//! wall's material), and the surface is not pulled to a depth another view sees past. With
//! `photo_check` a ray's span is carved only where the field's surface on it fails the stereo's
//! matching cost ([`crate::mvs::PhotoCost`]): the images, not other views' depths, decide.
//!
//! What it costs: the stereo once, when the prior turns on (a few tens of seconds for 46 views
//! of 400 × 300 on 2 cores), and a surface search of `rays` rays per step; with `photo_check`,
//! also the training images' grey values and masks (5 bytes a pixel) and two window costs per
//! ray with a span.

mod carve;
mod config;

pub use carve::{carve_loss_grad, CarvedRay};
pub(crate) use carve::{masked_rays, sdf_f64, surface_hits, Hit};
use config::off;
pub use config::DepthConfig;

use super::data::Batch;
use crate::field::Real;
use crate::mvs::{DepthMaps, PhotoCost};
use crate::render::NeusModel;
use crate::scene::Camera;
use serde::{Deserialize, Serialize};

/// A ray: origin and unit direction (normalised frame).
type Line = ([f64; 3], [f64; 3]);

/// What the depth prior did in one step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DepthStep {
    /// Rays looked at (masked, first of the batch).
    pub rays: usize,
    /// Of them, rays whose pixel has a depth.
    pub with_depth: usize,
    /// Of them, rays with a non-empty free span (the field crosses in front of the depth).
    pub carved: usize,
    /// Rays whose span the photo check (`photo_check`) kept from carving: the field's surface
    /// in front of the depth matches across the views. Not counted in `carved`.
    #[serde(default, skip_serializing_if = "off")]
    pub photo_kept: usize,
    /// The weighted loss.
    pub loss: f64,
}

/// The depth prior during training: the depth maps and the rays' cameras.
pub struct DepthPrior {
    cfg: DepthConfig,
    maps: DepthMaps,
    cameras: Vec<Camera>,
    /// The photo check's cost (`photo_check`; [`Self::with_photo`]).
    photo: Option<PhotoCost>,
}

impl DepthPrior {
    /// The prior over `cameras` (normalised frame) with depth maps already made.
    pub fn new(cfg: DepthConfig, cameras: Vec<Camera>, maps: DepthMaps) -> Self {
        assert_eq!(cameras.len(), maps.t.len(), "one depth map per camera");
        Self {
            cfg,
            maps,
            cameras,
            photo: None,
        }
    }

    /// This prior with the photo check's cost over the training images (used when
    /// `photo_check` is on; without it the check passes every span).
    pub fn with_photo(self, photo: PhotoCost) -> Self {
        Self {
            photo: Some(photo),
            ..self
        }
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
        let with: Vec<(Line, f64, usize, [u32; 2])> = rays
            .iter()
            .filter_map(|&(v, [x, y])| {
                let td = self.maps.get(v, x, y)?;
                let (o, d) = self.cameras[v].ray(x as f64 + 0.5, y as f64 + 0.5);
                Some(((o.into(), d.into()), td, v, [x, y]))
            })
            .collect();
        let lines: Vec<Line> = with.iter().map(|w| w.0).collect();
        let hits = surface_hits(sdf, &lines, r, cfg.march_samples, cfg.refine, eps);
        let (sp, mg, tau) = (cfg.spacing as f64, cfg.margin as f64, cfg.tau as f64);
        let photo_ok = self.photo_pass(&with, &hits);
        let mut photo_kept = 0;
        let plan: Vec<CarvedRay> = with
            .iter()
            .zip(&hits)
            .zip(photo_ok)
            .map(|((&((o, d), td, v, _), hit), photo_ok)| {
                let at = |s: f64| [0, 1, 2].map(|q| o[q] + s * d[q]);
                let t0 = hit.as_ref().map_or(td, |h| h.t);
                let mut free = Vec::new();
                let mut s = t0;
                while s <= td - mg {
                    free.push((at(s), tau.min(0.5 * (td - s))));
                    s += sp;
                }
                let span = free.len();
                let surface = at(td);
                let mut pull = true;
                if cfg.confirm_views > 0 {
                    // Seen past by another view: free. Seen at (within `margin`): surface.
                    free.retain(|(x, _)| self.confirmed(v, x, |tj, r| tj > r + mg));
                    pull = self.confirmed(v, &surface, |tj, r| (tj - r).abs() <= mg);
                }
                if cfg.veto_band > 0.0 {
                    // Just behind another view's seen surface: material. Seen past: free.
                    let band = cfg.veto_band as f64;
                    free.retain(|(x, _)| {
                        !self.seen_by(v, x, 1, |tj, r| tj > r - band && tj <= r + mg)
                    });
                    pull = pull && !self.seen_by(v, &surface, 1, |tj, r| tj > r + mg);
                }
                if !photo_ok && !free.is_empty() {
                    free.clear();
                    pull = false;
                    photo_kept += 1;
                }
                CarvedRay {
                    t: t0,
                    t_b: td,
                    free,
                    span,
                    surface,
                    pull,
                }
            })
            .collect();
        let step = DepthStep {
            rays: rays.len(),
            with_depth: plan.len(),
            carved: plan.iter().filter(|c| !c.free.is_empty()).count(),
            photo_kept,
            loss: 0.0,
        };
        (step, plan)
    }

    /// Per ray of `with` (the rays with a depth, as `(line, t_d, view, pixel)`) and its
    /// first crossing `hits`, whether the photo check (`photo_check`) lets its span be carved:
    /// true when the check is off, the ray has no crossing, or the crossing's cost (the plane
    /// with the field's normal there) is above `mvs.max_cost`, undefined, or above the cost at
    /// the depth by more than `photo_margin` ([`DepthConfig::photo_carves`]).
    fn photo_pass(&self, with: &[(Line, f64, usize, [u32; 2])], hits: &[Option<Hit>]) -> Vec<bool> {
        let photo = match (&self.photo, self.cfg.photo_check) {
            (Some(p), true) => p,
            _ => return vec![true; with.len()],
        };
        let mg = self.cfg.margin as f64;
        with.iter()
            .zip(hits)
            .map(|(&(_, td, v, [x, y]), hit)| {
                let Some(h) = hit.as_ref().filter(|h| h.t <= td - mg) else {
                    return true; // no span to carve
                };
                let g = h.grad;
                let norm = g.iter().map(|c| c * c).sum::<f64>().sqrt();
                let normal = (norm > 0.0 && norm.is_finite()).then(|| g.map(|c| c / norm));
                let (x, y) = (x as usize, y as usize);
                let c = photo.costs(v, x, y, &[(h.t, normal), (td, None)]);
                self.cfg.photo_carves(c[0], c[1])
            })
            .collect()
    }

    /// Whether at least `confirm_views` training views other than `view` confirm the point `x`
    /// (normalised frame): `agrees(t_j, r)` holds for the measured depth `t_j` of the pixel
    /// the point projects to and the point's distance `r = |x − C_j|`. Fills' depths do not
    /// count; they are the ones most often behind the truth.
    fn confirmed(&self, view: usize, x: &[f64; 3], agrees: impl Fn(f64, f64) -> bool) -> bool {
        self.seen_by(view, x, self.cfg.confirm_views, agrees)
    }

    /// Whether at least `need` training views other than `view` have a measured depth `t_j`
    /// at the pixel `x` projects to for which `agrees(t_j, |x − C_j|)` holds.
    fn seen_by(
        &self,
        view: usize,
        x: &[f64; 3],
        need: usize,
        agrees: impl Fn(f64, f64) -> bool,
    ) -> bool {
        let p = nalgebra::Vector3::from(*x);
        let mut seen = 0;
        for (j, cam) in self.cameras.iter().enumerate() {
            if j == view {
                continue;
            }
            let Some((px, py)) = crate::scene::camera::pixel_of(cam, &p) else {
                continue;
            };
            let k = py * self.maps.width[j] + px;
            if self.maps.filled[j][k] || self.maps.hole_filled[j][k] {
                continue;
            }
            let tj = self.maps.t[j][k];
            if tj.is_finite() && agrees(tj as f64, (p - cam.center).norm()) {
                seen += 1;
                if seen >= need {
                    return true;
                }
            }
        }
        false
    }

    /// The loss on `plan` at the weight `weight` ([`carve_loss_grad`] with
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
        let sw = self.cfg.surface_weight;
        carve_loss_grad(weight, sw, model, params, sdf, plan, active, grads)
    }

    /// One training step's part: `None` before `start_step`.
    #[allow(clippy::too_many_arguments)]
    pub fn add_grad(
        &self,
        model: &NeusModel,
        params: &[f32],
        step: u64,
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
        let weight = self.cfg.weight;
        out.loss = self.loss_grad(weight, model, params, &sdf, &plan, active, grads);
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mvs::tests::{plane_t, rig};

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

    /// The wall of the thin-wall tests: the slab −0.06 ≤ z ≤ 0, whose top is the plane every
    /// depth map of [`plane_prior`] sees.
    fn slab(pts: &[[f64; 3]]) -> Vec<f64> {
        pts.iter().map(|x| (x[2] + 0.03).abs() - 0.03).collect()
    }

    /// Six rays of view 0 across the image, all with a depth.
    fn six_rays() -> Vec<(usize, [u32; 2])> {
        (0..6).map(|i| (0, [20 + 9 * i, 24 + 6 * i])).collect()
    }

    /// Moves the depth of each of `rays` by `dt` (positive: behind the plane).
    fn shift_depths(p: &mut DepthPrior, rays: &[(usize, [u32; 2])], dt: f32) {
        for &(v, [x, y]) in rays {
            p.maps.t[v][y as usize * p.maps.width[v] + x as usize] += dt;
        }
    }

    /// Carved points of `plan` with `lo < z < hi`.
    fn carved_between(plan: &[CarvedRay], lo: f64, hi: f64) -> usize {
        plan.iter()
            .flat_map(|c| &c.free)
            .filter(|(x, _)| x[2] > lo && x[2] < hi)
            .count()
    }

    /// Spurious handles through thin walls: one view's depth lies behind a thin wall (the
    /// stereo matched the next tooth of a gear, or a hole fill took the far side), while the
    /// other views' measured depths see the wall. Without confirmation the plan carves the
    /// wall's inside along that ray, a tunnel; with `confirm_views = 1` it carves nothing
    /// there, nor pulls the surface to the wrong depth, and a false sheet in front of the
    /// surface, which the other views see past, is still carved. Fills' depths do not confirm.
    #[test]
    fn a_depth_behind_a_thin_wall_carves_the_wall_only_without_confirmation() {
        let cfg = |confirm_views| DepthConfig {
            weight: 1.0,
            confirm_views,
            ..Default::default()
        };
        let (wall, rays) = (slab, six_rays());
        let inside = |plan: &[CarvedRay]| carved_between(plan, -0.055, -0.005);
        let behind = |p: &mut DepthPrior| shift_depths(p, &rays, 0.3);
        let (mut today, _) = plane_prior(cfg(0));
        behind(&mut today);
        let (out, plan) = today.plan(3.0, &wall, 1e-5, &rays);
        assert_eq!(
            out.carved, 6,
            "every wrong depth carves without confirmation"
        );
        assert!(
            inside(&plan) >= 6 * 8,
            "{} points inside the wall",
            inside(&plan)
        );

        let (mut confirmed, _) = plane_prior(cfg(1));
        behind(&mut confirmed);
        let (out, plan) = confirmed.plan(3.0, &wall, 1e-5, &rays);
        assert_eq!(inside(&plan), 0, "no other view sees into the wall");
        assert_eq!(out.with_depth, 6);
        for c in &plan {
            assert!(c.span > c.free.len(), "{} of {}", c.free.len(), c.span);
            assert!(!c.pull, "no other view agrees with a depth behind the wall");
        }
        assert!(today.plan(3.0, &wall, 1e-5, &rays).1.iter().all(|c| c.pull));

        // A false sheet at z = 0.4 over right depths: the other views see past its span.
        let sheet = |pts: &[[f64; 3]]| pts.iter().map(|x| x[2] - 0.4).collect::<Vec<_>>();
        let (p, _) = plane_prior(cfg(1));
        let (out, plan) = p.plan(3.0, &sheet, 1e-5, &rays);
        assert_eq!(out.carved, 6);
        let (kept, span) = plan
            .iter()
            .fold((0, 0), |(k, s), c| (k + c.free.len(), s + c.span));
        assert!(kept * 10 >= span * 9, "{kept} of {span} confirmed");
        assert!(plan.iter().all(|c| c.pull), "right depths are pulled to");
        // ... unless the other views' depths all came from a fill (hole fill or fusion fill).
        let (mut filled, _) = plane_prior(cfg(1));
        for v in 1..filled.maps.hole_filled.len() {
            if v % 2 == 0 {
                filled.maps.hole_filled[v].fill(true);
            } else {
                filled.maps.filled[v].fill(true);
            }
        }
        let (out, _) = filled.plan(3.0, &sheet, 1e-5, &rays);
        assert_eq!(out.carved, 0, "a fill's depth confirms nothing");
    }

    /// The veto's distinction: the inside of a thin wall, just behind the surface the other
    /// views see, is not carved; a hollow deeper than the band behind that surface (a cavity
    /// under a lid, which no other view measures) still is; and a false sheet in front of right
    /// depths is carved as without the veto. A depth the other views see past is not pulled to.
    #[test]
    fn the_veto_keeps_a_walls_inside_and_carves_the_hollow_behind_it() {
        let cfg = |veto_band| DepthConfig {
            weight: 1.0,
            veto_band,
            ..Default::default()
        };
        // The wall over a hollow down to the depth, 0.3 behind the plane.
        let (wall, rays, count) = (slab, six_rays(), carved_between);
        let behind = |p: &mut DepthPrior| shift_depths(p, &rays, 0.3);
        let (mut off, _) = plane_prior(cfg(0.0));
        behind(&mut off);
        let (_, plan_off) = off.plan(3.0, &wall, 1e-5, &rays);
        let (mut on, _) = plane_prior(cfg(0.1));
        behind(&mut on);
        let (out, plan) = on.plan(3.0, &wall, 1e-5, &rays);
        assert_eq!(out.carved, 6);
        assert!(count(&plan_off, -0.055, -0.005) >= 6 * 8);
        assert_eq!(count(&plan, -0.055, -0.005), 0, "the wall's inside is kept");
        // Deeper than the band behind the seen top (z = 0), along the other views' oblique
        // rays: the hollow stays carved, point for point as without the veto.
        let deep = count(&plan_off, -1.0, -0.15);
        assert!(deep >= 6 * 8, "{deep}");
        assert_eq!(count(&plan, -1.0, -0.15), deep);
        // The wrong depth lies in the hollow, where no other view sees past it: still pulled.
        assert!(plan.iter().all(|c| c.pull));
        // Right depths under a false sheet at z = 0.4: carved as without the veto, and pulled.
        let sheet = |pts: &[[f64; 3]]| pts.iter().map(|x| x[2] - 0.4).collect::<Vec<_>>();
        let (p, _) = plane_prior(cfg(0.1));
        let (q, _) = plane_prior(cfg(0.0));
        let (a, b) = (
            p.plan(3.0, &sheet, 1e-5, &rays).1,
            q.plan(3.0, &sheet, 1e-5, &rays).1,
        );
        let kept: usize = a.iter().map(|c| c.free.len()).sum();
        let all: usize = b.iter().map(|c| c.free.len()).sum();
        assert!(kept * 10 >= all * 9, "{kept} of {all}");
        assert!(a.iter().all(|c| c.pull));
        // A depth in front of the plane the other views measure (a bubble in the air): the
        // others see past it, so the surface is not pulled there.
        let (mut early, _) = plane_prior(cfg(0.1));
        shift_depths(&mut early, &rays, -0.2);
        let truth = |pts: &[[f64; 3]]| pts.iter().map(|x| x[2]).collect::<Vec<_>>();
        assert!(early
            .plan(3.0, &truth, 1e-5, &rays)
            .1
            .iter()
            .all(|c| !c.pull));
    }

    /// The photo check: one view's depth behind a wall whose face the images agree on (the
    /// rig's textured plane) carves none of the wall and is not pulled to, while a false sheet
    /// in front of that plane, where the views' windows disagree, is carved and pulled as
    /// without the check. Without the cost (no images given) the check passes every span.
    #[test]
    fn the_photo_check_keeps_a_seen_walls_inside_and_carves_a_sheet_the_images_see_through() {
        let cfg = |photo_check| DepthConfig {
            weight: 1.0,
            photo_check,
            ..Default::default()
        };
        let (_, imgs) = rig();
        let with_photo = |c: DepthConfig| {
            let (p, cams) = plane_prior(c.clone());
            p.with_photo(PhotoCost::new(&c.mvs, &cams, &imgs, None))
        };
        let rays = six_rays();
        let inside = |plan: &[CarvedRay]| carved_between(plan, -0.055, -0.005);
        let mut off = with_photo(cfg(false));
        let mut on = with_photo(cfg(true));
        let (mut bare, _) = plane_prior(cfg(true));
        for p in [&mut off, &mut on, &mut bare] {
            shift_depths(p, &rays, 0.3);
        }
        let (_, plan_off) = off.plan(3.0, &slab, 1e-5, &rays);
        assert!(inside(&plan_off) >= 6 * 8, "{}", inside(&plan_off));
        assert_eq!(bare.plan(3.0, &slab, 1e-5, &rays).1, plan_off);
        let (out, plan) = on.plan(3.0, &slab, 1e-5, &rays);
        assert_eq!((out.with_depth, out.carved), (6, 0));
        assert_eq!(inside(&plan), 0, "the wall's face is photo-consistent");
        assert!(plan.iter().all(|c| !c.pull && c.span > 0));

        let sheet = |pts: &[[f64; 3]]| pts.iter().map(|x| x[2] - 0.4).collect::<Vec<_>>();
        let (on, off) = (with_photo(cfg(true)), with_photo(cfg(false)));
        let (out, plan) = on.plan(3.0, &sheet, 1e-5, &rays);
        assert_eq!(out.carved, 6, "the views see through the sheet");
        assert_eq!(plan, off.plan(3.0, &sheet, 1e-5, &rays).1);
        assert!(plan.iter().all(|c| c.pull));
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
}
