//! Loading and writing a scene folder in the NeuS / IDR DTU layout.
//!
//! ```text
//! <scene>/image/000000.png ...     RGB photographs (any zero padding; sorted numerically)
//! <scene>/mask/000.png ...         object masks (optional; sorted numerically)
//! <scene>/cameras_sphere.npz       world_mat_i (4×4, P = K[R|t] plus a [0,0,0,1] row) and
//!                                  scale_mat_i (4×4, diag(s,s,s,1) + the object centre)
//! ```
//! The i-th image in sorted order uses `world_mat_i` and `scale_mat_i`, and the i-th mask, as
//! Totoro97/NeuS `models/dataset.py` pairs them (lioryariv/idr `DATA_CONVENTION.md`). Cameras are
//! decomposed from `P = (world_mat · scale_mat)[:3, :4]`, so they live in the normalised space
//! where the object's region is inside the unit sphere; [`Normalization`] maps back to world mm.

use super::camera::{Camera, CameraError};
use super::image::{GrayImage, ImageError, RgbImage};
use super::npz::{self, NpArray, NpzError};
use nalgebra::{Matrix3x4, Matrix4, Vector3};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The camera file's name inside a scene folder.
pub const CAMERA_FILE: &str = "cameras_sphere.npz";

/// Why a scene folder cannot be loaded or written. Every variant names the file or key at fault.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene path does not exist or is not a directory.
    #[error("scene folder {0} does not exist or is not a directory")]
    NotADirectory(PathBuf),
    /// `cameras_sphere.npz` is absent.
    #[error("{0} is missing: a NeuS/IDR scene needs world_mat_i and scale_mat_i for every image")]
    MissingCameras(PathBuf),
    /// `image/` holds no PNG file.
    #[error("no PNG images in {0}")]
    NoImages(PathBuf),
    /// A file name under `image/` or `mask/` has no number to sort by.
    #[error("{0}: file name has no number to sort by (expected e.g. 000012.png)")]
    UnnumberedFile(PathBuf),
    /// A key the layout needs is absent from the camera file.
    #[error("{file}: key '{key}' is missing ({why})")]
    MissingKey {
        file: PathBuf,
        key: String,
        why: String,
    },
    /// A camera-file array has the wrong shape or non-finite values.
    #[error("{file}: '{key}' {problem}")]
    BadArray {
        file: PathBuf,
        key: String,
        problem: String,
    },
    /// A projection matrix does not decompose into a camera.
    #[error("{file}: '{key}' is not a valid camera: {source}")]
    BadCamera {
        file: PathBuf,
        key: String,
        #[source]
        source: CameraError,
    },
    /// `mask/` and `image/` hold different numbers of files.
    #[error("{dir} holds {masks} masks but image/ holds {images} images")]
    MaskCount {
        dir: PathBuf,
        masks: usize,
        images: usize,
    },
    /// An image and its mask differ in size.
    #[error("mask {mask} is {mask_w}×{mask_h} but image {image} is {image_w}×{image_h}")]
    SizeMismatch {
        image: PathBuf,
        mask: PathBuf,
        image_w: usize,
        image_h: usize,
        mask_w: usize,
        mask_h: usize,
    },
    /// A downscale factor that leaves no pixel, or zero.
    #[error("downscale factor {factor} is invalid for {width}×{height} images")]
    BadDownscale {
        factor: u32,
        width: usize,
        height: usize,
    },
    /// Image input/output failed.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// Camera-file input/output failed.
    #[error(transparent)]
    Npz(#[from] NpzError),
    /// A directory could not be listed or created.
    #[error("cannot access {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// The similarity from normalised space to world space, `X_world = s·X_norm + c`, read from
/// `scale_mat_0` (NeuS uses the first view's for the object's bounding box).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Normalization {
    /// `s`: world units (mm) per normalised unit.
    pub scale: f64,
    /// `c`: the world position of the normalised origin (mm).
    pub center: [f64; 3],
}

impl Normalization {
    /// Reads `diag(s,s,s,1)` + translation; other matrices (anisotropic, rotated, projective)
    /// are refused because meshes could not be mapped back to world mm by a similarity.
    pub fn from_scale_mat(m: &Matrix4<f64>) -> Result<Self, String> {
        let s = m[(0, 0)];
        let tol = 1e-9 * s.abs().max(1.0);
        let off_diagonal_ok = (0..3).all(|i| (0..3).all(|j| i == j || m[(i, j)].abs() <= tol));
        let isotropic = (m[(1, 1)] - s).abs() <= tol && (m[(2, 2)] - s).abs() <= tol;
        let last_row = m[(3, 0)] == 0.0 && m[(3, 1)] == 0.0 && m[(3, 2)] == 0.0 && m[(3, 3)] == 1.0;
        if !(s > 0.0 && off_diagonal_ok && isotropic && last_row) {
            return Err(format!(
                "is not diag(s,s,s,1) plus a translation (got {:?})",
                m.transpose().as_slice()
            ));
        }
        Ok(Self {
            scale: s,
            center: [m[(0, 3)], m[(1, 3)], m[(2, 3)]],
        })
    }

    /// The 4×4 `scale_mat`.
    pub fn matrix(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity() * self.scale;
        m[(3, 3)] = 1.0;
        m.fixed_view_mut::<3, 1>(0, 3)
            .copy_from(&Vector3::from(self.center));
        m
    }

    /// Normalised → world (mm).
    pub fn to_world(&self, p: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| self.scale * p[k] + self.center[k])
    }

    /// World (mm) → normalised.
    pub fn to_normalized(&self, p: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| (p[k] - self.center[k]) / self.scale)
    }
}

/// One posed photograph.
#[derive(Clone, Debug)]
pub struct View {
    /// Position in the sorted image list (= the `i` of `world_mat_i`).
    pub index: usize,
    /// The image file it came from.
    pub image_path: PathBuf,
    /// RGB in `[0, 1]`.
    pub image: RgbImage,
    /// Object mask in `[0, 1]` (1 = object), same size as the image, if the scene has masks.
    pub mask: Option<GrayImage>,
    /// Camera in the normalised space.
    pub camera: Camera,
}

/// A scene: posed views in normalised space plus the map back to world millimetres.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The folder it was loaded from.
    pub root: PathBuf,
    /// Views in camera-file order.
    pub views: Vec<View>,
    /// `scale_mat_0` as a similarity.
    pub normalization: Normalization,
    /// False when some `scale_mat_i` differs from `scale_mat_0` (each view still uses its own for
    /// its camera, as NeuS does; the mesh is mapped back with `scale_mat_0`).
    pub scale_mats_consistent: bool,
}

/// Options for [`Scene::load`].
#[derive(Clone, Debug)]
pub struct LoadOptions {
    /// Integer downscale factor for images, masks and intrinsics (1 = full size). Images are
    /// area-averaged over `f×f` blocks; `K` scales so pixel centres stay consistent.
    pub downscale: u32,
    /// Load masks when the scene has them.
    pub masks: bool,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            downscale: 1,
            masks: true,
        }
    }
}

/// PNG files in `dir`, sorted by the number in their stem (`7.png` < `012.png`).
fn numbered_pngs(dir: &Path) -> Result<Vec<PathBuf>, SceneError> {
    let entries = std::fs::read_dir(dir).map_err(|source| SceneError::Io {
        path: dir.into(),
        source,
    })?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry
            .map_err(|source| SceneError::Io {
                path: dir.into(),
                source,
            })?
            .path();
        let is_png = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"));
        if !is_png {
            continue;
        }
        let stem = path.file_stem().unwrap_or_default().to_string_lossy();
        let digits: String = stem.chars().filter(|c| c.is_ascii_digit()).collect();
        let number: u64 = digits
            .parse()
            .map_err(|_| SceneError::UnnumberedFile(path.clone()))?;
        files.push((number, path));
    }
    files.sort();
    Ok(files.into_iter().map(|(_, p)| p).collect())
}

fn matrix4(
    file: &Path,
    arrays: &BTreeMap<String, NpArray>,
    key: &str,
    why: &str,
) -> Result<Matrix4<f64>, SceneError> {
    let a = arrays.get(key).ok_or_else(|| SceneError::MissingKey {
        file: file.into(),
        key: key.into(),
        why: why.into(),
    })?;
    let bad = |problem: String| SceneError::BadArray {
        file: file.into(),
        key: key.into(),
        problem,
    };
    if a.shape != [4, 4] && a.shape != [3, 4] {
        return Err(bad(format!("has shape {:?}, expected 4×4", a.shape)));
    }
    if a.data.iter().any(|v| !v.is_finite()) {
        return Err(bad("has a non-finite entry".into()));
    }
    let mut m = Matrix4::identity();
    for r in 0..a.shape[0] {
        for c in 0..4 {
            m[(r, c)] = a.data[r * 4 + c];
        }
    }
    Ok(m)
}

impl Scene {
    /// Loads a scene folder. Images are decoded in parallel.
    pub fn load(root: &Path, opts: &LoadOptions) -> Result<Self, SceneError> {
        if !root.is_dir() {
            return Err(SceneError::NotADirectory(root.into()));
        }
        let cam_path = root.join(CAMERA_FILE);
        if !cam_path.is_file() {
            return Err(SceneError::MissingCameras(cam_path));
        }
        let image_dir = root.join("image");
        if !image_dir.is_dir() {
            return Err(SceneError::NoImages(image_dir));
        }
        let images = numbered_pngs(&image_dir)?;
        if images.is_empty() {
            return Err(SceneError::NoImages(image_dir));
        }
        let mask_dir = root.join("mask");
        let masks = if opts.masks && mask_dir.is_dir() {
            let m = numbered_pngs(&mask_dir)?;
            if m.len() != images.len() {
                return Err(SceneError::MaskCount {
                    dir: mask_dir,
                    masks: m.len(),
                    images: images.len(),
                });
            }
            Some(m)
        } else {
            None
        };
        let arrays = npz::read(&cam_path)?;
        // Camera matrices first: a missing key should fail before decoding any image.
        let mut mats = Vec::with_capacity(images.len());
        for (i, image) in images.iter().enumerate() {
            let why = format!("image {} has no camera", image.display());
            let world = matrix4(&cam_path, &arrays, &format!("world_mat_{i}"), &why)?;
            let scale = matrix4(&cam_path, &arrays, &format!("scale_mat_{i}"), &why)?;
            mats.push((world, scale));
        }
        let normalization =
            Normalization::from_scale_mat(&mats[0].1).map_err(|problem| SceneError::BadArray {
                file: cam_path.clone(),
                key: "scale_mat_0".into(),
                problem,
            })?;
        let scale_mats_consistent = mats
            .iter()
            .all(|(_, s)| (s - mats[0].1).abs().max() <= 1e-9 * normalization.scale);
        let f = opts.downscale;
        let views: Result<Vec<View>, SceneError> = images
            .par_iter()
            .enumerate()
            .map(|(i, image_path)| {
                let mut image = RgbImage::load(image_path)?;
                let mut mask = match &masks {
                    Some(m) => {
                        let mask = GrayImage::load(&m[i])?;
                        if (mask.width, mask.height) != (image.width, image.height) {
                            return Err(SceneError::SizeMismatch {
                                image: image_path.clone(),
                                mask: m[i].clone(),
                                image_w: image.width,
                                image_h: image.height,
                                mask_w: mask.width,
                                mask_h: mask.height,
                            });
                        }
                        Some(mask)
                    }
                    None => None,
                };
                let (world, scale) = &mats[i];
                let p: Matrix3x4<f64> = (world * scale).fixed_view::<3, 4>(0, 0).into_owned();
                let mut camera =
                    Camera::from_projection(&p, image.width as u32, image.height as u32).map_err(
                        |source| SceneError::BadCamera {
                            file: cam_path.clone(),
                            key: format!("world_mat_{i}"),
                            source,
                        },
                    )?;
                if f != 1 {
                    let (w, h) = (image.width, image.height);
                    if f == 0 || w / f as usize == 0 || h / f as usize == 0 {
                        return Err(SceneError::BadDownscale {
                            factor: f,
                            width: w,
                            height: h,
                        });
                    }
                    let fu = f as usize;
                    image = image.downscaled(fu);
                    mask = mask.map(|m| m.downscaled(fu));
                    camera = camera.downscaled(f);
                }
                Ok(View {
                    index: i,
                    image_path: image_path.clone(),
                    image,
                    mask,
                    camera,
                })
            })
            .collect();
        Ok(Self {
            root: root.into(),
            views: views?,
            normalization,
            scale_mats_consistent,
        })
    }
}

/// A view to write: image, optional mask, and its camera in **world** coordinates (mm).
#[derive(Clone, Debug)]
pub struct ViewOut<'a> {
    /// RGB in `[0, 1]`.
    pub image: &'a RgbImage,
    /// Object mask in `[0, 1]`.
    pub mask: Option<&'a GrayImage>,
    /// Camera in world coordinates; its size must match the image.
    pub camera: &'a Camera,
}

/// Writes a scene folder in the NeuS layout: `image/{i:06}.png`, `mask/{i:03}.png` (when every
/// view has a mask), and `cameras_sphere.npz` with `world_mat_i = K·[R | −R·C]` (world), its
/// inverse, and the shared `scale_mat_i` and inverse, as NeuS's preprocessing writes them.
pub fn write_scene(
    root: &Path,
    views: &[ViewOut],
    normalization: &Normalization,
) -> Result<(), SceneError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| SceneError::Io { path, source }
    };
    let image_dir = root.join("image");
    std::fs::create_dir_all(&image_dir).map_err(io(&image_dir))?;
    let with_masks = !views.is_empty() && views.iter().all(|v| v.mask.is_some());
    let mask_dir = root.join("mask");
    if with_masks {
        std::fs::create_dir_all(&mask_dir).map_err(io(&mask_dir))?;
    }
    views.par_iter().enumerate().try_for_each(|(i, v)| {
        assert_eq!(
            (v.camera.width as usize, v.camera.height as usize),
            (v.image.width, v.image.height),
            "camera size matches image size"
        );
        v.image.save(&image_dir.join(format!("{i:06}.png")))?;
        if let (true, Some(m)) = (with_masks, v.mask) {
            m.save(&mask_dir.join(format!("{i:03}.png")))?;
        }
        Ok::<(), SceneError>(())
    })?;
    let cameras: Vec<&Camera> = views.iter().map(|v| v.camera).collect();
    write_cameras(root, &cameras, normalization)
}

/// Writes only `cameras_sphere.npz` into `root` (which must exist): for each camera `i`
/// (world coordinates), `world_mat_i = K·[R | −R·C]` with a `[0,0,0,1]` row, its inverse, and the
/// shared `scale_mat_i = normalization.matrix()` and its inverse. [`write_scene`] calls it after
/// writing the images; importers that stream images call it directly.
pub fn write_cameras(
    root: &Path,
    cameras: &[&Camera],
    normalization: &Normalization,
) -> Result<(), SceneError> {
    let scale = normalization.matrix();
    let scale_inv = scale.try_inverse().expect("similarity with s > 0");
    let flat = |m: &Matrix4<f64>| -> Vec<f64> { m.transpose().as_slice().to_vec() };
    let mut arrays = Vec::new();
    for (i, camera) in cameras.iter().enumerate() {
        let mut world = Matrix4::identity();
        world
            .fixed_view_mut::<3, 4>(0, 0)
            .copy_from(&camera.projection());
        let world_inv = world.try_inverse().unwrap_or_else(Matrix4::zeros);
        arrays.push((format!("world_mat_{i}"), vec![4, 4], flat(&world)));
        arrays.push((format!("world_mat_inv_{i}"), vec![4, 4], flat(&world_inv)));
        arrays.push((format!("scale_mat_{i}"), vec![4, 4], flat(&scale)));
        arrays.push((format!("scale_mat_inv_{i}"), vec![4, 4], flat(&scale_inv)));
    }
    npz::write(&root.join(CAMERA_FILE), &arrays)?;
    Ok(())
}
