//! The COLMAP sparse model in memory (cameras, images, points), the camera models by name, and
//! the parse error both readers, text and binary, raise.

use super::ImportError;
use std::collections::BTreeMap;
use std::path::Path;

/// The camera models neus-aug knows by name (all COLMAP models, for the error messages), with
/// their COLMAP ids and parameter counts.
pub(crate) const MODELS: [(&str, i32, usize); 11] = [
    ("SIMPLE_PINHOLE", 0, 3),
    ("PINHOLE", 1, 4),
    ("SIMPLE_RADIAL", 2, 4),
    ("RADIAL", 3, 5),
    ("OPENCV", 4, 8),
    ("OPENCV_FISHEYE", 5, 8),
    ("FULL_OPENCV", 6, 12),
    ("FOV", 7, 5),
    ("SIMPLE_RADIAL_FISHEYE", 8, 4),
    ("RADIAL_FISHEYE", 9, 5),
    ("THIN_PRISM_FISHEYE", 10, 12),
];

/// Models whose parameters are `f cx cy ...` (one focal length) and that neus-aug imports.
pub(crate) const SUPPORTED: [&str; 5] = [
    "SIMPLE_PINHOLE",
    "PINHOLE",
    "SIMPLE_RADIAL",
    "RADIAL",
    "OPENCV",
];

/// One camera (intrinsics shared by some images).
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapCamera {
    /// COLMAP's camera id.
    pub id: u32,
    /// Model name, e.g. `PINHOLE`.
    pub model: String,
    /// Image width in pixels.
    pub width: u64,
    /// Image height in pixels.
    pub height: u64,
    /// Model parameters in COLMAP's order (see the module doc).
    pub params: Vec<f64>,
}

/// One registered image.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapImage {
    /// COLMAP's image id.
    pub id: u32,
    /// World-to-camera rotation quaternion `[qw, qx, qy, qz]`.
    pub qvec: [f64; 4],
    /// World-to-camera translation `t` (`x_cam = R·X + t`).
    pub tvec: [f64; 3],
    /// The camera it uses.
    pub camera_id: u32,
    /// File name relative to the image folder.
    pub name: String,
    /// Observations `(x, y, point3D id or −1)` in pixels.
    pub points2d: Vec<(f64, f64, i64)>,
}

/// One triangulated point.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapPoint {
    /// COLMAP's point id.
    pub id: u64,
    /// Position (world frame).
    pub xyz: [f64; 3],
    /// Colour.
    pub rgb: [u8; 3],
    /// Mean reprojection error (pixels).
    pub error: f64,
    /// Track: `(image id, index of the 2-D point in that image)`.
    pub track: Vec<(u32, u32)>,
}

/// A sparse model.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct ColmapModel {
    /// Cameras by id.
    pub cameras: BTreeMap<u32, ColmapCamera>,
    /// Images in file order.
    pub images: Vec<ColmapImage>,
    /// Points in file order.
    pub points: Vec<ColmapPoint>,
}

/// Which form a model folder holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelFormat {
    /// `*.txt`.
    Text,
    /// `*.bin`.
    Binary,
}

pub(crate) fn parse_err(file: &Path, message: String) -> ImportError {
    ImportError::Parse {
        file: file.into(),
        message,
    }
}

pub(crate) fn supported_hint() -> String {
    format!(
        "supported: {}; convert with `colmap image_undistorter`, which writes PINHOLE cameras",
        SUPPORTED.join(", ")
    )
}
