//! In-memory images: RGB photographs and single-channel masks, as f32 in [0, 1].
//!
//! Layout (one place for it, used by every module): row-major, `y` down and `x` right (the OpenCV
//! pixel frame, as IDR and NeuS use it), pixel `(x, y)` covers `[x, x+1) × [y, y+1)` so its centre
//! is at `(x + 0.5, y + 0.5)`. RGB values are the PNG's stored (sRGB-encoded) values divided by the
//! channel maximum, without any gamma conversion, exactly as NeuS and instant-nsr-pl read them
//! (Totoro97/NeuS `models/dataset.py`: `cv.imread(...) / 256.0`; we divide by 255 so white is 1.0).

use std::path::{Path, PathBuf};

/// Errors of image input and output. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The file could not be read or decoded (missing, truncated, not a PNG, ...).
    #[error("cannot read image {path}: {source}")]
    Decode {
        path: PathBuf,
        #[source]
        source: image::ImageError,
    },
    /// The file could not be written.
    #[error("cannot write image {path}: {source}")]
    Encode {
        path: PathBuf,
        #[source]
        source: image::ImageError,
    },
    /// A pixel holds NaN or ±inf, which no image file can store.
    #[error("image for {path} has a non-finite value at pixel ({x}, {y})")]
    NonFinite { path: PathBuf, x: usize, y: usize },
    /// The image has no pixels.
    #[error("image {path} is empty (0 × 0)")]
    Empty { path: PathBuf },
}

/// An RGB image: `data` is `[height][width][3]` row-major interleaved, values in `[0, 1]`.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `height * width * 3` values, index `(y * width + x) * 3 + channel`.
    pub data: Vec<f32>,
}

/// A single-channel image (object masks, grayscale): `data` is `[height][width]` row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct GrayImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `height * width` values in `[0, 1]`, index `y * width + x`.
    pub data: Vec<f32>,
}

impl RgbImage {
    /// A black image of the given size.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            data: vec![0.0; width * height * 3],
        }
    }

    /// Builds an image from `f(x, y) -> [r, g, b]`.
    pub fn from_fn(
        width: usize,
        height: usize,
        mut f: impl FnMut(usize, usize) -> [f32; 3],
    ) -> Self {
        let mut data = Vec::with_capacity(width * height * 3);
        for y in 0..height {
            for x in 0..width {
                data.extend_from_slice(&f(x, y));
            }
        }
        Self {
            width,
            height,
            data,
        }
    }

    /// The pixel at column `x`, row `y`.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        let i = (y * self.width + x) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// Overwrites the pixel at column `x`, row `y`.
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, rgb: [f32; 3]) {
        let i = (y * self.width + x) * 3;
        self.data[i..i + 3].copy_from_slice(&rgb);
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// True when the image has no pixels.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Area-average downscale by an integer `factor` (`floor(size / factor)`; trailing rows and
    /// columns that do not fill a block are dropped, matching `Camera::downscaled`). `factor`
    /// must be at least 1.
    pub fn downscaled(&self, factor: usize) -> Self {
        Self {
            width: self.width / factor,
            height: self.height / factor,
            data: downscale_channels(&self.data, self.width, self.height, 3, factor),
        }
    }

    /// Reads a PNG (8 or 16 bit; gray, gray+alpha, RGB or RGBA; alpha is dropped).
    pub fn load(path: &Path) -> Result<Self, ImageError> {
        let img = open(path)?.into_rgb32f();
        let (width, height) = (img.width() as usize, img.height() as usize);
        if width == 0 || height == 0 {
            return Err(ImageError::Empty { path: path.into() });
        }
        Ok(Self {
            width,
            height,
            data: img.into_raw(),
        })
    }

    /// Writes an 8-bit RGB PNG (values clamped to `[0, 1]`, rounded to the nearest of 256 levels).
    /// Fails on NaN or infinite values instead of writing a silently wrong picture.
    pub fn save(&self, path: &Path) -> Result<(), ImageError> {
        let bytes = quantize(&self.data, self.width, 3, path)?;
        let buf = image::RgbImage::from_raw(self.width as u32, self.height as u32, bytes)
            .expect("buffer length matches the image size");
        write_png(path, |out| {
            buf.write_to(&mut std::io::Cursor::new(out), image::ImageFormat::Png)
        })
    }
}

/// Encodes a PNG in memory with `encode`, then writes it with the workspace's one atomic writer
/// ([`dtu_eval::atomic::write_atomic`]): every write checked, fsync, rename; a failed or cut-short
/// write never leaves a truncated PNG under `path`, and a `path` that is not a regular file
/// (FIFO, device, symbolic link) is refused.
fn write_png(
    path: &Path,
    encode: impl FnOnce(&mut Vec<u8>) -> image::ImageResult<()>,
) -> Result<(), ImageError> {
    let err = |source| ImageError::Encode {
        path: path.into(),
        source,
    };
    let mut bytes = Vec::new();
    encode(&mut bytes).map_err(err)?;
    dtu_eval::atomic::write_atomic(path, &bytes).map_err(|e| err(image::ImageError::IoError(e)))
}

impl GrayImage {
    /// A black (all-zero) image of the given size.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            data: vec![0.0; width * height],
        }
    }

    /// The value at column `x`, row `y`.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Area-average downscale by an integer `factor` (see [`RgbImage::downscaled`]).
    pub fn downscaled(&self, factor: usize) -> Self {
        Self {
            width: self.width / factor,
            height: self.height / factor,
            data: downscale_channels(&self.data, self.width, self.height, 1, factor),
        }
    }

    /// Reads a PNG as one channel. Colour masks (as DTU ships them: three equal channels) keep
    /// their first channel, as NeuS does (`models/dataset.py` uses `mask[..., :1]`).
    pub fn load(path: &Path) -> Result<Self, ImageError> {
        let img = open(path)?.into_rgb32f();
        let (width, height) = (img.width() as usize, img.height() as usize);
        if width == 0 || height == 0 {
            return Err(ImageError::Empty { path: path.into() });
        }
        let data = img.into_raw().chunks_exact(3).map(|p| p[0]).collect();
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// Writes an 8-bit grayscale PNG (values clamped to `[0, 1]`); fails on non-finite values.
    pub fn save(&self, path: &Path) -> Result<(), ImageError> {
        let bytes = quantize(&self.data, self.width, 1, path)?;
        let buf = image::GrayImage::from_raw(self.width as u32, self.height as u32, bytes)
            .expect("buffer length matches the image size");
        write_png(path, |out| {
            buf.write_to(&mut std::io::Cursor::new(out), image::ImageFormat::Png)
        })
    }

    /// Fraction of pixels with value `> 0.5` (the object's share of the image for a mask).
    pub fn coverage(&self) -> f64 {
        if self.data.is_empty() {
            return 0.0;
        }
        self.data.iter().filter(|&&v| v > 0.5).count() as f64 / self.data.len() as f64
    }
}

/// Area average over `f×f` blocks of an interleaved `[h][w][channels]` buffer.
fn downscale_channels(
    data: &[f32],
    width: usize,
    height: usize,
    channels: usize,
    f: usize,
) -> Vec<f32> {
    assert!(f >= 1, "downscale factor must be at least 1");
    let (w, h) = (width / f, height / f);
    let norm = 1.0 / (f * f) as f32;
    let mut out = vec![0.0; w * h * channels];
    for y in 0..h {
        for x in 0..w {
            for c in 0..channels {
                let mut acc = 0.0;
                for dy in 0..f {
                    for dx in 0..f {
                        acc += data[((y * f + dy) * width + x * f + dx) * channels + c];
                    }
                }
                out[(y * w + x) * channels + c] = acc * norm;
            }
        }
    }
    out
}

fn open(path: &Path) -> Result<image::DynamicImage, ImageError> {
    let decode = |source| ImageError::Decode {
        path: path.into(),
        source,
    };
    image::ImageReader::open(path)
        .map_err(|e| decode(image::ImageError::IoError(e)))?
        .with_guessed_format()
        .map_err(|e| decode(image::ImageError::IoError(e)))?
        .decode()
        .map_err(decode)
}

/// `[0, 1]` floats to bytes, `round(clamp(v) * 255)`; the first non-finite value is an error.
fn quantize(
    data: &[f32],
    width: usize,
    channels: usize,
    path: &Path,
) -> Result<Vec<u8>, ImageError> {
    data.iter()
        .enumerate()
        .map(|(i, &v)| {
            if !v.is_finite() {
                let px = i / channels;
                return Err(ImageError::NonFinite {
                    path: path.into(),
                    x: px % width.max(1),
                    y: px / width.max(1),
                });
            }
            Ok((v.clamp(0.0, 1.0) * 255.0).round() as u8)
        })
        .collect()
}

/// ITU-R 601-2 luma weights, as Pillow's `convert("L")` uses them (`L = R·299/1000 + G·587/1000
/// + B·114/1000`, Pillow `Image.convert` docs).
pub const LUMA_WEIGHTS: [f32; 3] = [0.299, 0.587, 0.114];

/// ITU-R 601-2 luma of one `[r, g, b]` pixel (see [`LUMA_WEIGHTS`]).
#[inline]
pub fn luma(c: [f32; 3]) -> f32 {
    LUMA_WEIGHTS[0] * c[0] + LUMA_WEIGHTS[1] * c[1] + LUMA_WEIGHTS[2] * c[2]
}

/// A mask dilated by a square window of radius `r` pixels (object where `> 0.5`), as booleans
/// `height × width` row-major. Separable running maximum, `O(width·height)` per axis.
pub fn dilate_mask(mask: &GrayImage, r: usize) -> Vec<bool> {
    let (w, h) = (mask.width, mask.height);
    let on: Vec<bool> = mask.data.iter().map(|&v| v > 0.5).collect();
    let run = |src: &[bool], len: usize, stride: usize, count: usize, step: usize| {
        // For each of `count` lines (start `j·step`), OR over a window of ±r along `stride`.
        let mut out = vec![false; src.len()];
        for j in 0..count {
            let base = j * step;
            // Prefix counts of "on" along the line.
            let mut pre = vec![0u32; len + 1];
            for i in 0..len {
                pre[i + 1] = pre[i] + src[base + i * stride] as u32;
            }
            for i in 0..len {
                let lo = i.saturating_sub(r);
                let hi = (i + r + 1).min(len);
                out[base + i * stride] = pre[hi] > pre[lo];
            }
        }
        out
    };
    let rows = run(&on, w, 1, h, w);
    run(&rows, h, w, w, 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_round_trip_is_exact_on_8_bit_levels() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        let img = RgbImage::from_fn(7, 5, |x, y| {
            [
                x as f32 / 255.0,
                y as f32 / 255.0,
                ((x * 31 + y * 17) % 256) as f32 / 255.0,
            ]
        });
        img.save(&path).unwrap();
        let back = RgbImage::load(&path).unwrap();
        assert_eq!((back.width, back.height), (7, 5));
        for (a, b) in img.data.iter().zip(&back.data) {
            assert!((a - b).abs() < 1e-6, "{a} vs {b}");
        }
    }

    #[test]
    fn nan_pixel_is_an_error_naming_the_pixel() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = RgbImage::new(4, 3);
        img.set(2, 1, [0.0, f32::NAN, 0.0]);
        let err = img.save(&dir.path().join("n.png")).unwrap_err().to_string();
        assert!(err.contains("(2, 1)"), "{err}");
    }

    #[test]
    fn corrupt_png_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.png");
        std::fs::write(&path, b"\x89PNG\r\n\x1a\nthis is not a png").unwrap();
        let err = RgbImage::load(&path).unwrap_err().to_string();
        assert!(err.contains("bad.png"), "{err}");
    }
}
