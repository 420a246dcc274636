//! The stereo's matching cost at any point of a pixel's ray, for the depth prior's photo check
//! (`train.depth.photo_check`, `crate::train::depth`).
//!
//! The cost is the one the stereo minimises ([`super::slant`]): `1 − NCC` of the pixel's
//! `(2·window_half + 1)²` grey window against each source view's window warped through a plane,
//! the mean of the `top_k` best sources. The plane passes through the point; its normal is the
//! one given (the field's surface normal, say) or faces the camera (fronto-parallel). A low
//! cost says the images agree that a surface lies there; a high one, or none (too little
//! texture, the window leaves an image, fewer than `top_k` sources see it), says they do not.
//! This is the photo-consistency of space carving (Kutulakos & Seitz, IJCV 2000, §4), asked of
//! one point instead of a voxel.

use super::slant::Matcher;
use super::{nearest_sources, stereo_views, MvsConfig, View};
use crate::scene::{Camera, GrayImage, RgbImage};
use nalgebra::Vector3;

/// The views, their sources and the stereo's settings: what [`PhotoCost::cost`] needs.
pub struct PhotoCost {
    cfg: MvsConfig,
    views: Vec<View>,
    sources: Vec<Vec<usize>>,
}

impl PhotoCost {
    /// The cost over `cameras` (normalised frame), which took `images`; `masks` as for
    /// [`super::depth_maps`] (they only mark the pixels the stereo looked at).
    pub fn new(
        cfg: &MvsConfig,
        cameras: &[Camera],
        images: &[RgbImage],
        masks: Option<&[GrayImage]>,
    ) -> Self {
        assert_eq!(cameras.len(), images.len(), "one image per camera");
        let views = stereo_views(cameras, images, masks);
        let sources = nearest_sources(&views, cfg.sources);
        Self {
            cfg: cfg.clone(),
            views,
            sources,
        }
    }

    /// The cost (`1 − NCC`, in `[0, 2]`) of a surface through the point at distance `t`
    /// (normalised units) along the unit ray through the centre of pixel `(x, y)` of view
    /// `view`, with the world-frame outward normal `normal` (towards the camera; `None`, or a
    /// normal more than 80° from the ray: a plane facing the camera). NaN when the images give
    /// none: the window leaves the image, it holds a non-finite grey or too little texture, the
    /// point lies behind the camera, or fewer than `top_k` sources give a cost.
    pub fn cost(&self, view: usize, x: usize, y: usize, t: f64, normal: Option<[f64; 3]>) -> f32 {
        self.costs(view, x, y, &[(t, normal)])[0]
    }

    /// [`Self::cost`] at several points `(t, normal)` of one pixel's ray, the sources' warps
    /// and the reference window taken once.
    pub fn costs(
        &self,
        view: usize,
        x: usize,
        y: usize,
        at: &[(f64, Option<[f64; 3]>)],
    ) -> Vec<f32> {
        let (vi, hf) = (&self.views[view], self.cfg.window_half);
        let srcs = &self.sources[view];
        let inside = x >= hf && y >= hf && x + hf < vi.w && y + hf < vi.h;
        if !inside || srcs.len() < self.cfg.top_k {
            return vec![f32::NAN; at.len()];
        }
        let m = Matcher::new(&self.cfg, &self.views, view, srcs);
        let Some(reference) = m.reference(x, y) else {
            return vec![f32::NAN; at.len()];
        };
        // `t` along the unit ray is `z·|d|` for the ray `d` whose camera z is 1.
        let dir_norm = vi.dir(x as f64 + 0.5, y as f64 + 0.5).norm();
        let mut scratch = Vec::with_capacity(srcs.len());
        at.iter()
            .map(|&(t, normal)| {
                if !(t.is_finite() && t > 0.0) {
                    return f32::NAN;
                }
                let z = t / dir_norm;
                let front = m.plane_at(x, y, z, Vector3::z());
                let plane = normal
                    .map(|n| {
                        // The plane's normal points away from the camera (`Plane`): minus the
                        // outward one.
                        let nc = -(vi.r * Vector3::from(n));
                        m.plane_at(x, y, z, nc.normalize())
                    })
                    .filter(|pl| {
                        m.depth(pl, x, y)
                            .is_some_and(|zz| (zz - z).abs() <= 1e-9 * z)
                    })
                    .unwrap_or(front);
                m.cost(&plane, x, y, reference, &mut scratch)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{plane_t, rig};
    use super::*;

    /// On the rig's textured plane the cost is lowest at the plane's depth, with the plane's
    /// own normal or facing the camera, and grows off it (the rig's texture is smooth, so
    /// windows a little off the plane still correlate); a window off the image or a
    /// texture-less image gives none.
    #[test]
    fn the_cost_is_lowest_on_the_surface_and_none_without_texture() {
        let (cams, imgs) = rig();
        let cfg = MvsConfig::default();
        let pc = PhotoCost::new(&cfg, &cams, &imgs, None);
        let (mut on, mut far, mut n) = (0.0, 0.0, 0.0);
        for (x, y) in [(30, 30), (48, 40), (60, 50), (40, 25), (55, 33)] {
            let t = plane_t(&cams[0], x as f64 + 0.5, y as f64 + 0.5);
            let c_n = pc.cost(0, x, y, t, Some([0.0, 0.0, 1.0]));
            let c_f = pc.cost(0, x, y, t, None);
            assert!(c_n < 1e-3 && c_f < 1e-2, "on the plane: {c_n}, {c_f}");
            for dt in [-0.1, -0.05, 0.05, 0.1] {
                let c = pc.cost(0, x, y, t + dt, Some([0.0, 0.0, 1.0]));
                assert!(c > c_n, "{dt} off the plane: {c} against {c_n}");
            }
            (on, far, n) = (on + c_n, far + pc.cost(0, x, y, t - 0.4, None), n + 1.0);
        }
        assert!(far / n > 0.3 && on / n < 1e-3, "{on} against {far}");
        // Several points of one ray at once give what one at a time gives.
        let t = plane_t(&cams[0], 48.5, 40.5);
        let at = [
            (t, Some([0.0, 0.0, 1.0])),
            (t - 0.1, None),
            (f64::NAN, None),
        ];
        let both = pc.costs(0, 48, 40, &at);
        assert_eq!(
            both[..2],
            at[..2]
                .iter()
                .map(|&(t, n)| pc.cost(0, 48, 40, t, n))
                .collect::<Vec<_>>()
        );
        assert!(both[2].is_nan());
        let t = plane_t(&cams[0], 0.5, 0.5);
        assert!(
            pc.cost(0, 0, 0, t, None).is_nan(),
            "the window leaves the image"
        );
        assert!(pc.cost(0, 30, 30, f64::NAN, None).is_nan());
        let flat: Vec<RgbImage> = imgs
            .iter()
            .map(|i| {
                let mut f = i.clone();
                f.data.fill(0.5);
                f
            })
            .collect();
        let pc = PhotoCost::new(&cfg, &cams, &flat, None);
        let t = plane_t(&cams[0], 30.5, 30.5);
        assert!(pc.cost(0, 30, 30, t, None).is_nan(), "no texture, no cost");
    }
}
