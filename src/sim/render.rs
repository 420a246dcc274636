//! The renderer: closest-hit ray casting on obvhs, a fixed sub-pixel pattern, and only the
//! effects the description lists.
//!
//! Per view and pixel: `spp` primary rays through the fixed offsets of [`sample_offsets`]; each
//! hit is shaded ([`SimScene::render_view`] lists the order of operations), the samples are
//! averaged, then the per-view exposure gain is applied and values are clipped to `[0, 1]`, then
//! the degradations run in order. The mask is 1 where more than half the pixel's samples hit the
//! object (the ground plane never counts; with `spp = 1` the pixel centre decides), else 0.
//!
//! Rows are rendered in parallel (rayon); every pixel depends only on its own samples, and the
//! [`Counters`] are integer sums, so the output does not depend on thread scheduling. Per-view
//! random draws (exposure, light jitter, degradations) come from their own generator seeded by
//! `(scene seed, effect, view)`, so switching one effect never changes another's draws.

use super::setup::SimScene;
use super::texture::mix64;
use crate::scene::{GrayImage, RgbImage};
use glam::Vec3A;
use nalgebra::{Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use serde::Serialize;

/// Work done by the renderer, per kind: the proof that an absent effect costs nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Counters {
    /// Camera rays (pixels × spp).
    pub primary_rays: u64,
    /// Primary rays that hit the object.
    pub object_hits: u64,
    /// Primary rays that hit the ground plane.
    pub plane_hits: u64,
    /// Shadow rays traced towards the light.
    pub shadow_rays: u64,
    /// Procedural texture evaluations.
    pub texture_evals: u64,
    /// Lambert shading evaluations.
    pub lambert_evals: u64,
    /// Smooth-normal interpolations.
    pub normal_interps: u64,
    /// Blinn-Phong evaluations.
    pub specular_evals: u64,
    /// Views whose exposure gain was drawn and applied.
    pub exposure_views: u64,
    /// Views whose light direction was jittered.
    pub light_jitter_views: u64,
    /// Degradation applications (one per degradation per view).
    pub degrade_calls: u64,
}

impl std::ops::Add for Counters {
    type Output = Counters;
    fn add(self, o: Counters) -> Counters {
        Counters {
            primary_rays: self.primary_rays + o.primary_rays,
            object_hits: self.object_hits + o.object_hits,
            plane_hits: self.plane_hits + o.plane_hits,
            shadow_rays: self.shadow_rays + o.shadow_rays,
            texture_evals: self.texture_evals + o.texture_evals,
            lambert_evals: self.lambert_evals + o.lambert_evals,
            normal_interps: self.normal_interps + o.normal_interps,
            specular_evals: self.specular_evals + o.specular_evals,
            exposure_views: self.exposure_views + o.exposure_views,
            light_jitter_views: self.light_jitter_views + o.light_jitter_views,
            degrade_calls: self.degrade_calls + o.degrade_calls,
        }
    }
}

impl std::iter::Sum for Counters {
    fn sum<I: Iterator<Item = Counters>>(iter: I) -> Counters {
        iter.fold(Counters::default(), |a, b| a + b)
    }
}

/// Tags that separate the per-view random streams of the effects.
pub(crate) mod stream {
    pub const EXPOSURE: u64 = 0x45_5850; // "EXP"
    pub const LIGHT: u64 = 0x4C_4954; // "LIT"
    pub const DEGRADE: u64 = 0x44_4547; // "DEG"
}

/// The generator of `effect`'s draws for `view` (and `k`-th item) of a scene with `seed`.
pub(crate) fn view_rng(seed: u64, effect: u64, view: usize, k: usize) -> Pcg64Mcg {
    Pcg64Mcg::seed_from_u64(mix64(mix64(mix64(seed ^ effect) ^ view as u64) ^ k as u64))
}

/// The sub-pixel sample positions, offsets in `[0, 1)²` from the pixel's corner, shared by every
/// pixel: `spp = 1` is the centre `(0.5, 0.5)`; a square `spp = n²` is the centres of an `n × n`
/// grid; other counts use the rank-1 lattice `((k + 0.5)/spp, frac(0.5 + k·φ⁻¹))`.
pub fn sample_offsets(spp: u32) -> Vec<[f64; 2]> {
    let n = (spp as f64).sqrt().round() as u32;
    if n * n == spp {
        (0..spp)
            .map(|k| {
                [
                    ((k % n) as f64 + 0.5) / n as f64,
                    ((k / n) as f64 + 0.5) / n as f64,
                ]
            })
            .collect()
    } else {
        let inv_phi = 0.618_033_988_749_894_9;
        (0..spp)
            .map(|k| {
                [
                    (k as f64 + 0.5) / spp as f64,
                    (0.5 + k as f64 * inv_phi).fract(),
                ]
            })
            .collect()
    }
}

/// One rendered view.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewRender {
    /// RGB in `[0, 1]`.
    pub image: RgbImage,
    /// Object mask, 0 or 1.
    pub mask: GrayImage,
    /// Work done for this view.
    pub counters: Counters,
}

/// What the shading of one view needs.
struct ViewCtx<'a> {
    scene: &'a SimScene,
    origin: Vec3A,
    /// Rig-frame ray direction (unnormalised) of pixel coordinates `(u, v, 1)`.
    pix_to_dir: Matrix3<f64>,
    light: Option<Vec3A>,
    offsets: Vec<[f64; 2]>,
}

fn to_v3a(v: &Vector3<f64>) -> Vec3A {
    Vec3A::new(v.x as f32, v.y as f32, v.z as f32)
}

/// Turns the unit vector `l` by `angle` (radians) about the unit axis `cos φ·a + sin φ·b`
/// perpendicular to it (`a`, `b`: an orthonormal basis of `l`'s normal plane).
fn turn(l: Vector3<f64>, angle: f64, phi: f64) -> Vector3<f64> {
    let helper = if l.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let a = l.cross(&helper).normalize();
    let b = l.cross(&a);
    let axis = a * phi.cos() + b * phi.sin();
    l * angle.cos() + axis.cross(&l) * angle.sin()
}

impl SimScene {
    /// The light direction of a view (rig frame, unit): the shading's direction, turned by the
    /// light-jitter effect when it is on. `None` without Lambert shading.
    pub fn view_light(&self, view: usize, counters: &mut Counters) -> Option<Vector3<f64>> {
        let shading = self.desc.effects.lambert()?;
        let l = Vector3::from(shading.direction).normalize();
        Some(match self.desc.effects.light_jitter() {
            None => l,
            Some(j) => {
                counters.light_jitter_views += 1;
                let mut rng = view_rng(self.desc.seed, stream::LIGHT, view, 0);
                let angle = j.degrees.to_radians() * rng.random::<f64>();
                let phi = std::f64::consts::TAU * rng.random::<f64>();
                turn(l, angle, phi)
            }
        })
    }

    /// The exposure gain of a view (1 without the exposure effect, and then nothing is drawn).
    pub fn view_gain(&self, view: usize, counters: &mut Counters) -> Option<f32> {
        let e = self.desc.effects.exposure()?;
        counters.exposure_views += 1;
        let mut rng = view_rng(self.desc.seed, stream::EXPOSURE, view, 0);
        let z: f64 = StandardNormal.sample(&mut rng);
        Some((e.sigma as f64 * z).exp() as f32)
    }

    /// Renders view `view`. Per sample: closest hit; albedo (object: the texture if on, else
    /// `object.albedo`; plane: its checker); then, with Lambert shading, the normal (smooth if
    /// asked), `n·l`, a shadow ray if shadows are on and `n·l > 0`, and Blinn-Phong if specular
    /// is on; without shading the albedo is the colour. Then per pixel: average, exposure gain,
    /// clip; then per view: degradations.
    pub fn render_view(&self, view: usize) -> ViewRender {
        let cam = &self.cameras[view];
        let (w, h) = (cam.width as usize, cam.height as usize);
        let mut counters = Counters::default();
        let light = self.view_light(view, &mut counters).map(|l| to_v3a(&l));
        let gain = self.view_gain(view, &mut counters);
        let k_inv = cam.k.try_inverse().expect("rig intrinsics are invertible");
        let rig_from_world = self.frame.rotation.transpose();
        let ctx = ViewCtx {
            scene: self,
            origin: to_v3a(&self.frame.to_rig(&cam.center)),
            pix_to_dir: rig_from_world * cam.r.transpose() * k_inv,
            light,
            offsets: sample_offsets(self.desc.render.spp),
        };
        let mut image = RgbImage::new(w, h);
        let mut mask = GrayImage::new(w, h);
        let row_counters: Counters = image
            .data
            .par_chunks_mut(w * 3)
            .zip(mask.data.par_chunks_mut(w))
            .enumerate()
            .map(|(y, (row, mrow))| ctx.render_row(y, row, mrow, gain))
            .sum();
        counters = counters + row_counters;
        for (k, spec) in self.degradations.iter().enumerate() {
            let mut rng = view_rng(self.desc.seed, stream::DEGRADE, view, k);
            image = spec.apply(&image, &mut rng);
            counters.degrade_calls += 1;
        }
        ViewRender {
            image,
            mask,
            counters,
        }
    }
}

impl ViewCtx<'_> {
    fn render_row(
        &self,
        y: usize,
        row: &mut [f32],
        mrow: &mut [f32],
        gain: Option<f32>,
    ) -> Counters {
        let mut c = Counters::default();
        let spp = self.offsets.len();
        let inv = 1.0 / spp as f32;
        for (x, px) in row.chunks_exact_mut(3).enumerate() {
            let mut acc = [0f32; 3];
            let mut object = 0usize;
            for o in &self.offsets {
                let uv = Vector3::new(x as f64 + o[0], y as f64 + o[1], 1.0);
                let d = (self.pix_to_dir * uv).normalize();
                let (rgb, is_object) = self.sample(to_v3a(&d), &mut c);
                object += is_object as usize;
                for k in 0..3 {
                    acc[k] += rgb[k];
                }
            }
            let g = gain.unwrap_or(1.0);
            for k in 0..3 {
                px[k] = (acc[k] * inv * g).clamp(0.0, 1.0);
            }
            mrow[x] = if 2 * object > spp { 1.0 } else { 0.0 };
        }
        c
    }

    /// The colour of one camera ray and whether it hit the object.
    fn sample(&self, d: Vec3A, c: &mut Counters) -> ([f32; 3], bool) {
        let s = self.scene;
        c.primary_rays += 1;
        let tracer = s.render_tracer.as_ref().unwrap_or(&s.object_tracer);
        let Some((prim, t)) = tracer.closest(self.origin, d) else {
            return (s.desc.render.background, false);
        };
        let p = self.origin + d * t;
        let n_obj = s.object_tris.len() as u32;
        let on_object = prim < n_obj;
        let albedo = if on_object {
            c.object_hits += 1;
            match &s.texture {
                Some(tex) => {
                    c.texture_evals += 1;
                    tex.albedo(p.to_array())
                }
                None => s.desc.object.albedo,
            }
        } else {
            c.plane_hits += 1;
            let gp = s
                .desc
                .effects
                .ground_plane()
                .expect("plane triangles exist only with the ground plane effect");
            let k = (p.x / gp.checker_mm).floor() as i64 + (p.y / gp.checker_mm).floor() as i64;
            gp.colors[k.rem_euclid(2) as usize]
        };
        let Some(l) = self.light else {
            return (albedo, on_object);
        };
        let shading = s
            .desc
            .effects
            .lambert()
            .expect("a light implies Lambert shading");
        c.lambert_evals += 1;
        // Geometric normal, turned towards the viewer.
        let (mut ng, corners) = if on_object {
            let tri = &s.object_tris[prim as usize];
            (
                tri.compute_normal(),
                s.corner_normals.as_ref().map(|n| (tri, n[prim as usize])),
            )
        } else {
            (Vec3A::Z, None)
        };
        let flip = ng.dot(d) > 0.0;
        if flip {
            ng = -ng;
        }
        let mut n = ng;
        if let Some((tri, cn)) = corners {
            c.normal_interps += 1;
            let b = barycentric(tri.v0, tri.v1, tri.v2, p);
            let mut ns = (cn[0] * b[0] + cn[1] * b[1] + cn[2] * b[2]).normalize_or_zero();
            if flip {
                ns = -ns;
            }
            // Interpolation can tilt the normal past the silhouette; keep the geometric one then.
            if ns.dot(d) < 0.0 {
                n = ns;
            }
        }
        let ndl = n.dot(l).max(0.0);
        let mut visible = 1.0;
        if ndl > 0.0 {
            if let Some(sh) = s.desc.effects.shadows() {
                c.shadow_rays += 1;
                let start = p + ng * sh.offset_mm;
                if tracer.occluded(start, l, 0.0, f32::INFINITY) {
                    visible = 0.0;
                }
            }
        }
        let lit = shading.ambient + shading.diffuse * ndl * visible;
        let mut rgb = albedo.map(|a| a * lit);
        if let Some(sp) = s.desc.effects.specular() {
            c.specular_evals += 1;
            if ndl > 0.0 && visible > 0.0 {
                let hv = (l - d).normalize_or_zero();
                let spec = sp.strength * n.dot(hv).max(0.0).powf(sp.exponent);
                for v in &mut rgb {
                    *v += spec;
                }
            }
        }
        (rgb, on_object)
    }
}

/// Barycentric weights of `p` (on the triangle's plane) for `v0, v1, v2`.
fn barycentric(v0: Vec3A, v1: Vec3A, v2: Vec3A, p: Vec3A) -> [f32; 3] {
    let n = (v1 - v0).cross(v2 - v0);
    let nn = n.length_squared();
    if nn == 0.0 {
        return [1.0 / 3.0; 3];
    }
    let b1 = (p - v0).cross(v2 - v0).dot(n) / nn;
    let b2 = (v1 - v0).cross(p - v0).dot(n) / nn;
    [1.0 - b1 - b2, b1, b2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_patterns_are_fixed_and_inside_the_pixel() {
        assert_eq!(sample_offsets(1), vec![[0.5, 0.5]]);
        assert_eq!(
            sample_offsets(4),
            vec![[0.25, 0.25], [0.75, 0.25], [0.25, 0.75], [0.75, 0.75]]
        );
        for spp in [2, 3, 5, 7, 16] {
            let s = sample_offsets(spp);
            assert_eq!(s.len(), spp as usize);
            assert!(s.iter().flatten().all(|v| (0.0..1.0).contains(v)));
            // Mean near the pixel centre.
            let mx = s.iter().map(|p| p[0]).sum::<f64>() / spp as f64;
            assert!((mx - 0.5).abs() < 1e-12);
        }
    }

    #[test]
    fn barycentric_weights_reconstruct_the_point() {
        let (a, b, c) = (
            Vec3A::new(0.0, 0.0, 1.0),
            Vec3A::new(2.0, 0.0, 1.0),
            Vec3A::new(0.0, 3.0, 1.0),
        );
        let p = Vec3A::new(0.5, 0.75, 1.0);
        let w = barycentric(a, b, c, p);
        let q = a * w[0] + b * w[1] + c * w[2];
        assert!((q - p).length() < 1e-6, "{w:?}");
        assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn turning_keeps_unit_length_and_angle() {
        let l = Vector3::new(-0.4, -0.5, 0.77).normalize();
        for (angle, phi) in [(0.0, 1.0), (0.3, 0.0), (0.3, 2.0), (1.2, 5.0)] {
            let m = turn(l, angle, phi);
            assert!((m.norm() - 1.0).abs() < 1e-12);
            let between = m.cross(&l).norm().atan2(m.dot(&l));
            assert!((between - angle).abs() < 1e-12, "{between} vs {angle}");
        }
    }
}
