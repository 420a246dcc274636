//! COLMAP sparse models (`sparse/0/{cameras,images,points3D}.{txt,bin}`): reading both forms,
//! writing both (the text form for `synth --export colmap`, the binary one for tests), and
//! turning a model into [`ImportedView`]s.
//!
//! Conventions (COLMAP documentation, "Output Format" and "Camera Models"; `src/colmap/sensor/
//! models.h`):
//! - `images.txt` stores per image the **world-to-camera** rotation as a unit quaternion
//!   `QW QX QY QZ` (Hamilton, scalar first) and translation `TX TY TZ`: `x_cam = R·X + t`, so the
//!   camera centre is `C = −Rᵀ·t`. The camera frame is OpenCV's (x right, y down, z forward),
//!   the same as [`Camera`]'s, so no axis flips.
//! - Pixel coordinates put the centre of the top-left pixel at (0.5, 0.5) (COLMAP's feature
//!   coordinates; see nerfstudio-project/gsplat PR 151), the convention of [`Camera`], so `cx, cy`
//!   carry over unchanged.
//! - Camera models and parameters: SIMPLE_PINHOLE (id 0) `f cx cy`; PINHOLE (1) `fx fy cx cy`;
//!   SIMPLE_RADIAL (2) `f cx cy k`; RADIAL (3) `f cx cy k1 k2`; OPENCV (4)
//!   `fx fy cx cy k1 k2 p1 p2`.
//! - Binary files are little endian: `cameras.bin` = u64 count, then per camera i32 id, i32
//!   model id, u64 width, u64 height, f64 params; `images.bin` = u64 count, then per image i32 id,
//!   f64 qvec[4], f64 tvec[3], i32 camera id, NUL-terminated name, u64 number of 2-D points and
//!   per point f64 x, f64 y, i64 point3D id (−1 = none); `points3D.bin` = u64 count, then per
//!   point u64 id, f64 xyz[3], u8 rgb[3], f64 error, u64 track length and per element i32 image
//!   id, i32 2-D point index (COLMAP `scripts/python/read_write_model.py`).
//!
//! **Distortion** (a choice, documented): neus-aug's rays are pinhole rays, so the images (and
//! masks) of a camera of a distorted model (SIMPLE_RADIAL, RADIAL, OPENCV) are undistorted into
//! the scene: resampled into a pinhole camera with the same `K` and size ([`super::undistort`],
//! checked against `colmap image_undistorter` in `tests/colmap_roundtrip.rs`). Output of
//! `colmap image_undistorter` (PINHOLE cameras) imports as it is.

use super::colmap_binary;
pub use super::colmap_binary::write_binary;
pub(crate) use super::colmap_model::{parse_err, supported_hint, MODELS, SUPPORTED};
pub use super::colmap_model::{ColmapCamera, ColmapImage, ColmapModel, ColmapPoint, ModelFormat};
use super::{
    check_baseline, find_mask_or_err, io_err, roi_auto, roi_from_cameras, roi_from_points,
    Distortion, ImportError, ImportedView, Roi, RoiChoice,
};
use crate::scene::Camera;
use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Which form `dir` holds: binary when `cameras.bin` exists, else text when `cameras.txt`
/// exists, else an error naming both.
pub fn detect_format(dir: &Path) -> Result<ModelFormat, ImportError> {
    if dir.join("cameras.bin").is_file() {
        Ok(ModelFormat::Binary)
    } else if dir.join("cameras.txt").is_file() {
        Ok(ModelFormat::Text)
    } else {
        Err(ImportError::MissingFile {
            path: dir.join("cameras.txt"),
            what: format!(
                "no COLMAP model in {} (neither cameras.txt nor cameras.bin; a model is usually \
                 in <project>/sparse/0)",
                dir.display()
            ),
        })
    }
}

/// Reads the model in `dir`, text or binary (see [`detect_format`]).
pub fn read_model(dir: &Path) -> Result<(ColmapModel, ModelFormat), ImportError> {
    let format = detect_format(dir)?;
    let ext = match format {
        ModelFormat::Text => "txt",
        ModelFormat::Binary => "bin",
    };
    let mut files = Vec::new();
    for name in ["cameras", "images", "points3D"] {
        let path = dir.join(format!("{name}.{ext}"));
        let bytes = std::fs::read(&path).map_err(|source| {
            if source.kind() == std::io::ErrorKind::NotFound {
                ImportError::MissingFile {
                    path: path.clone(),
                    what: format!("a COLMAP {ext} model needs cameras, images and points3D"),
                }
            } else {
                ImportError::Io {
                    path: path.clone(),
                    source,
                }
            }
        })?;
        files.push((path, bytes));
    }
    let model = match format {
        ModelFormat::Text => {
            let text = |i: usize| {
                String::from_utf8(files[i].1.clone())
                    .map_err(|_| parse_err(&files[i].0, "is not UTF-8 text".into()))
            };
            ColmapModel {
                cameras: parse_cameras_text(&files[0].0, &text(0)?)?,
                images: parse_images_text(&files[1].0, &text(1)?)?,
                points: parse_points_text(&files[2].0, &text(2)?)?,
            }
        }
        ModelFormat::Binary => ColmapModel {
            cameras: colmap_binary::parse_cameras_bin(&files[0].0, &files[0].1)?,
            images: colmap_binary::parse_images_bin(&files[1].0, &files[1].1)?,
            points: colmap_binary::parse_points_bin(&files[2].0, &files[2].1)?,
        },
    };
    Ok((model, format))
}

/// Non-comment lines with their 1-based line numbers (`#` starts a comment line).
fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.starts_with('#'))
}

fn num<T: std::str::FromStr>(
    file: &Path,
    line: usize,
    what: &str,
    s: &str,
) -> Result<T, ImportError> {
    s.parse()
        .map_err(|_| parse_err(file, format!("line {line}: {what} '{s}' is not a number")))
}

fn parse_cameras_text(file: &Path, text: &str) -> Result<BTreeMap<u32, ColmapCamera>, ImportError> {
    let mut cams = BTreeMap::new();
    for (line, l) in data_lines(text).filter(|(_, l)| !l.is_empty()) {
        let t: Vec<&str> = l.split_whitespace().collect();
        if t.len() < 4 {
            return Err(parse_err(
                file,
                format!("line {line}: expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]"),
            ));
        }
        let cam = ColmapCamera {
            id: num(file, line, "camera id", t[0])?,
            model: t[1].to_string(),
            width: num(file, line, "width", t[2])?,
            height: num(file, line, "height", t[3])?,
            params: t[4..]
                .iter()
                .map(|s| num(file, line, "parameter", s))
                .collect::<Result<_, _>>()?,
        };
        cams.insert(cam.id, cam);
    }
    Ok(cams)
}

fn parse_images_text(file: &Path, text: &str) -> Result<Vec<ColmapImage>, ImportError> {
    // Two lines per image; the second (2-D points) may be empty, so only comments are skipped,
    // and blank lines only where an image line is expected.
    let mut images = Vec::new();
    let mut lines = data_lines(text).peekable();
    while let Some((line, l)) = lines.next() {
        if l.is_empty() {
            continue;
        }
        let t: Vec<&str> = l.split_whitespace().collect();
        if t.len() < 10 {
            return Err(parse_err(
                file,
                format!("line {line}: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME"),
            ));
        }
        let f = |i: usize, what: &str| num::<f64>(file, line, what, t[i]);
        let mut points2d = Vec::new();
        if let Some((pline, p)) = lines.next() {
            let pt: Vec<&str> = p.split_whitespace().collect();
            if !pt.len().is_multiple_of(3) {
                return Err(parse_err(
                    file,
                    format!("line {pline}: 2-D points come in triples X Y POINT3D_ID"),
                ));
            }
            for c in pt.chunks(3) {
                points2d.push((
                    num(file, pline, "x", c[0])?,
                    num(file, pline, "y", c[1])?,
                    num(file, pline, "point3D id", c[2])?,
                ));
            }
        }
        images.push(ColmapImage {
            id: num(file, line, "image id", t[0])?,
            qvec: [f(1, "qw")?, f(2, "qx")?, f(3, "qy")?, f(4, "qz")?],
            tvec: [f(5, "tx")?, f(6, "ty")?, f(7, "tz")?],
            camera_id: num(file, line, "camera id", t[8])?,
            name: t[9..].join(" "),
            points2d,
        });
    }
    Ok(images)
}

fn parse_points_text(file: &Path, text: &str) -> Result<Vec<ColmapPoint>, ImportError> {
    let mut points = Vec::new();
    for (line, l) in data_lines(text).filter(|(_, l)| !l.is_empty()) {
        let t: Vec<&str> = l.split_whitespace().collect();
        if t.len() < 8 || !(t.len() - 8).is_multiple_of(2) {
            return Err(parse_err(
                file,
                format!("line {line}: expected POINT3D_ID X Y Z R G B ERROR TRACK[] (pairs)"),
            ));
        }
        let track = t[8..]
            .chunks(2)
            .map(|c| {
                Ok((
                    num(file, line, "image id", c[0])?,
                    num(file, line, "2-D point index", c[1])?,
                ))
            })
            .collect::<Result<_, ImportError>>()?;
        points.push(ColmapPoint {
            id: num(file, line, "point id", t[0])?,
            xyz: [
                num(file, line, "x", t[1])?,
                num(file, line, "y", t[2])?,
                num(file, line, "z", t[3])?,
            ],
            rgb: [
                num(file, line, "r", t[4])?,
                num(file, line, "g", t[5])?,
                num(file, line, "b", t[6])?,
            ],
            error: num(file, line, "error", t[7])?,
            track,
        });
    }
    Ok(points)
}

/// Writes the model as `cameras.txt`, `images.txt`, `points3D.txt` in `dir` (created). Numbers
/// are written in Rust's shortest round-trip form, so reading back gives the same bits.
pub fn write_text(model: &ColmapModel, dir: &Path) -> Result<(), ImportError> {
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    let mut cams = String::from(
        "# Camera list with one line of data per camera:\n\
         #   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n",
    );
    let _ = writeln!(cams, "# Number of cameras: {}", model.cameras.len());
    for c in model.cameras.values() {
        let _ = write!(cams, "{} {} {} {}", c.id, c.model, c.width, c.height);
        for p in &c.params {
            let _ = write!(cams, " {p:?}");
        }
        cams.push('\n');
    }
    let mut imgs = String::from(
        "# Image list with two lines of data per image:\n\
         #   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n\
         #   POINTS2D[] as (X, Y, POINT3D_ID)\n",
    );
    let _ = writeln!(imgs, "# Number of images: {}", model.images.len());
    for im in &model.images {
        let [qw, qx, qy, qz] = im.qvec;
        let [tx, ty, tz] = im.tvec;
        let _ = writeln!(
            imgs,
            "{} {qw:?} {qx:?} {qy:?} {qz:?} {tx:?} {ty:?} {tz:?} {} {}",
            im.id, im.camera_id, im.name
        );
        let obs: Vec<String> = im
            .points2d
            .iter()
            .map(|(x, y, id)| format!("{x:?} {y:?} {id}"))
            .collect();
        imgs.push_str(&obs.join(" "));
        imgs.push('\n');
    }
    let mut pts = String::from(
        "# 3D point list with one line of data per point:\n\
         #   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n",
    );
    let _ = writeln!(pts, "# Number of points: {}", model.points.len());
    for p in &model.points {
        let [x, y, z] = p.xyz;
        let [r, g, b] = p.rgb;
        let _ = write!(pts, "{} {x:?} {y:?} {z:?} {r} {g} {b} {:?}", p.id, p.error);
        for (i, k) in &p.track {
            let _ = write!(pts, " {i} {k}");
        }
        pts.push('\n');
    }
    for (name, text) in [
        ("cameras.txt", cams),
        ("images.txt", imgs),
        ("points3D.txt", pts),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(io_err(&path))?;
    }
    Ok(())
}

/// The intrinsics `K` of a camera and its lens distortion (module doc for the models; the
/// distortion is undone when the scene is written, [`super::undistort`]).
pub fn intrinsics(
    cam: &ColmapCamera,
    file: &Path,
) -> Result<(Matrix3<f64>, Distortion), ImportError> {
    let unsupported = |hint: String| ImportError::UnsupportedModel {
        file: file.into(),
        camera_id: cam.id as u64,
        model: cam.model.clone(),
        hint,
    };
    let Some(&(_, _, n)) = MODELS.iter().find(|m| m.0 == cam.model) else {
        return Err(unsupported(format!(
            "not a COLMAP model name; {}",
            supported_hint()
        )));
    };
    if !SUPPORTED.contains(&cam.model.as_str()) {
        return Err(unsupported(supported_hint()));
    }
    if cam.params.len() != n {
        return Err(parse_err(
            file,
            format!(
                "camera {} ({}) has {} parameters, expected {n}",
                cam.id,
                cam.model,
                cam.params.len()
            ),
        ));
    }
    let p = &cam.params;
    let zero = Distortion::default();
    let (fx, fy, cx, cy, distortion) = match cam.model.as_str() {
        "SIMPLE_PINHOLE" => (p[0], p[0], p[1], p[2], zero),
        "PINHOLE" => (p[0], p[1], p[2], p[3], zero),
        "SIMPLE_RADIAL" => (p[0], p[0], p[1], p[2], Distortion { k1: p[3], ..zero }),
        "RADIAL" => (
            p[0],
            p[0],
            p[1],
            p[2],
            Distortion {
                k1: p[3],
                k2: p[4],
                ..zero
            },
        ),
        _ => (
            p[0],
            p[1],
            p[2],
            p[3],
            Distortion {
                k1: p[4],
                k2: p[5],
                p1: p[6],
                p2: p[7],
            },
        ),
    };
    let coefficients = [distortion.k1, distortion.k2, distortion.p1, distortion.p2];
    if coefficients.iter().any(|c| !c.is_finite()) {
        return Err(parse_err(
            file,
            format!(
                "camera {}: distortion coefficients must be finite, got {p:?}",
                cam.id
            ),
        ));
    }
    let finite = fx.is_finite() && fy.is_finite() && cx.is_finite() && cy.is_finite();
    if !(finite && fx > 0.0 && fy > 0.0) {
        return Err(parse_err(
            file,
            format!(
                "camera {}: focal lengths must be positive and finite, got {p:?}",
                cam.id
            ),
        ));
    }
    // The undistorted image keeps K and the size (module doc of `undistort`): its pixels reach
    // the normalised radius of its farthest corner, and the model must not fold back before it.
    let r_image = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
        .iter()
        .map(|&(a, b)| {
            let u = (a * cam.width as f64 - cx) / fx;
            let v = (b * cam.height as f64 - cy) / fy;
            (u * u + v * v).sqrt()
        })
        .fold(0.0, f64::max);
    if let Some(r) = distortion.radial_fold(r_image) {
        return Err(parse_err(
            file,
            format!(
                "camera {} ({} {p:?}): the radial distortion r·(1 + k1·r² + k2·r⁴) folds back at \
                 r = {r:.4} ({:.1} px from the principal point), inside the image, whose corners \
                 reach r = {r_image:.4}: undistorting would repeat parts of the view in rings. \
                 Check the calibration (a sign or a unit slipped?)",
                cam.id,
                cam.model,
                r * fx
            ),
        ));
    }
    Ok((
        Matrix3::new(fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0),
        distortion,
    ))
}

/// World-to-camera rotation of a COLMAP quaternion `[qw, qx, qy, qz]` (normalised first).
pub fn rotation(qvec: [f64; 4]) -> Option<Matrix3<f64>> {
    let q = Quaternion::new(qvec[0], qvec[1], qvec[2], qvec[3]);
    let n = q.norm();
    if !(n.is_finite() && n > 1e-12) {
        return None;
    }
    Some(
        UnitQuaternion::from_quaternion(q)
            .to_rotation_matrix()
            .into_inner(),
    )
}

/// The COLMAP quaternion `[qw, qx, qy, qz]` (`qw ≥ 0`) of a rotation matrix.
pub fn quaternion(r: &Matrix3<f64>) -> [f64; 4] {
    let q = UnitQuaternion::from_matrix(r);
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    [s * q.w, s * q.i, s * q.j, s * q.k]
}

/// What the automatic region of interest of [`import`] is computed from (`--roi-from`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum RoiSource {
    /// The camera layout when the capture orbits the sparse points, else the points
    /// ([`roi_auto`], which says which it took and why).
    #[default]
    Auto,
    /// The sparse points ([`roi_from_points`]): any capture, but only as complete as the points
    /// are; an object seen from one side gets a sphere about its visible side.
    Points,
    /// The camera layout ([`roi_from_cameras`]): the point nearest every optical axis and the
    /// largest sphere about it every camera sees whole; for captures that orbit an object and
    /// keep it in frame (DTU's rig, the simulator's), whatever the points cover.
    Cameras,
}

/// Options of [`import`].
#[derive(Clone, Debug, Default)]
pub struct ColmapImport {
    /// The model folder (`sparse/0`).
    pub model_dir: PathBuf,
    /// The image folder the model's image names are relative to.
    pub images: PathBuf,
    /// Optional mask folder (see [`super::find_mask`] for how masks are matched).
    pub masks: Option<PathBuf>,
    /// Region of interest override; `None` chooses it from [`Self::roi_from`].
    pub roi: Option<Roi>,
    /// What the automatic region of interest is computed from (ignored with `roi`).
    pub roi_from: RoiSource,
}

/// Reads the model and turns it into views sorted by image name plus a region of interest.
/// Returns the views, the ROI choice and the model's form.
pub fn import(
    opts: &ColmapImport,
) -> Result<(Vec<ImportedView>, RoiChoice, ModelFormat), ImportError> {
    let (model, format) = read_model(&opts.model_dir)?;
    let ext = if format == ModelFormat::Binary {
        "bin"
    } else {
        "txt"
    };
    let cameras_file = opts.model_dir.join(format!("cameras.{ext}"));
    let images_file = opts.model_dir.join(format!("images.{ext}"));
    if model.images.is_empty() {
        return Err(ImportError::NoViews(images_file));
    }
    if !opts.images.is_dir() {
        return Err(ImportError::MissingFile {
            path: opts.images.clone(),
            what: "the image folder given by --images".into(),
        });
    }
    if let Some(dir) = opts.masks.as_ref().filter(|d| !d.is_dir()) {
        return Err(ImportError::MissingFile {
            path: dir.clone(),
            what: "the --masks folder does not exist, or is not a folder".into(),
        });
    }
    let mut images: Vec<&ColmapImage> = model.images.iter().collect();
    images.sort_by(|a, b| a.name.cmp(&b.name));
    let mut views = Vec::with_capacity(images.len());
    // Each photograph once: the file (links resolved) → the first image naming it.
    let mut seen: BTreeMap<PathBuf, &ColmapImage> = BTreeMap::new();
    for im in images {
        let cam = model.cameras.get(&im.camera_id).ok_or_else(|| {
            parse_err(
                &images_file,
                format!(
                    "image '{}' uses camera {}, which {} does not define",
                    im.name,
                    im.camera_id,
                    cameras_file.display()
                ),
            )
        })?;
        let (k, distortion) = intrinsics(cam, &cameras_file)?;
        let r = rotation(im.qvec).ok_or_else(|| {
            parse_err(
                &images_file,
                format!(
                    "image '{}': quaternion {:?} is not a rotation",
                    im.name, im.qvec
                ),
            )
        })?;
        let t = Vector3::from(im.tvec);
        if !t.iter().all(|v| v.is_finite()) {
            return Err(parse_err(
                &images_file,
                format!(
                    "image '{}': translation {:?} is not finite",
                    im.name, im.tvec
                ),
            ));
        }
        let (Ok(width), Ok(height)) = (u32::try_from(cam.width), u32::try_from(cam.height)) else {
            return Err(parse_err(
                &cameras_file,
                format!(
                    "camera {}: size {}×{} is too large",
                    cam.id, cam.width, cam.height
                ),
            ));
        };
        let image = opts.images.join(&im.name);
        if !image.is_file() {
            return Err(ImportError::MissingImage {
                name: im.name.clone(),
                model: images_file.clone(),
                path: image,
            });
        }
        let file = image.canonicalize().map_err(io_err(&image))?;
        if let Some(first) = seen.get(&file) {
            // The two entries in the order of their ids.
            let (a, b) = if first.id <= im.id {
                (*first, im)
            } else {
                (im, *first)
            };
            return Err(ImportError::DuplicateImage {
                source_file: images_file.clone(),
                first: format!("image {} ('{}')", a.id, a.name),
                second: format!("image {} ('{}')", b.id, b.name),
                path: image,
            });
        }
        seen.insert(file, im);
        let mask = match &opts.masks {
            Some(dir) => Some(find_mask_or_err(dir, &im.name)?),
            None => None,
        };
        views.push(ImportedView {
            name: im.name.clone(),
            image,
            mask,
            camera: Camera {
                k,
                r,
                // x_cam = R·X + t = R·(X − C)  ⇒  C = −Rᵀ·t.
                center: -(r.transpose() * t),
                width,
                height,
            },
            distortion,
        });
    }
    // Before the region of interest: cameras with no baseline make every automatic choice fail
    // in ways that do not say why.
    let middle = |k: usize| {
        let mut axis: Vec<f64> = model
            .points
            .iter()
            .map(|p| p.xyz[k])
            .filter(|v| v.is_finite())
            .collect();
        axis.sort_by(f64::total_cmp);
        axis.get(axis.len() / 2).copied()
    };
    let points_middle = (0..3)
        .map(middle)
        .collect::<Option<Vec<f64>>>()
        .map(|m| [m[0], m[1], m[2]]);
    check_baseline(&views, opts.roi.map(|r| r.center).or(points_middle))?;
    let roi = match opts.roi {
        Some(roi) => RoiChoice {
            roi,
            method: "given by --roi-center and --roi-radius".into(),
        },
        None => {
            let cameras: Vec<Camera> = views.iter().map(|v| v.camera.clone()).collect();
            let points: Vec<([f64; 3], usize)> = model
                .points
                .iter()
                .map(|p| (p.xyz, p.track.len()))
                .collect();
            match opts.roi_from {
                RoiSource::Auto => roi_auto(&points, &cameras)?,
                RoiSource::Cameras => roi_from_cameras(&cameras)?,
                RoiSource::Points => {
                    let centers: Vec<Vector3<f64>> = cameras.iter().map(|c| c.center).collect();
                    roi_from_points(&points, &centers)?
                }
            }
        }
    };
    Ok((views, roi, format))
}

#[cfg(test)]
mod tests;
