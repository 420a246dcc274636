//! Normal angular error of held-out renders against a ground-truth mesh (synthetic scenes, whose
//! folder holds `gt_mesh.ply` in world mm).
//!
//! Per pixel: the ray of the held-out camera (normalised space) is cast against the ground-truth
//! mesh (mapped into normalised space with the scene's `scale_mat`, a similarity without rotation,
//! so directions are unchanged); where it hits and the model's opacity is above 0.5, the angle
//! between the rendered normal (the weight-averaged SDF gradient direction, renormalised) and the
//! hit triangle's outward face normal is taken. The mean over those pixels, in degrees, measures
//! how bumpy or wrong the surface is where both agree there is one; silhouette disagreement is
//! left to Chamfer.

use crate::mesh::trace::Tracer;
use crate::mesh::TriMesh;
use crate::scene::{Normalization, RgbImage};
use glam::Vec3A;
use obvhs::triangle::Triangle;

/// The held-out normal picture of `width × height` pixels: each pixel's rendered normal
/// `n [3]` (unit, normalised space = world axes) mapped to colour as `0.5·n + 0.5`, composited
/// over the render background `bg` by the pixel's opacity `o`, `o·(0.5·n + 0.5) + (1 − o)·bg`,
/// as the RGB render is. Without the opacity the renormalised normal of a nearly empty pixel
/// (weights of 1e-3 across a hole) shows as full-strength noise, and an open hole looks closed.
pub fn normal_image(
    width: usize,
    height: usize,
    normals: &[[f32; 3]],
    opacity: &[f32],
    bg: [f32; 3],
) -> RgbImage {
    assert_eq!(normals.len(), opacity.len(), "one opacity per normal");
    assert_eq!(normals.len(), width * height, "one normal per pixel");
    let data = normals
        .iter()
        .zip(opacity)
        .flat_map(|(n, &o)| {
            let o = if o.is_finite() {
                o.clamp(0.0, 1.0)
            } else {
                0.0
            };
            std::array::from_fn::<f32, 3, _>(|k| o * (0.5 * n[k] + 0.5) + (1.0 - o) * bg[k])
        })
        .collect();
    RgbImage {
        width,
        height,
        data,
    }
}

/// A ground-truth mesh ready for normal queries (normalised space).
pub struct GtNormals {
    tracer: Tracer,
    /// Unit outward face normals, in the mesh's face order.
    normals: Vec<[f64; 3]>,
}

impl GtNormals {
    /// Builds the tracer from a mesh in world mm. `None` for a mesh without non-degenerate faces.
    pub fn new(world: &TriMesh, norm: &Normalization) -> Option<Self> {
        let to_n = |v: [f32; 3]| -> [f64; 3] {
            std::array::from_fn(|k| (v[k] as f64 - norm.center[k]) / norm.scale)
        };
        let mut tris = Vec::with_capacity(world.faces.len());
        let mut normals = Vec::with_capacity(world.faces.len());
        for f in &world.faces {
            let [a, b, c] = f.map(|i| to_n(world.vertices[i as usize]));
            let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let n = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if l.is_nan() || l <= 0.0 {
                continue;
            }
            let v = |p: [f64; 3]| Vec3A::new(p[0] as f32, p[1] as f32, p[2] as f32);
            tris.push(Triangle {
                v0: v(a),
                v1: v(b),
                v2: v(c),
            });
            normals.push(n.map(|x| x / l));
        }
        if tris.is_empty() {
            return None;
        }
        Some(Self {
            tracer: Tracer::new(&tris),
            normals,
        })
    }

    /// `(sum of angles in degrees, pixels)` over the rays that hit the mesh where `opacity > 0.5`
    /// and the rendered normal is non-zero. `origins`, `dirs`, `normals`, `opacity`: one per ray.
    pub fn angular_error(
        &self,
        origins: &[[f32; 3]],
        dirs: &[[f32; 3]],
        normals: &[[f32; 3]],
        opacity: &[f32],
    ) -> (f64, usize) {
        let mut sum = 0.0;
        let mut n = 0;
        for r in 0..origins.len() {
            if opacity[r] <= 0.5 {
                continue;
            }
            let o = Vec3A::from(origins[r]);
            let d = Vec3A::from(dirs[r]);
            let Some((face, _)) = self.tracer.closest(o, d) else {
                continue;
            };
            let m = normals[r].map(|x| x as f64);
            let ml = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
            if ml.is_nan() || ml <= 0.0 {
                continue;
            }
            let g = self.normals[face as usize];
            let c = ((m[0] * g[0] + m[1] * g[1] + m[2] * g[2]) / ml).clamp(-1.0, 1.0);
            sum += c.acos().to_degrees();
            n += 1;
        }
        (sum, n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_image_shows_the_background_where_nothing_is_opaque() {
        let up = [0.0, 0.0, 1.0];
        // Pixel 0: opaque; 1: empty (a hole: tiny weights, renormalised normal); 2: half; 3: NaN
        // opacity (treated as empty, never written as NaN).
        let img = normal_image(2, 2, &[up; 4], &[1.0, 0.0, 0.5, f32::NAN], [1.0, 1.0, 1.0]);
        assert_eq!(&img.data[0..3], &[0.5, 0.5, 1.0]);
        assert_eq!(&img.data[3..6], &[1.0, 1.0, 1.0]);
        assert_eq!(&img.data[6..9], &[0.75, 0.75, 1.0]);
        assert_eq!(&img.data[9..12], &[1.0, 1.0, 1.0]);
    }

    #[test]
    fn flat_square_gives_the_tilt_angle() {
        // A square at z = 0 facing +z, seen straight down; rendered normals tilted by 10° about x.
        let mesh = TriMesh {
            vertices: vec![
                [-1.0, -1.0, 0.0],
                [1.0, -1.0, 0.0],
                [1.0, 1.0, 0.0],
                [-1.0, 1.0, 0.0],
            ],
            faces: vec![[0, 1, 2], [0, 2, 3]],
        };
        let norm = Normalization {
            scale: 2.0,
            center: [0.0, 0.0, 0.0],
        };
        let g = GtNormals::new(&mesh, &norm).unwrap();
        let t = 10f32.to_radians();
        let origins = vec![[0.1, 0.1, 1.0], [0.2, -0.1, 1.0], [3.0, 3.0, 1.0]];
        let dirs = vec![[0.0, 0.0, -1.0]; 3];
        let normals = vec![[0.0, t.sin(), t.cos()]; 3];
        let (s, n) = g.angular_error(&origins, &dirs, &normals, &[1.0, 1.0, 1.0]);
        assert_eq!(n, 2, "the third ray misses the square");
        assert!((s / n as f64 - 10.0).abs() < 1e-3, "{}", s / n as f64);
        // Transparent pixels are left out.
        assert_eq!(g.angular_error(&origins, &dirs, &normals, &[0.2; 3]).1, 0);
    }
}
