//! Importing posed photographs from other tools into a NeuS scene folder: COLMAP sparse models
//! ([`colmap`]) and instant-ngp / nerfstudio `transforms.json` files ([`transforms`]); and the
//! reverse, for tests, writing a scene's true cameras in those formats ([`export`]).
//! Every importer produces [`ImportedView`]s (image file, optional mask file, camera in the
//! source's world frame, OpenCV axes) and a region of interest ([`Roi`]), then
//! [`write_imported_scene`] writes the standard layout of [`crate::scene::dtu`]:
//!
//! ```text
//! <out>/image/000000.png ...   the views as 8-bit RGB PNG (COLMAP: sorted by image name;
//!                              transforms.json: frame order)
//! <out>/mask/000.png ...       masks, when a mask folder or mask paths were given
//! <out>/cameras_sphere.npz     world_mat_i = K·[R | −R·C] (source world frame), and
//!                              scale_mat_i = diag(r, r, r, 1) + ROI centre
//! <out>/import.json            what was imported and which region of interest was chosen, how
//! ```
//!
//! The world frame and its unit are the source's (COLMAP's arbitrary similarity frame, or the
//! transforms.json frame): the importer applies no rotation or scale to the cameras; the only
//! similarity it chooses is the `scale_mat` that maps the region of interest (centre `c`, radius
//! `r`) onto the unit sphere, `X_world = r·X_norm + c`, as NeuS's `preprocess_custom_data` does.
//!
//! Images are read as PNG or JPEG (the `image` crate's `png` and `jpeg` codecs; the format is
//! guessed from the file's bytes) and written as 8-bit PNG; masks likewise (first channel).

pub mod colmap;
pub mod colmap_binary;
mod colmap_model;
pub mod export;
pub mod perturb;
pub mod transforms;
pub mod undistort;

pub use undistort::Distortion;

use crate::scene::{
    write_cameras, Camera, GrayImage, ImageError, Normalization, RgbImage, SceneError,
};
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Why an import or export failed. Every variant names the file, camera or value at fault.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// A file or folder could not be read or written.
    #[error("cannot access {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A required input file is absent.
    #[error("{path} is missing ({what})")]
    MissingFile { path: PathBuf, what: String },
    /// A file does not parse (the message says where and why).
    #[error("{file}: {message}")]
    Parse { file: PathBuf, message: String },
    /// A camera model neus-aug does not handle.
    #[error(
        "{file}: camera {camera_id} uses the {model} camera model, which neus-aug does not \
             import ({hint})"
    )]
    UnsupportedModel {
        file: PathBuf,
        camera_id: u64,
        model: String,
        hint: String,
    },
    /// A registered image whose file is not in the image folder.
    #[error("image '{name}' is registered in {model} but {path} does not exist")]
    MissingImage {
        name: String,
        model: PathBuf,
        path: PathBuf,
    },
    /// An image's size differs from its camera's.
    #[error("image {path} is {actual_w}×{actual_h} but its camera says {camera_w}×{camera_h}")]
    ImageSize {
        path: PathBuf,
        actual_w: u32,
        actual_h: u32,
        camera_w: u32,
        camera_h: u32,
    },
    /// The model has no usable view.
    #[error("{0}: no registered image to import")]
    NoViews(PathBuf),
    /// The region of interest cannot be chosen or is invalid.
    #[error("region of interest: {0}")]
    Roi(String),
    /// A camera centre lies inside the region of interest, so NeuS would sample behind it.
    #[error(
        "camera of '{name}' lies inside the region of interest (distance {distance:.6} from \
             the centre, radius {radius:.6}); give --roi-center and a smaller --roi-radius"
    )]
    CameraInsideRoi {
        name: String,
        distance: f64,
        radius: f64,
    },
    /// The output folder exists and is not empty.
    #[error("output folder {0} exists and is not empty")]
    OutputExists(PathBuf),
    /// The output path cannot be a folder (a dangling link, a file, ...).
    #[error(transparent)]
    OutputDir(#[from] crate::util::OutputDirError),
    /// Two entries of the source name the same photograph.
    #[error(
        "{source_file}: {first} and {second} both name {path}; each view needs a photograph of \
         its own (remove or rename one of the two entries)"
    )]
    DuplicateImage {
        source_file: PathBuf,
        first: String,
        second: String,
        path: PathBuf,
    },
    /// No mask file matches an image in the mask folder.
    #[error("no mask for image '{name}' in {dir}: tried {tried}")]
    MissingMask {
        name: String,
        dir: PathBuf,
        tried: String,
    },
    /// The cameras cannot reconstruct anything: they share one centre, or too few see the
    /// region of interest.
    #[error("{0}")]
    Cameras(String),
    /// An export was asked of a camera the format cannot express.
    #[error("cannot export: {0}")]
    Export(String),
    /// Writing the scene failed.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// Reading or writing an image failed.
    #[error(transparent)]
    Image(#[from] ImageError),
}

pub(crate) fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> ImportError + '_ {
    move |source| ImportError::Io {
        path: path.into(),
        source,
    }
}

/// A region of interest in the source's world frame: the sphere that becomes the unit sphere.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Roi {
    /// Centre (world units).
    pub center: [f64; 3],
    /// Radius (world units), `> 0`.
    pub radius: f64,
}

impl Roi {
    /// Checks that the centre is finite and the radius finite and positive.
    pub fn validate(&self) -> Result<(), ImportError> {
        if !self.center.iter().all(|v| v.is_finite()) {
            return Err(ImportError::Roi(format!(
                "centre {:?} is not finite",
                self.center
            )));
        }
        if !(self.radius.is_finite() && self.radius > 0.0) {
            return Err(ImportError::Roi(format!(
                "radius {} is not a positive number",
                self.radius
            )));
        }
        Ok(())
    }

    /// The scene normalisation `X_world = r·X_norm + c`.
    pub fn normalization(&self) -> Normalization {
        Normalization {
            scale: self.radius,
            center: self.center,
        }
    }
}

/// The region of interest an importer settled on, and how.
#[derive(Clone, Debug, Serialize)]
pub struct RoiChoice {
    /// The sphere.
    pub roi: Roi,
    /// How it was chosen, in words (written to `import.json`).
    pub method: String,
}

/// Parses `x,y,z` (the `--roi-center` flag).
pub fn parse_vec3(s: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let bad = || format!("'{s}' is not x,y,z (three numbers separated by commas)");
    if parts.len() != 3 {
        return Err(bad());
    }
    let mut v = [0.0f64; 3];
    for (k, p) in parts.iter().enumerate() {
        v[k] = p.parse().map_err(|_| bad())?;
        if !v[k].is_finite() {
            return Err(bad());
        }
    }
    Ok(v)
}

/// The value at quantile `q ∈ [0, 1]` of `values` (sorted in place; nearest rank, no
/// interpolation). `values` must not be empty.
fn quantile(values: &mut [f64], q: f64) -> f64 {
    values.sort_by(f64::total_cmp);
    let i = ((values.len() - 1) as f64 * q).round() as usize;
    values[i]
}

/// The sparse points [`roi_from_points`] trusts: the finite ones seen by at least 3 images, or
/// every finite one when fewer than 16 are; and which of the two, in words. Fails below 4.
fn trusted_points(
    points: &[([f64; 3], usize)],
) -> Result<(Vec<[f64; 3]>, &'static str), ImportError> {
    let finite: Vec<&([f64; 3], usize)> = points
        .iter()
        .filter(|(p, _)| p.iter().all(|v| v.is_finite()))
        .collect();
    let seen3: Vec<[f64; 3]> = finite
        .iter()
        .filter(|(_, t)| *t >= 3)
        .map(|(p, _)| *p)
        .collect();
    let (kept, which) = if seen3.len() >= 16 {
        (seen3, "points seen by >= 3 images")
    } else {
        (finite.iter().map(|(p, _)| *p).collect(), "all points")
    };
    if kept.len() < 4 {
        return Err(ImportError::Roi(format!(
            "only {} finite sparse points: give --roi-center and --roi-radius",
            kept.len()
        )));
    }
    Ok((kept, which))
}

/// The per-axis 2nd and 98th percentiles of `points` (not empty): a bounding box that ignores
/// the 2 % strays on each side.
fn trimmed_box(points: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let (mut lo, mut hi) = ([0.0; 3], [0.0; 3]);
    for k in 0..3 {
        let mut axis: Vec<f64> = points.iter().map(|p| p[k]).collect();
        lo[k] = quantile(&mut axis, 0.02);
        hi[k] = quantile(&mut axis, 0.98);
    }
    (lo, hi)
}

/// The automatic region of interest of `import colmap` (`--roi-from auto`, the default): the
/// camera layout's sphere when the capture orbits an object, else the sparse points' sphere.
///
/// Why: the sparse points cover only what the cameras see. For a capture from one side of an
/// object (DTU's rig, a turntable seen from above), [`roi_from_points`] centres its sphere on
/// the visible side and cuts the rest off (up to about half of the object with a sparse rig,
/// `scripts/colmap_roundtrip.sh`), and a table or room around the object swells it to several
/// times the object's size. The
/// point the optical axes meet is where such a capture aims, whatever the points cover
/// (instant-nsr-pl's default `lookat` centre, `normalize_poses` in `datasets/colmap.py`, takes it
/// from pairs of rays; [`roi_from_cameras`] from all of them at once, in least squares).
///
/// Rule, `S` the sparse points [`roi_from_points`] trusts:
/// 1. [`roi_from_cameras`] gives the meeting point `p` and the radius `r_cam` of the largest
///    sphere about `p` that every camera sees whole;
/// 2. the capture counts as orbiting when that succeeds, `p` lies in front of every camera
///    (positive depth), and within the sphere about the trimmed box of `S` (2nd–98th percentile
///    per axis; the sphere through the box's corners, since the points of a one-sided capture
///    form a cap whose box need not contain the centre the cameras aim at);
///    otherwise (a forward-facing capture, cameras aimed past the points) the result is
///    [`roi_from_points`]'s;
/// 3. radius = `min(r_cam, 1.5 × d98)`, `d98` the 98th percentile of the distances of `S` to
///    `p`: the sphere stays within every view and does not grow far past the points (a small
///    object in a wide frame); the factor 1.5 leaves room for the side no camera saw.
pub fn roi_auto(
    points: &[([f64; 3], usize)],
    cameras: &[Camera],
) -> Result<RoiChoice, ImportError> {
    let centers: Vec<Vector3<f64>> = cameras.iter().map(|c| c.center).collect();
    let fallback = |why: String| -> Result<RoiChoice, ImportError> {
        let mut choice = roi_from_points(points, &centers)?;
        choice.method = format!("{} (auto: {why})", choice.method);
        Ok(choice)
    };
    let by_cameras = match roi_from_cameras(cameras) {
        Ok(choice) => choice,
        Err(e) => return fallback(format!("not an orbit, {e}")),
    };
    let p = Vector3::from(by_cameras.roi.center);
    if let Some(i) = cameras
        .iter()
        .position(|c| c.r.row(2).transpose().dot(&(p - c.center)) <= 0.0)
    {
        return fallback(format!(
            "the optical axes meet behind camera {i}, not an orbit"
        ));
    }
    let (kept, which) = trusted_points(points)?;
    let (lo, hi) = trimmed_box(&kept);
    let (lo, hi) = (Vector3::from(lo), Vector3::from(hi));
    if (p - 0.5 * (lo + hi)).norm() > 0.5 * (hi - lo).norm() {
        return fallback(
            "the optical axes meet outside the sphere about the sparse points' box, not an \
             orbit of them"
                .into(),
        );
    }
    let mut dist: Vec<f64> = kept
        .iter()
        .map(|q| (Vector3::from(*q) - p).norm())
        .collect();
    let d98 = quantile(&mut dist, 0.98);
    let (radius, bound) = if 1.5 * d98 < by_cameras.roi.radius {
        (
            1.5 * d98,
            "1.5 x the 98th percentile of the points' distances to it",
        )
    } else {
        (
            by_cameras.roi.radius,
            "the largest sphere about it that every camera sees whole",
        )
    };
    let roi = Roi {
        center: by_cameras.roi.center,
        radius,
    };
    roi.validate()?;
    Ok(RoiChoice {
        roi,
        method: format!(
            "auto, an orbit of {} cameras around {} of {} sparse points ({which}): centre = point \
             closest to all optical axes, radius = {bound}",
            cameras.len(),
            kept.len(),
            points.len()
        ),
    })
}

/// Region of interest from sparse 3-D points with their track lengths (number of images that
/// observe each point), robust to stray points:
/// 1. keep points seen by at least 3 images (COLMAP's triangulated outliers are mostly 2-view
///    points); if fewer than 16 remain, keep all points;
/// 2. centre = the per-axis midpoint of the 2nd and 98th percentiles (a trimmed bounding box);
/// 3. radius = 1.1 × the 98th percentile of the kept points' distances to that centre (10 %
///    margin, so the object's surface is not tangent to the sphere);
/// 4. if a camera would lie inside, the radius shrinks to 0.9 × the nearest camera's distance
///    (reported in `method`).
pub fn roi_from_points(
    points: &[([f64; 3], usize)],
    camera_centers: &[Vector3<f64>],
) -> Result<RoiChoice, ImportError> {
    let (kept, which) = trusted_points(points)?;
    let (lo, hi) = trimmed_box(&kept);
    let center: [f64; 3] = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
    let c = Vector3::from(center);
    let mut dist: Vec<f64> = kept
        .iter()
        .map(|p| (Vector3::from(*p) - c).norm())
        .collect();
    let mut radius = 1.1 * quantile(&mut dist, 0.98);
    let mut method = format!(
        "from {} of {} sparse points ({which}): centre = midpoint of the 2nd/98th percentiles per \
         axis, radius = 1.1 x 98th percentile of distances",
        kept.len(),
        points.len()
    );
    let nearest = camera_centers
        .iter()
        .map(|cc| (cc - c).norm())
        .fold(f64::INFINITY, f64::min);
    if nearest <= radius {
        radius = 0.9 * nearest;
        method.push_str("; shrunk to 0.9 x the nearest camera's distance");
    }
    let roi = Roi { center, radius };
    roi.validate()?;
    Ok(RoiChoice { roi, method })
}

/// Region of interest from the camera layout alone (for captures that orbit an object):
/// - centre = the point closest, in least squares, to every optical axis (the line through each
///   camera centre along its viewing direction): solves `Σ (I − d dᵀ) (p − C) = 0`;
/// - radius = the largest sphere about that centre every camera sees whole:
///   `min_i |C_i − p| · sin(θ_i)`, with `θ_i` the half field of view of camera `i`'s smaller
///   image side (`atan(min(w, h) / (2 f))`, `f` the larger focal length).
///
/// Fails when the axes are (nearly) parallel, e.g. a forward-facing capture: give `--roi-*`.
pub fn roi_from_cameras(cameras: &[Camera]) -> Result<RoiChoice, ImportError> {
    let mut a = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for cam in cameras {
        // The optical axis is the third row of R (the camera z axis in world coordinates).
        let d: Vector3<f64> = cam.r.row(2).transpose().normalize();
        let m = Matrix3::identity() - d * d.transpose();
        a += m;
        b += m * cam.center;
    }
    let eig = a.symmetric_eigenvalues();
    let (lo, hi) = (eig.min(), eig.max());
    if cameras.len() < 2 || lo <= 1e-6 * hi {
        return Err(ImportError::Roi(
            "the cameras' optical axes do not meet (too few views, or parallel axes as in a \
             forward-facing capture): give --roi-center and --roi-radius"
                .into(),
        ));
    }
    let p = a
        .try_inverse()
        .expect("positive definite by the eigenvalue test")
        * b;
    let mut radius = f64::INFINITY;
    for cam in cameras {
        let f = cam.k[(0, 0)].max(cam.k[(1, 1)]);
        let half = (cam.width.min(cam.height) as f64 / (2.0 * f)).atan();
        radius = radius.min((cam.center - p).norm() * half.sin());
    }
    let roi = Roi {
        center: [p.x, p.y, p.z],
        radius,
    };
    roi.validate()?;
    Ok(RoiChoice {
        roi,
        method: format!(
            "from the layout of {} cameras: centre = point closest to all optical axes, radius = \
             largest sphere about it that every camera sees whole",
            cameras.len()
        ),
    })
}

/// One view to import: where its image (and mask) is and its camera in the source's world frame.
#[derive(Clone, Debug)]
pub struct ImportedView {
    /// The name the source uses (COLMAP image name, transforms.json `file_path`).
    pub name: String,
    /// The image file.
    pub image: PathBuf,
    /// The mask file, if any (first channel used; 1 = object).
    pub mask: Option<PathBuf>,
    /// Camera in the source's world frame (OpenCV axes), size = the image's.
    pub camera: Camera,
    /// The lens distortion of the source camera (zero = pinhole); when non-zero, the image and
    /// mask are resampled into `camera`'s pinhole model on writing ([`undistort`]).
    pub distortion: Distortion,
}

/// What an import wrote (also saved as `import.json` in the scene).
#[derive(Clone, Debug, Serialize)]
pub struct ImportReport {
    /// `colmap-text`, `colmap-binary` or `transforms`.
    pub source_format: String,
    /// The model folder or json file read.
    pub source: PathBuf,
    /// The scene folder written.
    pub scene: PathBuf,
    /// Number of views.
    pub views: usize,
    /// Whether `mask/` was written.
    pub masks: bool,
    /// How many views had lens distortion and were resampled into their pinhole camera
    /// ([`undistort`]).
    pub undistorted: usize,
    /// The region of interest (world frame of the source) and how it was chosen.
    pub roi: RoiChoice,
    /// Source name of each view, in scene order (`image/{i:06}.png` is `names[i]`).
    pub names: Vec<String>,
}

/// Errors unless every camera centre lies outside the region of interest.
pub fn check_cameras_outside(views: &[ImportedView], roi: &Roi) -> Result<(), ImportError> {
    let c = Vector3::from(roi.center);
    for v in views {
        let distance = (v.camera.center - c).norm();
        if distance <= roi.radius {
            return Err(ImportError::CameraInsideRoi {
                name: v.name.clone(),
                distance,
                radius: roi.radius,
            });
        }
    }
    Ok(())
}

/// The output folder of an import while it is written: on drop, unless [`Self::keep`] was
/// called, removes what this import created and nothing else. When `out` did not exist, the
/// highest folder the import created for it (`out` or an ancestor) goes, whole; when it existed
/// (empty, as [`prepare_output`] requires), only the entries an import writes into it go
/// (`image/`, `mask/`, the camera file and `import.json`), and the folder stays.
pub(crate) struct OutputGuard {
    out: PathBuf,
    created: Option<PathBuf>,
    kept: bool,
}

impl OutputGuard {
    /// The import succeeded: leave everything in place.
    pub(crate) fn keep(mut self) {
        self.kept = true;
    }
}

impl Drop for OutputGuard {
    fn drop(&mut self) {
        if self.kept {
            return;
        }
        match &self.created {
            Some(root) => {
                let _ = std::fs::remove_dir_all(root);
            }
            None => {
                for dir in ["image", "mask"] {
                    let _ = std::fs::remove_dir_all(self.out.join(dir));
                }
                for file in [crate::scene::dtu::CAMERA_FILE, "import.json"] {
                    let _ = std::fs::remove_file(self.out.join(file));
                }
            }
        }
    }
}

/// Errors unless `out` is absent or an empty folder (a dangling symbolic link or a file is
/// named as such, [`crate::util::inspect_output_dir`]); then creates it, and returns the guard
/// that removes what was created if the import fails.
pub(crate) fn prepare_output(out: &Path) -> Result<OutputGuard, ImportError> {
    use crate::util::{inspect_output_dir, OutputDir};
    let created = match inspect_output_dir(out)? {
        OutputDir::NotEmpty => return Err(ImportError::OutputExists(out.into())),
        OutputDir::Empty => None,
        // The highest ancestor that does not exist yet: create_dir_all makes it and all below.
        OutputDir::Absent => out
            .ancestors()
            .take_while(|a| !a.as_os_str().is_empty() && std::fs::symlink_metadata(a).is_err())
            .last()
            .map(Path::to_path_buf),
    };
    let guard = OutputGuard {
        out: out.into(),
        created,
        kept: false,
    };
    std::fs::create_dir_all(out).map_err(io_err(out))?;
    Ok(guard)
}

/// Errors unless the cameras have a baseline: at least two views, and centres that are not all
/// one point, i.e. spread over more than a millionth of their distance to `reference` (a point
/// of the scene: the region of interest's centre, or the middle of the sparse points; the
/// source's origin when there is none). A panorama turned on a tripod sees the scene from one
/// point, and nothing can be triangulated from it.
pub fn check_baseline(
    views: &[ImportedView],
    reference: Option<[f64; 3]>,
) -> Result<(), ImportError> {
    if views.len() < 2 {
        return Err(ImportError::Cameras(format!(
            "only {} view: a reconstruction needs cameras at two places at least",
            views.len()
        )));
    }
    let centres: Vec<Vector3<f64>> = views.iter().map(|v| v.camera.center).collect();
    let mean = centres.iter().sum::<Vector3<f64>>() / centres.len() as f64;
    let spread = centres
        .iter()
        .map(|c| (c - mean).norm())
        .fold(0.0, f64::max);
    let reference = Vector3::from(reference.unwrap_or_default());
    let scale = centres
        .iter()
        .map(|c| (c - reference).norm())
        .fold(0.0, f64::max);
    if spread <= 1e-6 * scale {
        return Err(ImportError::Cameras(format!(
            "all {} cameras share one centre ({:?}, within {spread:.3e} source units): no \
             baseline, so nothing can be triangulated (a panorama turned about one point?); \
             import photographs taken from different places",
            views.len(),
            mean.as_slice()
        )));
    }
    Ok(())
}

/// Whether `cam` sees some of the sphere `roi`: the sphere lies in front of the camera and
/// reaches into its view, i.e. is not wholly outside one of the four planes through the camera
/// centre and the image's edges (the frustum test of real-time rendering, which may accept a
/// sphere just off a corner of the view, never refuse one in it).
fn sees(cam: &Camera, roi: &Roi) -> bool {
    let c = cam.r * (Vector3::from(roi.center) - cam.center);
    if c.z <= -roi.radius {
        return false;
    }
    let Some(k_inv) = cam.k.try_inverse() else {
        return false;
    };
    let (w, h) = (cam.width as f64, cam.height as f64);
    let corners =
        [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)].map(|(x, y)| k_inv * Vector3::new(x, y, 1.0));
    let inside = k_inv * Vector3::new(0.5 * w, 0.5 * h, 1.0);
    (0..4).all(|i| {
        let mut n = corners[i].cross(&corners[(i + 1) % 4]).normalize();
        if n.dot(&inside) < 0.0 {
            n = -n;
        }
        n.dot(&c) > -roi.radius
    })
}

/// Errors unless at least two cameras see some of the region of interest (a region no camera,
/// or a single one, sees cannot be reconstructed: e.g. `--roi-center` in the wrong frame or unit).
pub fn check_roi_seen(views: &[ImportedView], roi: &Roi) -> Result<(), ImportError> {
    let seeing: Vec<&str> = views
        .iter()
        .filter(|v| sees(&v.camera, roi))
        .map(|v| v.name.as_str())
        .collect();
    if seeing.len() >= 2 {
        return Ok(());
    }
    let [x, y, z] = roi.center;
    Err(ImportError::Roi(format!(
        "the sphere of centre ({x}, {y}, {z}) and radius {} (source world units) is seen by {} of \
         {} cameras{}; a reconstruction needs it in the view of two at least. Give a \
         --roi-center and --roi-radius in the source's frame and unit (or leave them out to \
         choose automatically)",
        roi.radius,
        seeing.len(),
        views.len(),
        match seeing.first() {
            Some(name) => format!(" (only '{name}')"),
            None => String::new(),
        }
    )))
}

/// Writes the NeuS scene folder `out` (absent or empty): images (and masks, when every view has
/// one) converted to 8-bit PNG in the given order, `cameras_sphere.npz` with the ROI's
/// `scale_mat`, and `import.json`. Checks first that the cameras have a baseline
/// ([`check_baseline`]), lie outside the ROI and that two of them see it ([`check_roi_seen`]),
/// and every image's size against its camera, so a bad input leaves no half-written scene behind the
/// first error it can detect from headers; a later failure (an image that does not decode)
/// removes what this call created ([`OutputGuard`]). Images are converted in parallel, one per
/// thread at a time.
pub fn write_imported_scene(
    out: &Path,
    views: &[ImportedView],
    roi: &RoiChoice,
    source_format: &str,
    source: &Path,
) -> Result<ImportReport, ImportError> {
    if views.is_empty() {
        return Err(ImportError::NoViews(source.into()));
    }
    roi.roi.validate()?;
    check_baseline(views, Some(roi.roi.center))?;
    check_cameras_outside(views, &roi.roi)?;
    check_roi_seen(views, &roi.roi)?;
    for v in views {
        for path in std::iter::once(&v.image).chain(&v.mask) {
            if !path.is_file() {
                return Err(ImportError::MissingImage {
                    name: v.name.clone(),
                    model: source.into(),
                    path: path.clone(),
                });
            }
            let (w, h) = image::image_dimensions(path).map_err(|source| {
                ImportError::Image(ImageError::Decode {
                    path: path.clone(),
                    source,
                })
            })?;
            if (w, h) != (v.camera.width, v.camera.height) {
                return Err(ImportError::ImageSize {
                    path: path.clone(),
                    actual_w: w,
                    actual_h: h,
                    camera_w: v.camera.width,
                    camera_h: v.camera.height,
                });
            }
        }
    }
    let masks = views.iter().all(|v| v.mask.is_some());
    let guard = prepare_output(out)?;
    let image_dir = out.join("image");
    std::fs::create_dir_all(&image_dir).map_err(io_err(&image_dir))?;
    let mask_dir = out.join("mask");
    if masks {
        std::fs::create_dir_all(&mask_dir).map_err(io_err(&mask_dir))?;
    }
    views
        .par_iter()
        .enumerate()
        .try_for_each(|(i, v)| -> Result<(), ImportError> {
            let (k, d) = (&v.camera.k, &v.distortion);
            let (w, h) = (v.camera.width as usize, v.camera.height as usize);
            let mut image = RgbImage::load(&v.image)?;
            if !d.is_zero() {
                image = undistort::undistort_rgb(&image, k, d, k, w, h);
            }
            image.save(&image_dir.join(format!("{i:06}.png")))?;
            if let (true, Some(m)) = (masks, &v.mask) {
                let mut mask = GrayImage::load(m)?;
                if !d.is_zero() {
                    mask = undistort::undistort_mask(&mask, k, d, k, w, h);
                }
                mask.save(&mask_dir.join(format!("{i:03}.png")))?;
            }
            Ok(())
        })?;
    let cameras: Vec<&Camera> = views.iter().map(|v| &v.camera).collect();
    write_cameras(out, &cameras, &roi.roi.normalization())?;
    let report = ImportReport {
        source_format: source_format.into(),
        source: source.into(),
        scene: out.into(),
        views: views.len(),
        masks,
        undistorted: views.iter().filter(|v| !v.distortion.is_zero()).count(),
        roi: roi.clone(),
        names: views.iter().map(|v| v.name.clone()).collect(),
    };
    let path = out.join("import.json");
    std::fs::write(
        &path,
        serde_json::to_string_pretty(&report).expect("report serialises"),
    )
    .map_err(io_err(&path))?;
    guard.keep();
    Ok(report)
}

/// Finds the mask of image `name` (a path relative to the image folder) in `mask_dir`, trying in
/// order: COLMAP's convention `<name>.png` (`colmap` mask_path: "image.jpg" → "image.jpg.png"),
/// the same relative path with a `.png` extension, and finally any PNG in the same relative
/// folder whose stem holds the same number (so `mask/000.png` matches `image/000000.png`, the
/// DTU layout's paddings).
pub fn find_mask(mask_dir: &Path, name: &str) -> Option<PathBuf> {
    find_mask_or_tried(mask_dir, name).ok()
}

/// [`find_mask`], or the error naming the image, the folder and the names tried.
pub fn find_mask_or_err(mask_dir: &Path, name: &str) -> Result<PathBuf, ImportError> {
    find_mask_or_tried(mask_dir, name).map_err(|tried| ImportError::MissingMask {
        name: name.into(),
        dir: mask_dir.into(),
        tried,
    })
}

/// [`find_mask`]'s search; `Err` lists what was tried, in words.
fn find_mask_or_tried(mask_dir: &Path, name: &str) -> Result<PathBuf, String> {
    let rel = Path::new(name);
    let colmap_style = mask_dir.join(format!("{name}.png"));
    if colmap_style.is_file() {
        return Ok(colmap_style);
    }
    let same = mask_dir.join(rel).with_extension("png");
    if same.is_file() {
        return Ok(same);
    }
    let number = |p: &Path| -> Option<u64> {
        let digits: String = p
            .file_stem()?
            .to_string_lossy()
            .chars()
            .filter(|c| c.is_ascii_digit())
            .collect();
        digits.parse().ok()
    };
    let dir = match rel.parent() {
        Some(p) if !p.as_os_str().is_empty() => mask_dir.join(p),
        _ => mask_dir.to_path_buf(),
    };
    let file = |p: &Path| p.strip_prefix(mask_dir).unwrap_or(p).display().to_string();
    let mut tried = format!(
        "{} (COLMAP's <image name>.png) and {}",
        file(&colmap_style),
        file(&same)
    );
    let Some(want) = number(rel) else {
        tried.push_str("; the image name holds no number to match a mask by");
        return Err(tried);
    };
    let mut found: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map_err(|e| format!("{tried}; cannot list {}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) && number(p) == Some(want)
        })
        .collect();
    found.sort();
    match found.len() {
        1 => Ok(found.remove(0)),
        0 => Err(format!("{tried}, and found no PNG numbered {want}")),
        n => Err(format!(
            "{tried}, and found {n} PNGs numbered {want} ({}), which is ambiguous",
            found.iter().map(|p| file(p)).collect::<Vec<_>>().join(", ")
        )),
    }
}

#[cfg(test)]
mod tests;
