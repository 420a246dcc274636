//! Scenes in the DTU layout used by NeuS, IDR and instant-nsr-pl: images, masks, cameras and the
//! normalisation that maps the object into the unit sphere.

pub mod image;

pub use image::{GrayImage, ImageError, RgbImage};
