//! Scenes in the DTU layout used by NeuS, IDR and instant-nsr-pl: images, masks, cameras and the
//! normalisation that maps the object into the unit sphere.

pub mod camera;
pub mod dtu;
pub mod image;
pub mod npz;
pub mod summary;

pub use camera::{Camera, CameraError};
pub use dtu::{
    write_cameras, write_scene, LoadOptions, Normalization, Scene, SceneError, View, ViewOut,
};
pub use image::{GrayImage, ImageError, RgbImage};
pub use summary::SceneSummary;
