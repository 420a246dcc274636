//! Training rays: random pixels of the training views, turned into rays in the normalised space,
//! with their (possibly augmented) target colours, masks and appearance inputs.
//!
//! Sampling follows instant-nsr-pl `systems/neus.py` (`batch_image_sampling: true`): each ray
//! draws its own view uniformly and its own pixel uniformly, and goes through the pixel centre
//! (`x + 0.5, y + 0.5`, `scene::camera`). With masks, the target colour is composited on the
//! background, `rgb·m + bg·(1 − m)` (`apply_mask: true` there). With `train.error_map` on, a
//! share of the pixels is drawn where the colour error is high instead ([`super::error_map`]).

use super::error_map::ErrorMap;
use crate::augment::{AugSample, AugSampler};
use crate::scene::{Camera, GrayImage};
use rand::Rng;

/// Why training data cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// No view is left to train on.
    #[error("no training view left (after the held-out views and the views fraction)")]
    NoViews,
    /// Masks exist but none has an object pixel.
    #[error("every training mask is empty: nothing marks the object (check mask/ of the scene)")]
    AllMasksEmpty,
    /// Views, cameras and masks disagree in number or size.
    #[error("training data is inconsistent: {0}")]
    Inconsistent(String),
}

/// Per-view ray generator: `dir = normalize(M·[u, v, 1])` with `M = Rᵀ·K⁻¹`, origin `C`
/// (normalised space).
#[derive(Clone, Copy, Debug)]
struct RayCamera {
    m: [[f64; 3]; 3],
    origin: [f32; 3],
    width: u32,
    height: u32,
}

impl RayCamera {
    fn new(c: &Camera) -> Self {
        let k_inv = c.k.try_inverse().expect("K has a positive diagonal");
        let m = c.r.transpose() * k_inv;
        Self {
            m: std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)])),
            origin: [c.center.x as f32, c.center.y as f32, c.center.z as f32],
            width: c.width,
            height: c.height,
        }
    }

    /// Origin and unit direction of the ray through continuous pixel coordinates `(u, v)`.
    #[inline]
    fn ray(&self, u: f64, v: f64) -> ([f32; 3], [f32; 3]) {
        let m = &self.m;
        let d = [
            m[0][0] * u + m[0][1] * v + m[0][2],
            m[1][0] * u + m[1][1] * v + m[1][2],
            m[2][0] * u + m[2][1] * v + m[2][2],
        ];
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        (
            self.origin,
            [(d[0] / n) as f32, (d[1] / n) as f32, (d[2] / n) as f32],
        )
    }
}

/// A batch of training rays, struct-of-arrays, reused between steps (no allocation once grown).
#[derive(Clone, Debug, Default)]
pub struct Batch {
    /// `[n][3]` origins (normalised space).
    pub origins: Vec<[f32; 3]>,
    /// `[n][3]` unit directions.
    pub dirs: Vec<[f32; 3]>,
    /// `[n]` appearance codes (0 without augmentation).
    pub codes: Vec<u32>,
    /// `[n]` augmentation intensities fed to the colour network (DIA), else 0.
    pub p: Vec<f32>,
    /// `[n][3]` target colours, composited on the background where masks exist.
    pub rgb: Vec<[f32; 3]>,
    /// `[n]` mask values in `[0, 1]`; empty when the scene has no masks.
    pub mask: Vec<f32>,
    /// `[n]` training view of each ray (index into the cameras given to [`TrainData::new`]).
    pub views: Vec<u32>,
    /// `[n]` pixel `[x, y]` each ray goes through (its centre).
    pub pixels: Vec<[u32; 2]>,
    samples: Vec<AugSample>,
}

impl Batch {
    /// Number of rays.
    pub fn len(&self) -> usize {
        self.origins.len()
    }

    /// True when the batch has no ray.
    pub fn is_empty(&self) -> bool {
        self.origins.is_empty()
    }
}

/// The training set: cameras, the augmentation sampler that owns the images, and masks.
pub struct TrainData {
    cameras: Vec<RayCamera>,
    sampler: AugSampler,
    masks: Option<Vec<GrayImage>>,
    background: [f32; 3],
}

impl TrainData {
    /// `cameras[i]` (normalised space) goes with image `i` of `sampler` and `masks[i]`.
    /// `background`: the colour the renderer composites behind the object.
    pub fn new(
        cameras: &[Camera],
        sampler: AugSampler,
        masks: Option<Vec<GrayImage>>,
        background: [f32; 3],
    ) -> Result<Self, DataError> {
        if cameras.is_empty() {
            return Err(DataError::NoViews);
        }
        let views = sampler.views();
        if views.len() != cameras.len() {
            return Err(DataError::Inconsistent(format!(
                "{} images for {} cameras",
                views.len(),
                cameras.len()
            )));
        }
        for (i, (img, cam)) in views.iter().zip(cameras).enumerate() {
            if (img.width, img.height) != (cam.width as usize, cam.height as usize) {
                return Err(DataError::Inconsistent(format!(
                    "view {i}: image {}×{} but camera {}×{}",
                    img.width, img.height, cam.width, cam.height
                )));
            }
        }
        if let Some(m) = &masks {
            if m.len() != cameras.len() {
                return Err(DataError::Inconsistent(format!(
                    "{} masks for {} views",
                    m.len(),
                    cameras.len()
                )));
            }
            if m.iter().all(|m| m.data.iter().all(|&v| v <= 0.5)) {
                return Err(DataError::AllMasksEmpty);
            }
        }
        Ok(Self {
            cameras: cameras.iter().map(RayCamera::new).collect(),
            sampler,
            masks,
            background,
        })
    }

    /// Number of training views.
    pub fn n_views(&self) -> usize {
        self.cameras.len()
    }

    /// The masks, in camera order (`None`: the run has none).
    pub fn masks(&self) -> Option<&[GrayImage]> {
        self.masks.as_deref()
    }

    /// Whether the mask loss can be used.
    pub fn has_masks(&self) -> bool {
        self.masks.is_some()
    }

    /// The training images before augmentation (degraded, when the run degrades them), in the
    /// order of the cameras given to [`TrainData::new`].
    pub fn views(&self) -> &[crate::scene::RgbImage] {
        self.sampler.views()
    }

    /// Training-view sizes `(width, height)` in pixels, in camera order.
    pub fn sizes(&self) -> Vec<(u32, u32)> {
        self.cameras.iter().map(|c| (c.width, c.height)).collect()
    }

    /// Fills `batch` with `n` rays. `rng` picks views and pixels; `aug_rng` draws augmentations
    /// (separate streams, so runs with and without augmentation visit the same pixels). With an
    /// `error_map` ([`super::error_map`]), a ray's pixel comes from the map with probability
    /// `share` (one more draw of `rng` per ray); without, the draws are those of the uniform
    /// sampler alone.
    pub fn sample(
        &self,
        n: usize,
        rng: &mut impl Rng,
        aug_rng: &mut impl Rng,
        error_map: Option<&ErrorMap>,
        batch: &mut Batch,
    ) {
        batch.origins.clear();
        batch.dirs.clear();
        batch.codes.clear();
        batch.p.clear();
        batch.rgb.clear();
        batch.mask.clear();
        batch.samples.clear();
        batch.views.clear();
        batch.pixels.clear();
        let nv = self.cameras.len();
        for _ in 0..n {
            let v = rng.random_range(0..nv);
            let cam = &self.cameras[v];
            let (x, y) = match error_map {
                Some(m) if rng.random::<f32>() < m.config().share => m.sample_pixel(v, rng),
                _ => (
                    rng.random_range(0..cam.width),
                    rng.random_range(0..cam.height),
                ),
            };
            batch.views.push(v as u32);
            batch.pixels.push([x, y]);
            let (o, d) = cam.ray(x as f64 + 0.5, y as f64 + 0.5);
            let s = self.sampler.sample(aug_rng, v, x as usize, y as usize);
            let rgb = match &self.masks {
                Some(masks) => {
                    let m = masks[v].get(x as usize, y as usize);
                    batch.mask.push(m);
                    std::array::from_fn(|c| s.rgb[c] * m + self.background[c] * (1.0 - m))
                }
                None => s.rgb,
            };
            batch.origins.push(o);
            batch.dirs.push(d);
            batch.codes.push(s.code);
            batch.p.push(s.p);
            batch.rgb.push(rgb);
        }
    }
}

/// Rays through every pixel centre of a camera (row-major), for rendering a whole view.
pub fn camera_rays(camera: &Camera) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let rc = RayCamera::new(camera);
    let n = (rc.width * rc.height) as usize;
    let mut origins = Vec::with_capacity(n);
    let mut dirs = Vec::with_capacity(n);
    for y in 0..rc.height {
        for x in 0..rc.width {
            let (o, d) = rc.ray(x as f64 + 0.5, y as f64 + 0.5);
            origins.push(o);
            dirs.push(d);
        }
    }
    (origins, dirs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::augment::AugmentConfig;
    use crate::scene::RgbImage;
    use nalgebra::{Matrix3, Vector3};
    use rand::SeedableRng;

    fn camera() -> Camera {
        Camera {
            k: Matrix3::new(40.0, 0.3, 16.0, 0.0, 42.0, 12.0, 0.0, 0.0, 1.0),
            r: nalgebra::Rotation3::from_euler_angles(0.1, -0.2, 0.3).into_inner(),
            center: Vector3::new(0.5, -2.0, 1.5),
            width: 32,
            height: 24,
        }
    }

    #[test]
    fn rays_match_the_camera_and_targets_are_masked() {
        let cam = camera();
        let img = RgbImage::from_fn(32, 24, |x, y| [x as f32 / 32.0, y as f32 / 24.0, 0.25]);
        let mut mask = GrayImage::new(32, 24);
        for x in 0..16 {
            for y in 0..24 {
                mask.data[y * 32 + x] = 1.0;
            }
        }
        let sampler = AugSampler::new(vec![img.clone()], &AugmentConfig::default()).unwrap();
        let data = TrainData::new(
            std::slice::from_ref(&cam),
            sampler,
            Some(vec![mask]),
            [1.0; 3],
        )
        .unwrap();
        let mut batch = Batch::default();
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(1);
        let mut aug = rand_pcg::Pcg64Mcg::seed_from_u64(2);
        data.sample(500, &mut rng, &mut aug, None, &mut batch);
        assert_eq!(batch.len(), 500);
        for i in 0..batch.len() {
            // The ray projects back to a pixel centre; recover the pixel and check the target.
            let o = batch.origins[i].map(|v| v as f64);
            let d = batch.dirs[i].map(|v| v as f64);
            let p = Vector3::new(o[0] + 3.0 * d[0], o[1] + 3.0 * d[1], o[2] + 3.0 * d[2]);
            let (u, v, _) = cam.project(&p).unwrap();
            let (x, y) = ((u - 0.5).round(), (v - 0.5).round());
            assert!((u - 0.5 - x).abs() < 1e-4 && (v - 0.5 - y).abs() < 1e-4);
            assert_eq!(batch.pixels[i], [x as u32, y as u32]);
            assert_eq!(batch.views[i], 0);
            let (x, y) = (x as usize, y as usize);
            let expect = if x < 16 { img.get(x, y) } else { [1.0; 3] };
            assert_eq!(batch.rgb[i], expect);
            assert_eq!(batch.mask[i], if x < 16 { 1.0 } else { 0.0 });
            assert_eq!((batch.codes[i], batch.p[i]), (0, 0.0));
        }
    }

    #[test]
    fn empty_masks_and_no_views_are_errors() {
        let cam = camera();
        let sampler =
            AugSampler::new(vec![RgbImage::new(32, 24)], &AugmentConfig::default()).unwrap();
        let err = TrainData::new(
            &[cam],
            sampler,
            Some(vec![GrayImage::new(32, 24)]),
            [1.0; 3],
        );
        assert!(matches!(err, Err(DataError::AllMasksEmpty)));
        // The sampler itself refuses an empty image list; cameras without views are refused here.
        assert!(AugSampler::new(vec![], &AugmentConfig::default()).is_err());
        let sampler =
            AugSampler::new(vec![RgbImage::new(32, 24)], &AugmentConfig::default()).unwrap();
        assert!(matches!(
            TrainData::new(&[], sampler, None, [1.0; 3]),
            Err(DataError::NoViews)
        ));
    }

    #[test]
    fn whole_view_rays_go_through_pixel_centres() {
        let cam = camera();
        let (o, d) = camera_rays(&cam);
        assert_eq!(o.len(), 32 * 24);
        let i = 5 * 32 + 7;
        let (_, dr) = cam.ray(7.5, 5.5);
        for k in 0..3 {
            assert!((d[i][k] as f64 - dr[k]).abs() < 1e-6);
        }
    }
}
