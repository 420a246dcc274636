//! Renders an exported mesh: closest-hit ray casting on an `obvhs` wide BVH, unlit (the colours
//! already hold the training images' shading), colour from the vertex colours or the baked
//! texture, and the interpolated vertex normal as a normal map (`0.5·n + 0.5`, world frame, as
//! the held-out normal renders show it). One ray per pixel centre ([`camera_rays`]); a ray that
//! hits nothing shows the background.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::bake::BakedTexture;
use super::unwrap::UvMesh;
use super::{ColoredMesh, TexturedMesh};
use crate::scene::{Camera, RgbImage};
use crate::train::data::camera_rays;
use glam::Vec3A;
use obvhs::cwbvh::{builder::build_cwbvh_from_tris, CwBvh};
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;
use rayon::prelude::*;
use std::time::Duration;

/// Where a mesh's colour comes from.
enum Shading<'a> {
    /// `[n_vertices][3]` 8-bit colours, interpolated.
    Vertex(&'a [[u8; 3]]),
    /// The baked texture at the interpolated texture coordinate.
    Texture(&'a UvMesh, &'a BakedTexture),
}

/// A mesh ready to render (world frame, the cameras' units).
pub struct MeshScene<'a> {
    positions: &'a [[f32; 3]],
    faces: &'a [[u32; 3]],
    normals: &'a [[f32; 3]],
    shading: Shading<'a>,
    bvh: CwBvh,
    /// Triangles in the BVH's primitive order.
    tris: Vec<Triangle>,
}

/// A rendered view.
#[derive(Clone, Debug)]
pub struct MeshRender {
    pub rgb: RgbImage,
    /// Normals as colours (`0.5·n + 0.5`), background where nothing is hit.
    pub normal: RgbImage,
    /// `[h·w]` whether some ray of the pixel hit the mesh.
    pub hit: Vec<bool>,
    /// Rays per pixel (`ss²`).
    pub samples: usize,
    /// `[h·w·samples]` unit ray directions, pixel by pixel.
    pub dirs: Vec<[f32; 3]>,
    /// `[h·w·samples]` each ray's hit point (the mesh's frame) and interpolated unit normal.
    pub surface: Vec<Option<([f32; 3], [f32; 3])>>,
}

impl<'a> MeshScene<'a> {
    fn new(
        positions: &'a [[f32; 3]],
        faces: &'a [[u32; 3]],
        normals: &'a [[f32; 3]],
        shading: Shading<'a>,
    ) -> Self {
        let v = |i: u32| Vec3A::from(positions[i as usize]);
        let tris: Vec<Triangle> = faces
            .iter()
            .map(|f| Triangle {
                v0: v(f[0]),
                v1: v(f[1]),
                v2: v(f[2]),
            })
            .collect();
        let bvh = build_cwbvh_from_tris(
            &tris,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        let tris = bvh
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize])
            .collect();
        Self {
            positions,
            faces,
            normals,
            shading,
            bvh,
            tris,
        }
    }

    /// The vertex-coloured mesh.
    pub fn vertex_colored(m: &'a ColoredMesh) -> Self {
        Self::new(
            &m.mesh.vertices,
            &m.mesh.faces,
            &m.normals,
            Shading::Vertex(&m.colors),
        )
    }

    /// The textured mesh.
    pub fn textured(t: &'a TexturedMesh) -> Self {
        Self::new(
            &t.uv.positions,
            &t.uv.faces,
            &t.uv.normals,
            Shading::Texture(&t.uv, &t.texture),
        )
    }

    /// The closest hit: `(face, barycentric)`.
    fn closest(&self, o: [f32; 3], d: [f32; 3]) -> Option<(usize, [f32; 3])> {
        let ray = Ray::new(Vec3A::from(o), Vec3A::from(d), 0.0, f32::INFINITY);
        let mut hit = RayHit::none();
        if !self
            .bvh
            .ray_traverse(ray, &mut hit, |r, id| self.tris[id].intersect(r))
        {
            return None;
        }
        let face = self.bvh.primitive_indices[hit.primitive_id as usize] as usize;
        let p = [0, 1, 2].map(|a| o[a] as f64 + d[a] as f64 * hit.t as f64);
        Some((face, self.barycentric(face, p)))
    }

    /// Barycentric coordinates of `p` (on or near the plane of `face`), clamped to the triangle.
    fn barycentric(&self, face: usize, p: [f64; 3]) -> [f32; 3] {
        let x = self.faces[face].map(|i| self.positions[i as usize].map(|v| v as f64));
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let (e1, e2, q) = (sub(x[1], x[0]), sub(x[2], x[0]), sub(p, x[0]));
        let (d11, d12, d22) = (dot(e1, e1), dot(e1, e2), dot(e2, e2));
        let (q1, q2) = (dot(q, e1), dot(q, e2));
        let den = d11 * d22 - d12 * d12;
        if den.is_nan() || den <= 0.0 {
            return [1.0, 0.0, 0.0];
        }
        let b1 = ((d22 * q1 - d12 * q2) / den).clamp(0.0, 1.0);
        let b2 = ((d11 * q2 - d12 * q1) / den).clamp(0.0, 1.0 - b1);
        [(1.0 - b1 - b2) as f32, b1 as f32, b2 as f32]
    }

    /// Colour and unit normal at a hit.
    fn shade(&self, face: usize, b: [f32; 3]) -> ([f32; 3], [f32; 3]) {
        let f = self.faces[face];
        let mix3 =
            |v: [[f32; 3]; 3]| [0, 1, 2].map(|a| b[0] * v[0][a] + b[1] * v[1][a] + b[2] * v[2][a]);
        let n = mix3(f.map(|i| self.normals[i as usize]));
        let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let n = if l > 1e-12 { n.map(|v| v / l) } else { n };
        let c = match &self.shading {
            Shading::Vertex(c) => mix3(f.map(|i| c[i as usize].map(|v| v as f32 / 255.0))),
            Shading::Texture(uv, tex) => {
                let t = uv.uv_faces[face].map(|i| uv.uv[i as usize]);
                let st = [0, 1].map(|a| b[0] * t[0][a] + b[1] * t[1][a] + b[2] * t[2][a]);
                tex.sample(st)
            }
        };
        (c, n)
    }

    /// Renders `cam` (the mesh's frame and units) on `background`, one ray per pixel centre.
    pub fn render(&self, cam: &Camera, background: [f32; 3]) -> MeshRender {
        self.render_aa(cam, background, 1)
    }

    /// Renders with `ss × ss` rays per pixel on a regular sub-pixel grid (`(x + (i + ½)/ss,
    /// y + (j + ½)/ss)`), averaged: the silhouette then covers its pixels by area, as the
    /// anti-aliased truth images and the network's soft opacity do. `ss = 1` is the pixel
    /// centre of [`camera_rays`].
    pub fn render_aa(&self, cam: &Camera, background: [f32; 3], ss: u32) -> MeshRender {
        let (w, h) = (cam.width as usize, cam.height as usize);
        let ss = ss.max(1) as usize;
        let k = ss * ss;
        let (origins, dirs) = if ss == 1 {
            camera_rays(cam)
        } else {
            let mut o = Vec::with_capacity(w * h * k);
            let mut d = Vec::with_capacity(w * h * k);
            for y in 0..h {
                for x in 0..w {
                    for j in 0..ss {
                        for i in 0..ss {
                            let u = x as f64 + (i as f64 + 0.5) / ss as f64;
                            let v = y as f64 + (j as f64 + 0.5) / ss as f64;
                            let (c, r) = cam.ray(u, v);
                            o.push([c.x as f32, c.y as f32, c.z as f32]);
                            d.push([r.x as f32, r.y as f32, r.z as f32]);
                        }
                    }
                }
            }
            (o, d)
        };
        type Px = ([f32; 3], [f32; 3], Option<([f32; 3], [f32; 3])>);
        let px: Vec<Px> = origins
            .par_iter()
            .zip(dirs.par_iter())
            .map(|(o, d)| match self.closest(*o, *d) {
                Some((face, b)) => {
                    let (c, n) = self.shade(face, b);
                    let x = self.faces[face].map(|i| self.positions[i as usize]);
                    let p = [0, 1, 2].map(|a| b[0] * x[0][a] + b[1] * x[1][a] + b[2] * x[2][a]);
                    (c, n.map(|v| 0.5 * v + 0.5), Some((p, n)))
                }
                None => (background, background, None),
            })
            .collect();
        let resolve = |f: &dyn Fn(&Px) -> [f32; 3]| -> Vec<f32> {
            px.chunks_exact(k)
                .flat_map(|s| {
                    let mut a = [0f32; 3];
                    for p in s {
                        let c = f(p);
                        for ch in 0..3 {
                            a[ch] += c[ch];
                        }
                    }
                    a.map(|v| v / k as f32)
                })
                .collect()
        };
        MeshRender {
            rgb: RgbImage {
                width: w,
                height: h,
                data: resolve(&|p| p.0),
            },
            normal: RgbImage {
                width: w,
                height: h,
                data: resolve(&|p| p.1),
            },
            hit: px
                .chunks_exact(k)
                .map(|s| s.iter().any(|p| p.2.is_some()))
                .collect(),
            samples: k,
            dirs,
            surface: px.iter().map(|p| p.2).collect(),
        }
    }
}

impl MeshRender {
    /// The colour image with each hit sample's colour replaced by `colors` (one per `Some` of
    /// `surface`, in order) and misses showing `background`, averaged per pixel.
    pub fn recolored(&self, colors: &[[f32; 3]], background: [f32; 3]) -> RgbImage {
        let mut it = colors.iter();
        let k = self.samples;
        let per: Vec<[f32; 3]> = self
            .surface
            .iter()
            .map(|s| match s {
                Some(_) => *it.next().expect("one colour per hit"),
                None => background,
            })
            .collect();
        let data = per
            .chunks_exact(k)
            .flat_map(|s| {
                let mut a = [0f32; 3];
                for c in s {
                    for ch in 0..3 {
                        a[ch] += c[ch];
                    }
                }
                a.map(|v| v / k as f32)
            })
            .collect();
        RgbImage {
            width: self.rgb.width,
            height: self.rgb.height,
            data,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dtu_eval::mesh::TriMesh;
    use nalgebra::{Matrix3, Vector3};

    /// A red/blue quad facing a camera: the pixel colours interpolate the vertex colours, the
    /// background shows around it, and the normal map shows +z as (0.5, 0.5, 1).
    #[test]
    fn a_quad_renders_its_colours_and_normal() {
        let mesh = TriMesh {
            vertices: vec![
                [-1.0, -1.0, 0.0],
                [1.0, -1.0, 0.0],
                [1.0, 1.0, 0.0],
                [-1.0, 1.0, 0.0],
            ],
            faces: vec![[0, 1, 2], [0, 2, 3]],
        };
        let m = ColoredMesh {
            normals: vec![[0.0, 0.0, 1.0]; 4],
            colors: vec![[255, 0, 0], [0, 0, 255], [0, 0, 255], [255, 0, 0]],
            mesh,
            fallbacks: 0,
        };
        // Looking down −z from z = 4: x right, y down in the image → world y points down.
        let cam = Camera {
            k: Matrix3::new(20.0, 0.0, 16.0, 0.0, 20.0, 16.0, 0.0, 0.0, 1.0),
            r: Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0),
            center: Vector3::new(0.0, 0.0, 4.0),
            width: 32,
            height: 32,
        };
        let s = MeshScene::vertex_colored(&m);
        let r = s.render(&cam, [0.0, 1.0, 0.0]);
        assert_eq!(r.rgb.get(0, 0), [0.0, 1.0, 0.0], "background");
        assert!(!r.hit[0] && r.hit[16 * 32 + 16]);
        // The quad covers pixels 11..=20 (focal 20, half-width 1 at distance 4): left red, right
        // blue, the middle a mix.
        let (l, c, rr) = (r.rgb.get(12, 16), r.rgb.get(16, 16), r.rgb.get(20, 16));
        assert!(l[0] > 0.8 && l[2] < 0.2, "{l:?}");
        assert!(rr[2] > 0.8 && rr[0] < 0.2, "{rr:?}");
        assert!(
            (c[0] - 0.5).abs() < 0.1 && (c[2] - 0.5).abs() < 0.1,
            "{c:?}"
        );
        assert_eq!(r.normal.get(16, 16), [0.5, 0.5, 1.0]);
    }
}
