//! Texture baking: each texel's surface point, the colour network's colour there, and a
//! dilation past the chart borders.
//!
//! Per texel centre `(x + ½, y + ½)` covered by a UV triangle (a top-left fill rule, so a texel
//! on an edge shared by two triangles belongs to exactly one): the barycentric coordinates of the
//! centre in that triangle give the surface point `Σ b_k·X_k` (world mm, then normalised), and
//! [`SurfaceField::shade`] its colour seen head-on (see [`super::colors`] for how this relates to
//! nerfstudio's ray from just outside along `−n`). A point whose query is not finite takes
//! mid-grey and is counted ([`BakedTexture::fallbacks`]).
//!
//! Then the charts grow by [`super::unwrap::padding_for`] texels (each empty texel next to a
//! filled one takes the mean of its filled 8-neighbours, ring by ring): bilinear filtering and
//! mipmaps at a chart's border then read the chart's colours, not the empty atlas (the seams
//! nerfstudio avoids with the same dilation). Texels no chart reaches take the mean colour.

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

use super::colors::SurfaceField;
use super::unwrap::{padding_for, UvMesh};
use super::{to_normalized, to_u8, ExportError};
use crate::scene::Normalization;
use std::time::Instant;

/// A baked square texture.
#[derive(Clone, Debug, PartialEq)]
pub struct BakedTexture {
    /// Side in texels.
    pub size: u32,
    /// `[size][size][3]` row-major (row 0 at the top, the image's first row), `[0, 1]`.
    pub rgb: Vec<[f32; 3]>,
    /// Texels inside some chart (queried).
    pub baked: usize,
    /// Texels filled by the dilation.
    pub dilated: usize,
    /// Baked texels whose query was not finite (mid-grey).
    pub fallbacks: usize,
    pub seconds: f64,
}

impl BakedTexture {
    /// The bilinear colour at texture coordinate `uv` (the [`UvMesh`] convention: `(0, 0)` the
    /// top-left corner), clamped to the edge.
    pub fn sample(&self, uv: [f32; 2]) -> [f32; 3] {
        let n = self.size as usize;
        let fx = (uv[0] * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
        let fy = (uv[1] * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(n - 1), (y0 + 1).min(n - 1));
        let (tx, ty) = (fx - x0 as f32, fy - y0 as f32);
        let at = |x: usize, y: usize| self.rgb[y * n + x];
        let (a, b, c, d) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
        [0, 1, 2].map(|k| {
            (a[k] * (1.0 - tx) + b[k] * tx) * (1.0 - ty) + (c[k] * (1.0 - tx) + d[k] * tx) * ty
        })
    }

    /// The texture as an 8-bit RGB PNG (what the OBJ's `map_Kd` names and the GLB embeds).
    pub fn png_bytes(&self) -> Result<Vec<u8>, ExportError> {
        use image::ImageEncoder;
        let bytes: Vec<u8> = self.rgb.iter().flat_map(|c| c.map(to_u8)).collect();
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(&bytes, self.size, self.size, image::ExtendedColorType::Rgb8)
            .map_err(|e| ExportError::Io {
                path: "texture (in memory)".into(),
                source: std::io::Error::other(e),
            })?;
        Ok(out)
    }
}

/// Calls `f(x, y, [b0, b1, b2])` for every texel `(x, y)` of a `w × h` grid whose centre lies in
/// the triangle `p` (texel units, any orientation), with the centre's barycentric coordinates.
/// Top-left rule: of two triangles sharing an edge, exactly one gets a centre on it. Degenerate
/// triangles cover nothing.
pub fn raster_triangle(
    p: [[f32; 2]; 3],
    w: usize,
    h: usize,
    mut f: impl FnMut(usize, usize, [f64; 3]),
) {
    let mut q = p.map(|v| [v[0] as f64, v[1] as f64]);
    let area = |q: &[[f64; 2]; 3]| {
        (q[1][0] - q[0][0]) * (q[2][1] - q[0][1]) - (q[1][1] - q[0][1]) * (q[2][0] - q[0][0])
    };
    let mut a = area(&q);
    let mut order = [0usize, 1, 2];
    if a < 0.0 {
        q.swap(1, 2);
        order.swap(1, 2);
        a = -a;
    }
    if a.is_nan() || a <= 0.0 || a.is_infinite() {
        return;
    }
    let lo = |k: usize| q.iter().map(|v| v[k]).fold(f64::INFINITY, f64::min);
    let hi = |k: usize| q.iter().map(|v| v[k]).fold(f64::NEG_INFINITY, f64::max);
    let x0 = (lo(0) - 0.5).ceil().max(0.0) as usize;
    let y0 = (lo(1) - 0.5).ceil().max(0.0) as usize;
    let x1 = ((hi(0) - 0.5).floor() as i64).min(w as i64 - 1);
    let y1 = ((hi(1) - 0.5).floor() as i64).min(h as i64 - 1);
    if x1 < x0 as i64 || y1 < y0 as i64 {
        return;
    }
    // Edge k runs from vertex k+1 to k+2; its function is positive inside (positive area).
    let edge = |k: usize, x: f64, y: f64| {
        let (a, b) = (q[(k + 1) % 3], q[(k + 2) % 3]);
        (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0])
    };
    let top_left = |k: usize| {
        let (a, b) = (q[(k + 1) % 3], q[(k + 2) % 3]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        dy < 0.0 || (dy == 0.0 && dx > 0.0)
    };
    let tl = [top_left(0), top_left(1), top_left(2)];
    for y in y0..=y1 as usize {
        let cy = y as f64 + 0.5;
        for x in x0..=x1 as usize {
            let cx = x as f64 + 0.5;
            let e = [edge(0, cx, cy), edge(1, cx, cy), edge(2, cx, cy)];
            if (0..3).all(|k| e[k] > 0.0 || (e[k] == 0.0 && tl[k])) {
                let mut b = [0.0; 3];
                for k in 0..3 {
                    b[order[k]] = e[k] / a;
                }
                f(x, y, b);
            }
        }
    }
}

/// Bakes a `size × size` texture of `uv`'s mesh from the field (world mm → normalised with
/// `norm`). Deterministic: triangles in order, the field query's fixed chunks.
pub fn bake_texture(
    field: &SurfaceField,
    uv: &UvMesh,
    norm: &Normalization,
    size: u32,
) -> BakedTexture {
    let t0 = Instant::now();
    let n = size as usize;
    // Texel → (face, barycentric) of the first triangle that covers its centre.
    let mut owner: Vec<u32> = vec![u32::MAX; n * n];
    let mut texels: Vec<usize> = Vec::new();
    let mut points: Vec<[f32; 3]> = Vec::new();
    let mut fallback: Vec<[f32; 3]> = Vec::new();
    for (fi, (t, f)) in uv.uv_faces.iter().zip(&uv.faces).enumerate() {
        let p = t.map(|i| uv.uv[i as usize].map(|c| c * size as f32));
        let x = f.map(|i| uv.positions[i as usize].map(|v| v as f64));
        let nr = f.map(|i| uv.normals[i as usize]);
        raster_triangle(p, n, n, |tx, ty, b| {
            let k = ty * n + tx;
            if owner[k] != u32::MAX {
                return;
            }
            owner[k] = fi as u32;
            texels.push(k);
            points
                .push([0, 1, 2].map(|a| (b[0] * x[0][a] + b[1] * x[1][a] + b[2] * x[2][a]) as f32));
            let m = [0, 1, 2].map(|a| {
                (b[0] * nr[0][a] as f64 + b[1] * nr[1][a] as f64 + b[2] * nr[2][a] as f64) as f32
            });
            let l = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
            fallback.push(if l > 1e-12 {
                m.map(|v| v / l)
            } else {
                [0.0, 0.0, 1.0]
            });
        });
    }
    let shaded = field.shade(&to_normalized(&points, norm), &fallback);
    let mut rgb = vec![[0f32; 3]; n * n];
    let mut filled = vec![false; n * n];
    for (&k, c) in texels.iter().zip(&shaded.rgb) {
        rgb[k] = *c;
        filled[k] = true;
    }
    let dilated = dilate(&mut rgb, &mut filled, n, padding_for(size) as usize);
    // The rest of the atlas: the mean colour (mipmaps then blend towards the object's colour).
    let mut mean = [0f64; 3];
    for c in &shaded.rgb {
        for k in 0..3 {
            mean[k] += c[k] as f64;
        }
    }
    let mean = mean.map(|v| (v / shaded.rgb.len().max(1) as f64) as f32);
    for (c, &f) in rgb.iter_mut().zip(&filled) {
        if !f {
            *c = mean;
        }
    }
    BakedTexture {
        size,
        rgb,
        baked: texels.len(),
        dilated,
        fallbacks: shaded.fallbacks,
        seconds: t0.elapsed().as_secs_f64(),
    }
}

/// Grows the filled region by `rings` texels: each empty texel with a filled 8-neighbour takes
/// their mean (all of a ring decided from the previous ring). Returns the texels filled.
pub fn dilate(rgb: &mut [[f32; 3]], filled: &mut [bool], n: usize, rings: usize) -> usize {
    let mut total = 0;
    for _ in 0..rings {
        let mut add: Vec<(usize, [f32; 3])> = Vec::new();
        for y in 0..n {
            for x in 0..n {
                if filled[y * n + x] {
                    continue;
                }
                let (mut s, mut c) = ([0f32; 3], 0u32);
                for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                        if (dx, dy) == (0, 0)
                            || xx < 0
                            || yy < 0
                            || xx >= n as i64
                            || yy >= n as i64
                        {
                            continue;
                        }
                        let k = yy as usize * n + xx as usize;
                        if filled[k] {
                            for a in 0..3 {
                                s[a] += rgb[k][a];
                            }
                            c += 1;
                        }
                    }
                }
                if c > 0 {
                    add.push((y * n + x, s.map(|v| v / c as f32)));
                }
            }
        }
        if add.is_empty() {
            break;
        }
        total += add.len();
        for (k, c) in add {
            rgb[k] = c;
            filled[k] = true;
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles of a square cover each texel centre inside it exactly once (top-left rule on
    /// the shared diagonal, through texel centres), and the barycentric coordinates reproduce
    /// the centre.
    #[test]
    fn raster_covers_a_square_exactly_once() {
        let (a, b, c, d) = ([1.0, 1.0], [9.0, 1.0], [9.0, 9.0], [1.0, 9.0]);
        let mut hits = [0u8; 100];
        for t in [[a, b, c], [a, d, c]] {
            raster_triangle(t, 10, 10, |x, y, bc| {
                hits[y * 10 + x] += 1;
                let px: f64 = (0..3).map(|k| bc[k] * t[k][0] as f64).sum();
                let py: f64 = (0..3).map(|k| bc[k] * t[k][1] as f64).sum();
                assert!(
                    (px - (x as f64 + 0.5)).abs() < 1e-9 && (py - (y as f64 + 0.5)).abs() < 1e-9
                );
            });
        }
        for y in 0..10 {
            for x in 0..10 {
                let inside = (1..9).contains(&x) && (1..9).contains(&y);
                assert_eq!(hits[y * 10 + x], inside as u8, "texel {x},{y}");
            }
        }
    }

    #[test]
    fn dilation_grows_by_rings_and_averages_neighbours() {
        let n = 7;
        let mut rgb = vec![[0f32; 3]; n * n];
        let mut filled = vec![false; n * n];
        rgb[3 * n + 3] = [1.0, 0.5, 0.0];
        filled[3 * n + 3] = true;
        let added = dilate(&mut rgb, &mut filled, n, 2);
        assert_eq!(added, 8 + 16);
        assert_eq!(filled.iter().filter(|&&f| f).count(), 25);
        assert!(!filled[0] && filled[n + 1]);
        assert!(rgb
            .iter()
            .zip(&filled)
            .all(|(c, &f)| !f || *c == [1.0, 0.5, 0.0]));
    }

    #[test]
    fn bilinear_sampling_hits_texel_centres() {
        let t = BakedTexture {
            size: 2,
            rgb: vec![[0.0; 3], [1.0; 3], [0.0; 3], [1.0; 3]],
            baked: 4,
            dilated: 0,
            fallbacks: 0,
            seconds: 0.0,
        };
        assert_eq!(t.sample([0.25, 0.25]), [0.0; 3]);
        assert_eq!(t.sample([0.75, 0.75]), [1.0; 3]);
        assert_eq!(t.sample([0.5, 0.5]), [0.5; 3]);
        assert_eq!(t.sample([-1.0, 2.0]), [0.0; 3], "clamped to the edge");
    }
}
