//! instant-ngp / nerfstudio `transforms.json`: reading it into [`ImportedView`]s and writing one
//! from cameras (for `synth --export transforms`).
//!
//! Conventions (instant-ngp `docs/nerf_dataset_tips.md` and `scripts/colmap2nerf.py`;
//! nerfstudio `docs/quickstart/data_conventions.md` and `nerfstudio/cameras/camera_utils.py`):
//! - Each frame's `transform_matrix` is the **camera-to-world** 4×4 pose with **OpenGL camera
//!   axes** (x right, y up, z backward: the camera looks along −z). The OpenCV camera of
//!   [`Camera`] (x right, y down, z forward) is the same camera with its y and z axes flipped:
//!   `c2w_cv = c2w_gl · diag(1, −1, −1, 1)`, i.e. negate the second and third columns of the
//!   rotation; the camera centre (last column) is unchanged. Then `R = R_c2w_cvᵀ`.
//! - Intrinsics in pixels: `fl_x`, `fl_y`, `cx`, `cy`, `w`, `h`, either at the top level (shared)
//!   or in each frame (a frame's value wins); or a horizontal field of view `camera_angle_x`
//!   (radians) with `fl_x = 0.5·w / tan(0.5·camera_angle_x)` (and `camera_angle_y` likewise for
//!   `fl_y`; `fl_y` defaults to `fl_x`). `cx`, `cy` default to the image centre `w/2`, `h/2`;
//!   `w`, `h` default to the image file's size. Pixel centres are at +0.5 (nerfstudio
//!   `get_image_coords(pixel_offset=0.5)`), as in [`Camera`], so `cx, cy` carry over unchanged.
//! - `file_path` (and nerfstudio's optional `mask_path`) are relative to the json's folder, with
//!   or without an extension (the Blender scenes write `./train/r_0`); a path without one is
//!   tried with `.png`, `.PNG`, `.jpg`, `.jpeg`, `.JPG`.
//! - Distortion coefficients (`k1 k2 k3 k4 p1 p2`) must be absent or zero, and a nerfstudio
//!   `camera_model` must be `OPENCV` or `PINHOLE` (pinhole rays only, as for COLMAP).
//! - Ignored: instant-ngp's `scale`, `offset` and `aabb_scale` (they configure its own
//!   normalisation at load time, not the cameras) and nerfstudio's `applied_transform`.
//!
//! Frames keep the file's order. The region of interest comes from the camera layout
//! ([`roi_from_cameras`]) unless overridden.

use super::{check_baseline, io_err, roi_from_cameras, ImportError, ImportedView, Roi, RoiChoice};
use crate::scene::Camera;
use nalgebra::{Matrix3, Vector3};
use serde_json::{json, Map, Value};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// `diag(1, −1, −1)`: flips the camera y and z axes between OpenGL and OpenCV.
fn flip_yz() -> Matrix3<f64> {
    Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0))
}

/// The OpenGL camera-to-world 4×4 pose (row-major rows) of an OpenCV [`Camera`].
pub fn c2w_opengl(cam: &Camera) -> [[f64; 4]; 4] {
    let r = cam.r.transpose() * flip_yz();
    let mut m = [[0.0, 0.0, 0.0, 1.0]; 4];
    for (i, row) in m.iter_mut().take(3).enumerate() {
        for (j, v) in row.iter_mut().take(3).enumerate() {
            *v = r[(i, j)];
        }
        row[3] = cam.center[i];
    }
    m
}

fn parse_err(file: &Path, message: String) -> ImportError {
    ImportError::Parse {
        file: file.into(),
        message,
    }
}

/// A number field: the frame's, else the top level's; `Err` when present but not a number.
fn field(
    file: &Path,
    what: &str,
    frame: &Map<String, Value>,
    top: &Map<String, Value>,
    key: &str,
) -> Result<Option<f64>, ImportError> {
    match frame.get(key).or_else(|| top.get(key)) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => match v.as_f64() {
            Some(x) if x.is_finite() => Ok(Some(x)),
            _ => Err(parse_err(
                file,
                format!("{what}: '{key}' = {v} is not a finite number"),
            )),
        },
    }
}

/// Resolves `rel` against `dir`, trying image extensions when the path has none or is absent.
fn resolve_image(dir: &Path, rel: &str) -> Option<PathBuf> {
    let p = dir.join(rel);
    if p.is_file() {
        return Some(p);
    }
    ["png", "PNG", "jpg", "jpeg", "JPG"].iter().find_map(|ext| {
        let mut s = p.clone().into_os_string();
        s.push(".");
        s.push(ext);
        let q = PathBuf::from(s);
        q.is_file().then_some(q)
    })
}

/// Reads `json_path` into views in file order plus the region of interest (`roi` overrides the
/// camera-layout choice).
pub fn import(
    json_path: &Path,
    roi: Option<Roi>,
) -> Result<(Vec<ImportedView>, RoiChoice), ImportError> {
    let text = std::fs::read_to_string(json_path).map_err(|source| {
        if source.kind() == std::io::ErrorKind::NotFound {
            ImportError::MissingFile {
                path: json_path.into(),
                what: "the transforms.json to import".into(),
            }
        } else {
            ImportError::Io {
                path: json_path.into(),
                source,
            }
        }
    })?;
    let root: Value = serde_json::from_str(&text)
        .map_err(|e| parse_err(json_path, format!("is not valid JSON: {e}")))?;
    let top = root
        .as_object()
        .ok_or_else(|| parse_err(json_path, "the top level is not a JSON object".into()))?;
    let frames = match top.get("frames") {
        Some(Value::Array(f)) if !f.is_empty() => f,
        Some(Value::Array(_)) => return Err(ImportError::NoViews(json_path.into())),
        _ => {
            return Err(parse_err(
                json_path,
                "has no 'frames' array (instant-ngp / nerfstudio format expected)".into(),
            ))
        }
    };
    if let Some(m) = top.get("camera_model").and_then(Value::as_str) {
        if m != "OPENCV" && m != "PINHOLE" {
            return Err(ImportError::UnsupportedModel {
                file: json_path.into(),
                camera_id: 0,
                model: m.into(),
                hint: "neus-aug models pinhole rays only (OPENCV without distortion, PINHOLE); \
                       undistort the images first"
                    .into(),
            });
        }
    }
    let dir = json_path.parent().unwrap_or(Path::new("."));
    let mut views = Vec::with_capacity(frames.len());
    // Each photograph once: the file (links resolved) → the frame that named it first.
    let mut seen: BTreeMap<PathBuf, (usize, String)> = BTreeMap::new();
    for (i, frame) in frames.iter().enumerate() {
        let frame = frame
            .as_object()
            .ok_or_else(|| parse_err(json_path, format!("frame {i} is not a JSON object")))?;
        let rel = frame
            .get("file_path")
            .and_then(Value::as_str)
            .ok_or_else(|| parse_err(json_path, format!("frame {i} has no 'file_path' string")))?;
        let what = format!("frame {i} ('{rel}')");
        let image = resolve_image(dir, rel).ok_or_else(|| ImportError::MissingImage {
            name: rel.into(),
            model: json_path.into(),
            path: dir.join(rel),
        })?;
        let mask = match frame.get("mask_path").and_then(Value::as_str) {
            Some(m) => Some(
                resolve_image(dir, m).ok_or_else(|| ImportError::MissingImage {
                    name: m.into(),
                    model: json_path.into(),
                    path: dir.join(m),
                })?,
            ),
            None => None,
        };
        let get = |key: &str| field(json_path, &what, frame, top, key);
        for key in ["k1", "k2", "k3", "k4", "p1", "p2"] {
            if let Some(v) = get(key)? {
                if v != 0.0 {
                    return Err(ImportError::UnsupportedModel {
                        file: json_path.into(),
                        camera_id: i as u64,
                        model: format!("distorted (frame '{rel}': {key} = {v})"),
                        hint: "neus-aug models pinhole rays only; undistort the images first"
                            .into(),
                    });
                }
            }
        }
        let (w, h) = match (get("w")?, get("h")?) {
            (Some(w), Some(h)) => (w, h),
            _ => {
                let (w, h) = image::image_dimensions(&image).map_err(|source| {
                    ImportError::Image(crate::scene::ImageError::Decode {
                        path: image.clone(),
                        source,
                    })
                })?;
                (w as f64, h as f64)
            }
        };
        if !(w >= 1.0 && h >= 1.0 && w.fract() == 0.0 && h.fract() == 0.0 && w < 1e9 && h < 1e9) {
            return Err(parse_err(
                json_path,
                format!("{what}: image size {w}×{h} is invalid"),
            ));
        }
        let fx = match (get("fl_x")?, get("camera_angle_x")?) {
            (Some(f), _) => f,
            (None, Some(a)) => 0.5 * w / (0.5 * a).tan(),
            (None, None) => {
                return Err(parse_err(
                    json_path,
                    format!(
                        "{what} has no focal length: neither 'fl_x' nor 'camera_angle_x' in the \
                         frame or shared at the top level (intrinsics must be shared or given \
                         for every frame)"
                    ),
                ))
            }
        };
        let fy = match (get("fl_y")?, get("camera_angle_y")?) {
            (Some(f), _) => f,
            (None, Some(a)) => 0.5 * h / (0.5 * a).tan(),
            (None, None) => fx,
        };
        if !(fx > 0.0 && fy > 0.0 && fx.is_finite() && fy.is_finite()) {
            return Err(parse_err(
                json_path,
                format!("{what}: focal lengths {fx}, {fy} are not positive"),
            ));
        }
        let cx = get("cx")?.unwrap_or(0.5 * w);
        let cy = get("cy")?.unwrap_or(0.5 * h);
        let m = frame
            .get("transform_matrix")
            .and_then(Value::as_array)
            .ok_or_else(|| parse_err(json_path, format!("{what} has no 'transform_matrix'")))?;
        let bad_matrix = |why: &str| {
            parse_err(
                json_path,
                format!("{what}: 'transform_matrix' {why} (expected a 4×4 camera-to-world pose)"),
            )
        };
        if m.len() != 4 && m.len() != 3 {
            return Err(bad_matrix("does not have 3 or 4 rows"));
        }
        let mut c2w = [[0.0f64; 4]; 3];
        for (r, row) in c2w.iter_mut().enumerate() {
            let vals = m[r].as_array().filter(|a| a.len() == 4);
            let vals = vals.ok_or_else(|| bad_matrix("has a row that is not 4 numbers"))?;
            for (c, v) in row.iter_mut().enumerate() {
                *v = vals[c]
                    .as_f64()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| bad_matrix("has a non-finite or non-numeric entry"))?;
            }
        }
        let r_gl = Matrix3::from_fn(|a, b| c2w[a][b]);
        let ortho = (r_gl.transpose() * r_gl - Matrix3::identity()).abs().max();
        if ortho > 1e-6 || r_gl.determinant() <= 0.0 {
            return Err(bad_matrix(&format!(
                "has a rotation block that is not a rotation (|RᵀR − I| = {ortho:.2e}, det = {:.4})",
                r_gl.determinant()
            )));
        }
        let r = (r_gl * flip_yz()).transpose();
        let file = image.canonicalize().map_err(io_err(&image))?;
        if let Some((j, first)) = seen.get(&file) {
            return Err(ImportError::DuplicateImage {
                source_file: json_path.into(),
                first: format!("frame {j} ('{first}')"),
                second: format!("frame {i} ('{rel}')"),
                path: image,
            });
        }
        seen.insert(file, (i, rel.to_string()));
        views.push(ImportedView {
            name: rel.into(),
            image,
            mask,
            camera: Camera {
                k: Matrix3::new(fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0),
                r,
                center: Vector3::new(c2w[0][3], c2w[1][3], c2w[2][3]),
                width: w as u32,
                height: h as u32,
            },
            distortion: Default::default(),
        });
    }
    check_baseline(&views, roi.map(|r| r.center))?;
    let choice = match roi {
        Some(roi) => RoiChoice {
            roi,
            method: "given by --roi-center and --roi-radius".into(),
        },
        None => {
            let cams: Vec<Camera> = views.iter().map(|v| v.camera.clone()).collect();
            roi_from_cameras(&cams)?
        }
    };
    Ok((views, choice))
}

/// One frame to export: image path (as written into `file_path`), optional mask path, camera.
pub struct FrameOut<'a> {
    /// `file_path` value.
    pub file_path: String,
    /// `mask_path` value (nerfstudio), if any.
    pub mask_path: Option<String>,
    /// The camera (OpenCV axes, world frame); skew must be zero.
    pub camera: &'a Camera,
}

/// Writes a transforms.json: intrinsics at the top level when every camera shares them, else per
/// frame; poses as OpenGL camera-to-world matrices (module doc).
pub fn write_json(path: &Path, frames: &[FrameOut]) -> Result<(), ImportError> {
    let intr = |c: &Camera| -> Result<Map<String, Value>, ImportError> {
        if c.k[(0, 1)] != 0.0 {
            return Err(ImportError::Export(format!(
                "camera has skew {} and transforms.json has no skew",
                c.k[(0, 1)]
            )));
        }
        let v = json!({
            "fl_x": c.k[(0, 0)], "fl_y": c.k[(1, 1)], "cx": c.k[(0, 2)], "cy": c.k[(1, 2)],
            "w": c.width, "h": c.height,
        });
        Ok(v.as_object().expect("object").clone())
    };
    let first = frames
        .first()
        .ok_or_else(|| ImportError::Export("no frames to write".into()))?;
    let shared = frames.iter().all(|f| {
        f.camera.k == first.camera.k
            && (f.camera.width, f.camera.height) == (first.camera.width, first.camera.height)
    });
    let mut top = if shared {
        intr(first.camera)?
    } else {
        Map::new()
    };
    top.insert("camera_model".into(), "OPENCV".into());
    let mut list = Vec::with_capacity(frames.len());
    for f in frames {
        let mut fr = if shared { Map::new() } else { intr(f.camera)? };
        intr(f.camera)?; // skew check in the shared case too
        fr.insert("file_path".into(), f.file_path.clone().into());
        if let Some(m) = &f.mask_path {
            fr.insert("mask_path".into(), m.clone().into());
        }
        fr.insert("transform_matrix".into(), json!(c2w_opengl(f.camera)));
        list.push(Value::Object(fr));
    }
    top.insert("frames".into(), Value::Array(list));
    let text = serde_json::to_string_pretty(&Value::Object(top)).expect("json serialises");
    std::fs::write(path, text).map_err(io_err(path))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::camera::tests::random_camera;
    use crate::scene::RgbImage;
    use rand::SeedableRng;

    #[test]
    fn opengl_pose_is_the_opencv_camera_with_y_and_z_flipped() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(2);
        let cam = random_camera(&mut rng);
        let m = c2w_opengl(&cam);
        // The OpenGL camera looks along its −z axis: −(third column) is the OpenCV optical axis,
        // and its +y axis (second column) is OpenCV's −y (up in the image).
        for (k, row) in m.iter().take(3).enumerate() {
            assert!((-row[2] - cam.r[(2, k)]).abs() < 1e-15);
            assert!((-row[1] - cam.r[(1, k)]).abs() < 1e-15);
            assert!((row[0] - cam.r[(0, k)]).abs() < 1e-15);
            assert_eq!(row[3], cam.center[k]);
        }
    }

    fn write_png(path: &Path, w: usize, h: usize) {
        RgbImage::new(w, h).save(path).unwrap();
    }

    #[test]
    fn blender_style_file_with_camera_angle_and_no_extension() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("train")).unwrap();
        write_png(&dir.path().join("train/r_0.png"), 8, 6);
        write_png(&dir.path().join("train/r_1.png"), 8, 6);
        let angle: f64 = 0.6911112070083618;
        let text = format!(
            r#"{{"camera_angle_x": {angle}, "frames": [
              {{"file_path": "./train/r_0", "transform_matrix":
                 [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}},
              {{"file_path": "./train/r_1", "transform_matrix":
                 [[0,0,1,4],[1,0,0,0],[0,1,0,0],[0,0,0,1]], "fl_y": 9.5}}]}}"#
        );
        let json = dir.path().join("transforms.json");
        std::fs::write(&json, text).unwrap();
        let (views, roi) = import(&json, None).unwrap();
        assert_eq!(views.len(), 2);
        let f = 0.5 * 8.0 / (0.5 * angle).tan();
        let c0 = &views[0].camera;
        assert_eq!((c0.width, c0.height), (8, 6));
        assert_eq!(c0.k, Matrix3::new(f, 0.0, 4.0, 0.0, f, 3.0, 0.0, 0.0, 1.0));
        // Identity OpenGL pose at z = 4: the camera looks along world −z, image y down = world −y.
        assert_eq!(c0.r, Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0)));
        assert_eq!(c0.center, Vector3::new(0.0, 0.0, 4.0));
        assert_eq!(views[1].camera.k[(1, 1)], 9.5);
        // Both axes pass through the origin: that is the ROI centre.
        assert!(Vector3::from(roi.roi.center).norm() < 1e-12, "{roi:?}");
        assert!(roi.roi.radius < 4.0);
    }

    #[test]
    fn jpeg_frames_without_extension_become_png_scenes() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (16u32, 12u32);
        let pixels = image::RgbImage::from_fn(w, h, |x, y| {
            image::Rgb([(x * 15) as u8, (y * 20) as u8, 90])
        });
        pixels.save(dir.path().join("f0.jpg")).unwrap();
        pixels.save(dir.path().join("f1.jpg")).unwrap();
        let text = r#"{"fl_x": 20, "frames": [
            {"file_path": "f0", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,5],[0,0,0,1]]},
            {"file_path": "f1", "transform_matrix": [[0,0,1,5],[1,0,0,0],[0,1,0,0],[0,0,0,1]]}]}"#;
        let json = dir.path().join("transforms.json");
        std::fs::write(&json, text).unwrap();
        let (views, roi) = import(&json, None).unwrap();
        assert_eq!(views[0].image, dir.path().join("f0.jpg"));
        let out = dir.path().join("scene");
        crate::import::write_imported_scene(&out, &views, &roi, "transforms", &json).unwrap();
        let png = RgbImage::load(&out.join("image/000001.png")).unwrap();
        let jpg = RgbImage::load(&dir.path().join("f1.jpg")).unwrap();
        assert_eq!((png.width, png.height), (16, 12));
        // The PNG holds the decoded JPEG's 8-bit values exactly.
        assert_eq!(png, jpg);
    }

    #[test]
    fn bad_files_name_the_problem() {
        let dir = tempfile::tempdir().unwrap();
        write_png(&dir.path().join("a.png"), 4, 4);
        let json = dir.path().join("t.json");
        let case = |text: &str| {
            std::fs::write(&json, text).unwrap();
            import(&json, None).unwrap_err().to_string()
        };
        let eye = "[[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]";
        let err = case(r#"{"fl_x": 5, "frames": []}"#);
        assert!(err.contains("no registered image"), "{err}");
        let err = case(&format!(
            r#"{{"frames": [{{"file_path": "a.png", "transform_matrix": {eye}, "fl_x": 5}},
                           {{"file_path": "a.png", "transform_matrix": {eye}}}]}}"#
        ));
        assert!(
            err.contains("frame 1") && err.contains("no focal length"),
            "{err}"
        );
        let err = case(
            r#"{"fl_x": 5, "frames": [{"file_path": "a.png", "transform_matrix":
               [[1,0,0,0],[0,1,0,0],[0,0,1,NaN],[0,0,0,1]]}]}"#,
        );
        assert!(err.contains("not valid JSON"), "{err}");
        let err = case(
            r#"{"fl_x": 5, "frames": [{"file_path": "a.png", "transform_matrix":
               [[1,0,0,0],[0,1,0,0],[0,0,1,"nan"],[0,0,0,1]]}]}"#,
        );
        assert!(err.contains("non-finite"), "{err}");
        let err = case(&format!(
            r#"{{"fl_x": 5, "frames": [{{"file_path": "b.png", "transform_matrix": {eye}}}]}}"#
        ));
        assert!(
            err.contains("b.png") && err.contains("does not exist"),
            "{err}"
        );
        let err = case(&format!(
            r#"{{"fl_x": 5, "k1": 0.1, "frames": [{{"file_path": "a.png", "transform_matrix": {eye}}}]}}"#
        ));
        assert!(err.contains("k1"), "{err}");
        let err = case(
            r#"{"fl_x": 5, "frames": [{"file_path": "a.png", "transform_matrix":
               [[2,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]}]}"#,
        );
        assert!(err.contains("not a rotation"), "{err}");
        assert!(import(&dir.path().join("none.json"), None)
            .unwrap_err()
            .to_string()
            .contains("none.json"));
    }
}
