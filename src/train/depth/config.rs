//! The depth prior's settings (`[train.depth]`), their checks, and the photo check's verdict.

use crate::mvs::MvsConfig;
use serde::{Deserialize, Serialize};

/// Settings of the depth prior (`[train.depth]`); defaults in parentheses.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DepthConfig {
    /// Weight of the loss (0: off, unless `auto` switches it on at `auto.weight`).
    pub weight: f32,
    /// Weight of the `|f(x(t_d))|` term against the hinge's (0.5): how hard the surface is
    /// pulled to the stereo's depth, which is only as good as the stereo there.
    pub surface_weight: f32,
    /// First step that applies it (200).
    pub start_step: u64,
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
    /// Other views that must confirm a point of the free span before it is carved (0: off,
    /// every point is carved). A view confirms a point when the point projects inside its
    /// image onto a pixel whose measured depth (one the consistency check kept, not a fill's)
    /// lies more than `margin` beyond the point's distance from that camera: the view sees
    /// past it. This is the free-space support of visibility-based fusion (Merrell et al.,
    /// ICCV 2007, §4). One view's depth lying behind a thin wall then cannot tunnel through
    /// the wall, whose inside no other view sees past. Likewise the surface term pulls the
    /// field to zero at the depth only where as many other views' measured depths lie within
    /// `margin` of it: a lone depth inside the material would grow a bubble there. Off by
    /// default: it removes most of a gear's spurious handles but costs an open cavity, whose
    /// inside no second view measures, a third or more of its accuracy
    /// (`docs/hard-shapes.md`). Left out of `config.toml` at 0, so the configurations (and
    /// their hashes) of runs made before the key existed still match.
    #[serde(skip_serializing_if = "off")]
    pub confirm_views: usize,
    /// Depth of the band behind another view's seen surface where the free span is not carved,
    /// normalised units (0: off). The opposite test to `confirm_views`: a point is kept unless
    /// some other view's measured depth lies between `veto_band` in front of the point and
    /// `margin` behind it, that is, the point sits just behind a surface another view sees (in
    /// the material of a wall). Likewise the surface is not pulled to a depth that another
    /// view's measured depth sees past by more than `margin` (a free-space violation). Points
    /// no other view measures, such as the inside of a cavity, stay carved. The two conflicts
    /// are Merrell et al.'s occlusion and free-space violation (ICCV 2007, §4). Off by default:
    /// measured so far on one seed of a gear and of the cup only (`docs/hard-shapes.md`). Left
    /// out of `config.toml` at 0.
    #[serde(skip_serializing_if = "zero")]
    pub veto_band: f32,
    /// Photo check of the free span (off): a span is carved, and its depth pulled to, only
    /// where the field's first surface on the ray fails the stereo's own test there, that is,
    /// where its matching cost ([`crate::mvs::PhotoCost`], the plane through the crossing with
    /// the field's normal) is above `mvs.max_cost` or undefined, or the stereo's depth matches
    /// better (a lower cost, facing the camera). A surface the images agree on (a wall's face)
    /// is then not tunnelled by one view's depth behind it, while a lid the views see through
    /// (a cavity's, whose cost is high) is still carved. Space carving's photo-consistency
    /// (Kutulakos & Seitz, IJCV 2000, §4). Left out of `config.toml` when off.
    #[serde(skip_serializing_if = "not")]
    pub photo_check: bool,
    /// Half-width of the photo check's window, pixels (0: the stereo's `mvs.window_half`). The
    /// check tells a surface from no surface rather than finding a depth, so it can afford a
    /// wider window than the stereo, which tells fewer depths apart on a smooth texture. Left
    /// out of `config.toml` at 0.
    #[serde(skip_serializing_if = "off")]
    pub photo_window_half: usize,
    /// Margin of the photo check's comparison, in `1 − NCC` (0: none): the span is carved only
    /// where the field's surface costs more than the stereo's depth by more than this. A
    /// measured depth is the minimum of this very cost along its ray, so without a margin it
    /// wins nearly every comparison; the margin asks the field's surface to be clearly worse.
    /// At most 2 (the cost's range). Left out of `config.toml` at 0.
    #[serde(skip_serializing_if = "zero")]
    pub photo_margin: f32,
    /// The stereo.
    pub mvs: MvsConfig,
    /// The automatic switch: with `weight` 0, whether a check part-way through the run turns
    /// the prior on ([`crate::train::depth_auto`]).
    pub auto: crate::train::depth_auto::DepthAutoConfig,
}

/// Whether an opt-in count is 0 (off).
pub(super) fn off(n: &usize) -> bool {
    *n == 0
}

/// Whether an opt-in switch is off.
fn not(b: &bool) -> bool {
    !*b
}

/// Whether an opt-in length is 0 (off).
fn zero(x: &f32) -> bool {
    *x == 0.0
}

impl Default for DepthConfig {
    fn default() -> Self {
        Self {
            weight: 0.0,
            surface_weight: 0.5,
            start_step: 200,
            rays: 256,
            tau: 0.01,
            spacing: 0.00625,
            margin: 0.0125,
            march_samples: 128,
            refine: 6,
            confirm_views: 0,
            veto_band: 0.0,
            photo_check: false,
            photo_window_half: 0,
            photo_margin: 0.0,
            mvs: MvsConfig::default(),
            auto: Default::default(),
        }
    }
}

impl DepthConfig {
    /// Whether the prior runs at all.
    pub fn enabled(&self) -> bool {
        self.weight > 0.0
    }

    /// Whether it applies at `step`.
    pub fn active_at(&self, step: u64) -> bool {
        self.enabled() && step >= self.start_step
    }

    /// The first invalid field, as `(key, value, why)`.
    pub fn invalid(&self) -> Option<(String, String, &'static str)> {
        let pos = |v: f32| v.is_finite() && v > 0.0;
        let nonneg = |v: f32| v.is_finite() && v >= 0.0;
        let c = |key, ok, value: &dyn std::fmt::Display, why| (key, ok, value.to_string(), why);
        let checks = [
            c("weight", nonneg(self.weight), &self.weight, "must be ≥ 0"),
            c(
                "surface_weight",
                nonneg(self.surface_weight),
                &self.surface_weight,
                "must be ≥ 0",
            ),
            c("rays", self.rays > 0, &self.rays, "must be at least 1"),
            c(
                "tau",
                pos(self.tau),
                &self.tau,
                "must be positive (normalised units)",
            ),
            c(
                "spacing",
                pos(self.spacing),
                &self.spacing,
                "must be positive (normalised units)",
            ),
            c(
                "margin",
                nonneg(self.margin),
                &self.margin,
                "must be ≥ 0 (normalised units)",
            ),
            c(
                "march_samples",
                self.march_samples >= 2,
                &self.march_samples,
                "must be at least 2",
            ),
            c(
                "confirm_views",
                self.confirm_views <= 64,
                &self.confirm_views,
                "must be at most 64 (0: off)",
            ),
            c(
                "photo_window_half",
                self.photo_window_half <= 16,
                &self.photo_window_half,
                "must be at most 16 (pixels; 0: the stereo's window)",
            ),
            c(
                "photo_margin",
                (0.0..=2.0).contains(&self.photo_margin),
                &self.photo_margin,
                "must be in [0, 2] (1 − NCC; 0: none)",
            ),
            c(
                "veto_band",
                nonneg(self.veto_band),
                &self.veto_band,
                "must be ≥ 0 (normalised units; 0: off)",
            ),
        ];
        if let Some((key, _, value, why)) = checks.into_iter().find(|c| !c.1) {
            return Some((format!("train.depth.{key}"), value, why));
        }
        if let Some((key, value, why)) = self.mvs.invalid() {
            return Some((format!("train.depth.mvs.{key}"), value, why));
        }
        self.auto
            .invalid()
            .map(|(key, value, why)| (key.to_string(), value, why))
    }

    /// The photo check's verdict on a span (`photo_check`): whether it may be carved, given
    /// the cost at the field's first surface and at the stereo's depth. Carved when the
    /// field's cost is undefined or above `mvs.max_cost` (the images do not back that
    /// surface), or above the depth's by more than `photo_margin`.
    pub fn photo_carves(&self, at_field: f32, at_depth: f32) -> bool {
        at_field.is_nan() || at_field > self.mvs.max_cost || at_depth + self.photo_margin < at_field
    }

    /// The stereo's settings as the photo check uses them: `mvs` with the check's window.
    pub fn photo_mvs(&self) -> MvsConfig {
        let mut m = self.mvs.clone();
        if self.photo_window_half > 0 {
            m.window_half = self.photo_window_half;
        }
        m
    }

    /// This prior as the automatic switch turns it on after step `check_step`: weight
    /// `auto.weight`, from the later of `start_step` and `check_step` (the first step after
    /// the check).
    pub fn switched_on(&self, check_step: u64) -> Self {
        Self {
            weight: self.auto.weight,
            start_step: self.start_step.max(check_step),
            ..self.clone()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_defaults_are_off_and_checks_name_the_key() {
        let d = DepthConfig::default();
        assert!(!d.enabled() && !d.active_at(1000));
        assert!(d.invalid().is_none());
        let on = DepthConfig {
            weight: 5.0,
            ..Default::default()
        };
        assert!(!on.active_at(199) && on.active_at(200) && on.active_at(100_000));
        let bad = |f: &dyn Fn(&mut DepthConfig)| {
            let mut c = on.clone();
            f(&mut c);
            c.invalid().map(|x| x.0)
        };
        let key = |k: &str| Some(k.to_string());
        assert_eq!(bad(&|c| c.weight = f32::NAN), key("train.depth.weight"));
        assert_eq!(bad(&|c| c.rays = 0), key("train.depth.rays"));
        assert_eq!(bad(&|c| c.margin = -1.0), key("train.depth.margin"));
        assert_eq!(bad(&|c| c.mvs.top_k = 5), key("train.depth.mvs.top_k"));
        assert_eq!(bad(&|c| c.mvs.planes = 1), key("train.depth.mvs.planes"));
        assert_eq!(
            bad(&|c| c.confirm_views = 65),
            key("train.depth.confirm_views")
        );
        // The opt-in keys are written only when on, so older configurations keep their hash.
        let saved = |f: &dyn Fn(&mut DepthConfig)| {
            let mut c = DepthConfig::default();
            f(&mut c);
            toml::to_string(&c).unwrap()
        };
        let defaults = saved(&|_| {});
        assert!(!defaults.contains("confirm_views"));
        assert!(saved(&|c| c.confirm_views = 1).contains("confirm_views = 1"));
        assert_eq!(bad(&|c| c.veto_band = -0.1), key("train.depth.veto_band"));
        assert_eq!(
            bad(&|c| c.veto_band = f32::NAN),
            key("train.depth.veto_band")
        );
        assert!(!defaults.contains("veto_band"));
        assert!(saved(&|c| c.veto_band = 0.05).contains("veto_band = 0.05"));
        assert_eq!(
            bad(&|c| c.photo_window_half = 17),
            key("train.depth.photo_window_half")
        );
        let photo = saved(&|c| {
            c.photo_check = true;
            c.photo_window_half = 4;
            c.photo_margin = 0.1;
        });
        assert!(photo.contains("photo_check = true") && photo.contains("photo_window_half = 4"));
        assert!(photo.contains("photo_margin = 0.1"), "{photo}");
        // The verdict: an undefined or too-high field cost carves; otherwise the field's cost
        // must exceed the depth's by more than the margin.
        let m = |photo_margin| DepthConfig {
            photo_margin,
            ..Default::default()
        };
        let max = d.mvs.max_cost;
        assert!(m(0.0).photo_carves(f32::NAN, 0.1) && m(0.5).photo_carves(max + 0.01, max));
        assert!(m(0.0).photo_carves(0.3, 0.2) && !m(0.0).photo_carves(0.2, 0.3));
        assert!(!m(0.2).photo_carves(0.3, 0.2) && m(0.05).photo_carves(0.3, 0.2));
        assert_eq!(
            bad(&|c| c.photo_margin = 2.5),
            key("train.depth.photo_margin")
        );
        assert_eq!(
            bad(&|c| c.photo_margin = f32::NAN),
            key("train.depth.photo_margin")
        );
        assert!(
            !defaults.contains("photo"),
            "all three are left out when off"
        );
        let wide = DepthConfig {
            photo_window_half: 4,
            ..Default::default()
        };
        assert_eq!(
            (wide.photo_mvs().window_half, d.photo_mvs()),
            (4, d.mvs.clone())
        );
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
        for (f, k) in cases {
            assert_eq!(bad(&f), Some(format!("train.depth.mvs.{k}")));
        }
        // TOML: a section with one key keeps every other default.
        let t: DepthConfig = toml::from_str("weight = 5.0\n[mvs]\nplanes = 64\n").unwrap();
        assert_eq!(t.mvs.planes, 64);
        assert_eq!(t.mvs.top_k, 2);
        assert!(t.enabled());
        assert!(toml::from_str::<DepthConfig>("wieght = 5.0\n").is_err());
    }
}
