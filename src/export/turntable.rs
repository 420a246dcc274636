//! A turntable GIF of an exported mesh and a contact sheet of the held-out views.
//!
//! The orbit ([`Orbit::around`]) circles the scene's up axis ([`super::scene_up`]) through the
//! normalisation centre at the training cameras' mean distance and mean elevation, starting at
//! the first camera's azimuth; the focal length frames the mesh's bounding sphere (about the
//! centre) in 90 % of the shorter side. Each frame is the mesh's colour render beside its
//! normal render ([`super::raycast`]); the GIF (`gif` crate, NeuQuant palette per frame, looping)
//! plays one turn in four seconds.
//!
//! The turntable renders the exported mesh, not the field: ray casting a mesh costs a fraction
//! of a second where volume rendering the same frames would cost about a tenth of a `quick` run,
//! and it shows what the user's viewer will show.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::raycast::MeshScene;
use super::{io_err, to_u8, ExportError};
use crate::scene::{Camera, RgbImage};
use dtu_eval::mesh::TriMesh;
use nalgebra::{Matrix3, Vector3};
use std::path::Path;

/// A circular camera path around an object (world frame).
#[derive(Clone, Debug, PartialEq)]
pub struct Orbit {
    /// Centre of the circle's axis (world).
    pub center: Vector3<f64>,
    /// Unit up axis.
    pub up: Vector3<f64>,
    /// Distance of the cameras from `center`.
    pub radius: f64,
    /// Elevation above the plane ⟂ `up` through `center`, radians.
    pub elevation: f64,
    /// Azimuth of the first frame, radians, from `a0` towards `up × a0`.
    pub azimuth0: f64,
    /// Unit reference direction ⟂ `up` (azimuth 0).
    pub a0: Vector3<f64>,
    /// Bounding-sphere radius of the object about `center`.
    pub object_radius: f64,
}

impl Orbit {
    /// The orbit of [`super::turntable`]'s module docs: from `cameras` (world frame), the mesh
    /// (world) and the normalisation centre (world). With no cameras: 45° elevation, three
    /// object radii away, about +z.
    pub fn around(cameras: &[Camera], mesh: &TriMesh, center: [f64; 3]) -> Self {
        let c = Vector3::from(center);
        let u = Vector3::from(super::scene_up(cameras));
        let a0 = {
            let t = if u.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            (t - u * u.dot(&t)).normalize()
        };
        let b0 = u.cross(&a0);
        let object_radius = mesh
            .vertices
            .iter()
            .map(|v| (Vector3::new(v[0] as f64, v[1] as f64, v[2] as f64) - c).norm())
            .fold(0.0f64, f64::max)
            .max(1e-6);
        let (mut dist, mut elev) = (0.0, 0.0);
        for cam in cameras {
            let d = cam.center - c;
            dist += d.norm();
            elev += (d.normalize().dot(&u)).clamp(-1.0, 1.0).asin();
        }
        let n = cameras.len() as f64;
        let (radius, elevation, azimuth0) = match cameras.first() {
            Some(first) => {
                let d = first.center - c;
                (dist / n, elev / n, d.dot(&b0).atan2(d.dot(&a0)))
            }
            None => (3.0 * object_radius, std::f64::consts::FRAC_PI_4, 0.0),
        };
        Self {
            center: c,
            up: u,
            radius: radius.max(1.5 * object_radius),
            elevation,
            azimuth0,
            a0,
            object_radius,
        }
    }

    /// The camera of frame `k` of `frames` (`w × h` pixels), looking at the centre with the up
    /// axis up in the image.
    pub fn camera(&self, k: u32, frames: u32, w: u32, h: u32) -> Camera {
        let phi = self.azimuth0 + std::f64::consts::TAU * k as f64 / frames.max(1) as f64;
        let b0 = self.up.cross(&self.a0);
        let dir = (self.a0 * phi.cos() + b0 * phi.sin()) * self.elevation.cos()
            + self.up * self.elevation.sin();
        let center = self.center + dir * self.radius;
        // OpenCV axes: z forward (to the centre), y down (against up), x = y × z.
        let z = -dir;
        let y = (-self.up + z * self.up.dot(&z)).normalize();
        let x = y.cross(&z);
        let r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
        let half = (self.object_radius / self.radius).clamp(1e-6, 0.999).asin();
        let f = 0.45 * w.min(h) as f64 / half.tan();
        Camera {
            k: Matrix3::new(
                f,
                0.0,
                w as f64 / 2.0,
                0.0,
                f,
                h as f64 / 2.0,
                0.0,
                0.0,
                1.0,
            ),
            r,
            center,
            width: w,
            height: h,
        }
    }
}

/// `images` side by side (same height), as 8-bit RGB.
fn hstack(images: &[&RgbImage]) -> (usize, usize, Vec<u8>) {
    let h = images[0].height;
    let w: usize = images.iter().map(|i| i.width).sum();
    let mut out = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for im in images {
            let row = &im.data[y * im.width * 3..(y + 1) * im.width * 3];
            out.extend(row.iter().map(|&v| to_u8(v)));
        }
    }
    (w, h, out)
}

/// Writes the turntable of `scene` along `orbit`: `frames` frames of two `size` panels (colour,
/// normals) on `background`, looping, as a GIF at `path` (atomically).
pub fn write_turntable(
    path: &Path,
    scene: &MeshScene,
    orbit: &Orbit,
    frames: u32,
    size: [u32; 2],
    background: [f32; 3],
) -> Result<(), ExportError> {
    let gif_err = |e: gif::EncodingError| ExportError::Io {
        path: path.into(),
        source: std::io::Error::other(e),
    };
    let mut bytes = Vec::new();
    {
        let (w, h) = (2 * size[0] as u16, size[1] as u16);
        let mut enc = gif::Encoder::new(&mut bytes, w, h, &[]).map_err(gif_err)?;
        enc.set_repeat(gif::Repeat::Infinite).map_err(gif_err)?;
        for k in 0..frames {
            let cam = orbit.camera(k, frames, size[0], size[1]);
            let r = scene.render(&cam, background);
            let (fw, fh, rgb) = hstack(&[&r.rgb, &r.normal]);
            let mut frame = gif::Frame::from_rgb_speed(fw as u16, fh as u16, &rgb, 10);
            // Hundredths of a second: one turn in about four seconds.
            frame.delay = (400 / frames.max(1)).max(2) as u16;
            enc.write_frame(&frame).map_err(gif_err)?;
        }
    }
    dtu_eval::atomic::write_atomic(path, &bytes).map_err(io_err(path))
}

/// The held-out views `renders/view{v:03}_{gt,rgb,normal}.png` in `renders` as one sheet, a row
/// per view (truth, render, normals), written to `path` (atomically). Views whose images are
/// missing are skipped; none at all writes nothing.
pub fn write_heldout_sheet(
    path: &Path,
    renders: &Path,
    views: &[usize],
) -> Result<(), ExportError> {
    let mut rows: Vec<Vec<RgbImage>> = Vec::new();
    for v in views {
        let load = |kind: &str| RgbImage::load(&renders.join(format!("view{v:03}_{kind}.png")));
        if let (Ok(g), Ok(r), Ok(n)) = (load("gt"), load("rgb"), load("normal")) {
            if g.width == r.width
                && r.width == n.width
                && g.height == r.height
                && r.height == n.height
            {
                rows.push(vec![g, r, n]);
            }
        }
    }
    let Some(first) = rows.first() else {
        return Ok(());
    };
    let gap = 2usize;
    let (w, h) = (first[0].width, first[0].height);
    let rows: Vec<&Vec<RgbImage>> = rows
        .iter()
        .filter(|r| r[0].width == w && r[0].height == h)
        .collect();
    let sw = 3 * w + 2 * gap;
    let sh = rows.len() * h + (rows.len() - 1) * gap;
    let mut sheet = RgbImage::from_fn(sw, sh, |_, _| [1.0; 3]);
    for (i, row) in rows.iter().enumerate() {
        for (j, im) in row.iter().enumerate() {
            for y in 0..h {
                for x in 0..w {
                    sheet.set(j * (w + gap) + x, i * (h + gap) + y, im.get(x, y));
                }
            }
        }
    }
    sheet.save(path)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The orbit's cameras all look at the centre, keep the distance and elevation, and the
    /// object's bounding sphere fits the frame.
    #[test]
    fn orbit_cameras_look_at_the_centre_from_the_mean_elevation() {
        let mesh = TriMesh {
            vertices: vec![[10.0, 0.0, 600.0], [-10.0, 0.0, 600.0], [0.0, 10.0, 600.0]],
            faces: vec![[0, 1, 2]],
        };
        let c = [0.0, 0.0, 600.0];
        // Four cameras around the object, 30° above the xy plane (up = +z in their images), at
        // distance 100: their image-up axes' tilts cancel.
        let cams: Vec<Camera> = (0..4)
            .map(|i| {
                let t = i as f64 * std::f64::consts::FRAC_PI_2 + 0.3;
                let e = 30f64.to_radians();
                let dir = Vector3::new(t.cos() * e.cos(), t.sin() * e.cos(), e.sin());
                let o = Orbit {
                    center: Vector3::from(c),
                    up: Vector3::z(),
                    radius: 100.0,
                    elevation: e,
                    azimuth0: 0.0,
                    a0: Vector3::x(),
                    object_radius: 10.0,
                };
                let cam = o.camera(0, 1, 64, 48);
                // Re-aim the reference camera along `dir`.
                let z = -dir;
                let y = (-Vector3::z() + z * z.z).normalize();
                let x = y.cross(&z);
                Camera {
                    r: Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]),
                    center: Vector3::from(c) + dir * 100.0,
                    ..cam
                }
            })
            .collect();
        let o = Orbit::around(&cams, &mesh, c);
        assert!((o.up - Vector3::z()).norm() < 1e-9, "{:?}", o.up);
        assert!((o.radius - 100.0).abs() < 1e-9);
        assert!((o.elevation - 30f64.to_radians()).abs() < 1e-9);
        assert!((o.object_radius - 10.0).abs() < 1e-4);
        for k in 0..8 {
            let cam = o.camera(k, 8, 64, 48);
            let (u, v, _) = cam.project(&Vector3::from(c)).unwrap();
            assert!(
                (u - 32.0).abs() < 1e-6 && (v - 24.0).abs() < 1e-6,
                "frame {k}"
            );
            assert!(((cam.center - Vector3::from(c)).norm() - 100.0).abs() < 1e-9);
            // Up is up: a point above the centre projects above it.
            let (_, v_up, _) = cam
                .project(&(Vector3::from(c) + Vector3::z() * 5.0))
                .unwrap();
            assert!(v_up < 24.0);
        }
        // The first frame sits at the first camera's azimuth.
        assert!((o.camera(0, 8, 64, 48).center - cams[0].center).norm() < 1e-6);
    }
}
