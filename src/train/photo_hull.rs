//! Photo-consistent carving of the visual hull (`[train.init] photo_tau`, issue 13).
//!
//! The masks' visual hull ([`super::hull::carve`]) cannot see into a concavity: a cup's opening
//! is inside every silhouette, so the hull (and the sphere start, and NeuS training from either)
//! keeps a lid over it, which the colour network then paints with what lies behind it. The lid
//! is a local minimum of the photometric loss: the samples under it get no colour gradient while
//! the lid is opaque, so nothing pulls it down (issue 13, `cup`: 4.8–5.6 mm against a 0.23 mm
//! floor with every start and knob tried; results/geometry/knobs-2026-11-25).
//!
//! This module carves the hull further with the images' colours, the space carving of Kutulakos
//! & Seitz ("A Theory of Shape by Space Carving", IJCV 2000, §4–5; Seitz & Dyer's voxel colouring
//! with visibility, IJCV 1999). Under Lambertian light a voxel on the true surface looks the same
//! from every view that sees it; a voxel in front of the surface (a lid) shows each view a
//! different point behind it:
//! 1. Every masked pixel of every training view casts a ray through the `res³` grid (the hull's,
//!    over `[-r, r]³`, normalised space); its first occupied voxel, found by a 3-D DDA (Amanatides
//!    & Woo, "A Fast Voxel Traversal Algorithm for Ray Tracing", Eurographics 1987), is the voxel
//!    that pixel sees.
//! 2. Per voxel, the pixels of each view that see it are averaged (a voxel covers a few pixels);
//!    the voxel is consistent when at least half of those per-view means lie within `tau` of
//!    their per-channel median in every channel (RGB in `[0, 1]`). A majority vote rather
//!    than a spread: a voxel on the surface next to an occluding contour is also hit by a few
//!    grazing rays that see something behind it, and a spread would carve it (then the voxel
//!    behind it, and so on into the object); the majority of its views still agree.
//! 3. A voxel that at least `min_views` views see and that is not consistent is carved. The rays that saw
//!    it walk on to the next occupied voxel, and 2–3 repeat until nothing is carved (or
//!    `max_iterations`). Only voxels some view sees can be carved, so unseen space stays full.
//!
//! The result is never larger than the visual hull, and where the images do not say (a uniform
//! or dark region, fewer than `min_views` views) nothing is carved. It can carve too much: parts
//! thinner than a voxel are seen by few pixels, are voted away, and the rays that saw them then
//! vote against the surface behind (`thin` at `tau` 0.07 loses 14 % of the voxels more than one
//! voxel inside the object; `cup` 0.6 %), and view-dependent light (highlights) does the same.
//! So it is off by default (`photo_tau = 0`): on `cup` it removes the lid (the init's seen
//! hull no longer closes the opening) but the Chamfer does not improve at the `fast` preset
//! (results/geometry/photo-hull-2026-11-25).

use crate::scene::{Camera, GrayImage, RgbImage};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// The carve's knobs (`[train.init]`: `photo_tau`, `photo_min_views`, `photo_max_iterations`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhotoCarveParams {
    /// Colour tolerance (RGB in `[0, 1]`, per channel) of the majority vote (module docs).
    pub tau: f32,
    /// Views that must see a voxel before it is judged (at least 2).
    pub min_views: usize,
    /// Carve passes at most (each removes at most one layer along every ray).
    pub max_iterations: usize,
}

/// What a carve did.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PhotoCarveReport {
    /// Voxels inside before and after.
    pub inside_before: usize,
    pub inside_after: usize,
    /// Passes run, and whether the last one carved nothing.
    pub iterations: usize,
    pub converged: bool,
    /// Rays cast (masked pixels of the views).
    pub rays: usize,
    /// Wall time (s).
    pub seconds: f64,
}

impl PhotoCarveReport {
    /// Share of the visual hull's voxels that the carve removed (0 for an empty hull).
    pub fn carved_share(&self) -> f64 {
        if self.inside_before == 0 {
            0.0
        } else {
            (self.inside_before - self.inside_after) as f64 / self.inside_before as f64
        }
    }
}

/// One pixel's ray in normalised space (f32 is ample for a 512³ grid over a unit box).
struct Ray {
    o: [f32; 3],
    d: [f32; 3],
    t_end: f32,
    view: u32,
    rgb: [f32; 3],
}

/// Entry and exit of `o + t·d` through the box `[-r, r]³`, clipped to `t ≥ 0`
/// ([`super::unseen::box_interval`], in f32).
fn box_span(o: [f32; 3], d: [f32; 3], r: f32) -> Option<(f32, f32)> {
    super::unseen::box_interval(o.map(f64::from), d.map(f64::from), f64::from(r))
        .map(|(t0, t1)| (t0 as f32, t1 as f32))
}

/// The first voxel with `inside` set that the ray crosses at or after `t_start`, and the ray
/// parameter where it enters that voxel (3-D DDA, Amanatides & Woo 1987). Index
/// `(k·res + j)·res + i`, as [`super::hull::carve`] lays the grid out.
fn first_hit(inside: &[bool], res: usize, r: f32, ray: &Ray, t_start: f32) -> Option<(u32, f32)> {
    let h = 2.0 * r / res as f32;
    let mut cell = [0i64; 3];
    let mut t_max = [f32::INFINITY; 3];
    let mut t_delta = [f32::INFINITY; 3];
    let mut step = [0i64; 3];
    for a in 0..3 {
        let p = ray.o[a] + ray.d[a] * t_start;
        let c = (((p + r) / h).floor() as i64).clamp(0, res as i64 - 1);
        cell[a] = c;
        if ray.d[a] > 0.0 {
            step[a] = 1;
            t_max[a] = (-r + (c + 1) as f32 * h - ray.o[a]) / ray.d[a];
            t_delta[a] = h / ray.d[a];
        } else if ray.d[a] < 0.0 {
            step[a] = -1;
            t_max[a] = (-r + c as f32 * h - ray.o[a]) / ray.d[a];
            t_delta[a] = -h / ray.d[a];
        }
    }
    let mut t = t_start;
    loop {
        let idx = ((cell[2] as usize * res) + cell[1] as usize) * res + cell[0] as usize;
        if inside[idx] {
            return Some((idx as u32, t));
        }
        let a = if t_max[0] <= t_max[1] && t_max[0] <= t_max[2] {
            0
        } else if t_max[1] <= t_max[2] {
            1
        } else {
            2
        };
        t = t_max[a];
        if t > ray.t_end {
            return None;
        }
        cell[a] += step[a];
        if cell[a] < 0 || cell[a] >= res as i64 {
            return None;
        }
        t_max[a] += t_delta[a];
    }
}

/// Whether at least half of the per-view colours `means` lie within `tau` of their per-channel
/// median in every channel (module docs, step 2).
fn agrees(means: &[[f64; 3]], tau: f32) -> bool {
    let n = means.len();
    let mut ch = vec![0.0f64; n];
    let median: [f64; 3] = std::array::from_fn(|c| {
        for (x, m) in ch.iter_mut().zip(means) {
            *x = m[c];
        }
        ch.sort_unstable_by(f64::total_cmp);
        if n % 2 == 1 {
            ch[n / 2]
        } else {
            0.5 * (ch[n / 2 - 1] + ch[n / 2])
        }
    });
    let close = means
        .iter()
        .filter(|m| (0..3).all(|c| (m[c] - median[c]).abs() <= tau as f64))
        .count();
    2 * close >= n
}

/// The voxels to carve this pass: those that `min_views` views see and that fail the vote
/// (module docs, step 2). `seen` pairs each hitting ray's `(voxel, view)` key with its colour.
fn inconsistent(seen: &mut [(u64, [f32; 3])], p: &PhotoCarveParams) -> Vec<u32> {
    seen.par_sort_unstable_by_key(|e| e.0);
    let mut out = Vec::new();
    let mut means: Vec<[f64; 3]> = Vec::new();
    let mut i = 0;
    while i < seen.len() {
        let voxel = seen[i].0 >> 32;
        means.clear();
        while i < seen.len() && seen[i].0 >> 32 == voxel {
            let view = seen[i].0;
            let (mut sum, mut n) = ([0.0f64; 3], 0usize);
            while i < seen.len() && seen[i].0 == view {
                for (s, c) in sum.iter_mut().zip(seen[i].1) {
                    *s += c as f64;
                }
                n += 1;
                i += 1;
            }
            means.push(sum.map(|s| s / n as f64));
        }
        if means.len() >= p.min_views && !agrees(&means, p.tau) {
            out.push(voxel as u32);
        }
    }
    out
}

/// Carves `inside` (a `res³` grid over `[-radius, radius]³`, normalised space, laid out as
/// [`super::hull::carve`] returns it) by photo-consistency (module docs). `views` are the
/// training views: camera (normalised space), RGB in `[0, 1]`, and the mask (object `> 0.5`)
/// whose pixels cast rays; a view without a mask casts every pixel. Deterministic: the result
/// does not depend on the thread count.
pub fn photo_carve(
    views: &[(&Camera, &RgbImage, Option<&GrayImage>)],
    inside: &mut [bool],
    res: usize,
    radius: f32,
    p: &PhotoCarveParams,
) -> PhotoCarveReport {
    assert_eq!(inside.len(), res * res * res, "grid size");
    let t_start = std::time::Instant::now();
    let inside_before = inside.iter().filter(|&&b| b).count();
    let rays: Vec<Ray> = views
        .par_iter()
        .enumerate()
        .flat_map_iter(|(vi, (cam, img, mask))| {
            let (w, hgt) = (img.width, img.height);
            (0..w * hgt).filter_map(move |px| {
                let (x, y) = (px % w, px / w);
                if mask.is_some_and(|m| m.data[px] <= 0.5) {
                    return None;
                }
                let (o, d) = cam.ray(x as f64 + 0.5, y as f64 + 0.5);
                let (o, d) = (o.map(|v| v as f32), d.map(|v| v as f32));
                let (o, d) = ([o.x, o.y, o.z], [d.x, d.y, d.z]);
                let (t0, t1) = box_span(o, d, radius)?;
                // Start the ray at the box entry, so the DDA's first cell is on the box.
                let o = std::array::from_fn(|a| o[a] + d[a] * t0);
                Some(Ray {
                    o,
                    d,
                    t_end: t1 - t0,
                    view: vi as u32,
                    rgb: img.get(x, y),
                })
            })
        })
        .collect();
    let mut hits: Vec<Option<(u32, f32)>> = rays
        .par_iter()
        .map(|ray| first_hit(inside, res, radius, ray, 0.0))
        .collect();
    let mut report = PhotoCarveReport {
        inside_before,
        rays: rays.len(),
        ..Default::default()
    };
    while report.iterations < p.max_iterations {
        report.iterations += 1;
        let mut seen: Vec<(u64, [f32; 3])> = hits
            .par_iter()
            .zip(&rays)
            .filter_map(|(h, ray)| h.map(|(v, _)| (((v as u64) << 32) | ray.view as u64, ray.rgb)))
            .collect();
        let carve = inconsistent(&mut seen, p);
        if carve.is_empty() {
            report.converged = true;
            break;
        }
        for v in carve {
            inside[v as usize] = false;
        }
        let grid: &[bool] = inside;
        hits.par_iter_mut().zip(&rays).for_each(|(h, ray)| {
            if let Some((v, t)) = *h {
                if !grid[v as usize] {
                    *h = first_hit(grid, res, radius, ray, t);
                }
            }
        });
    }
    report.inside_after = inside.iter().filter(|&&b| b).count();
    report.seconds = t_start.elapsed().as_secs_f64();
    report
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};

    fn camera_at(eye: [f64; 3], size: u32) -> Camera {
        let f = size as f64 / 2.0 / (25f64.to_radians()).tan();
        let c = size as f64 / 2.0;
        crate::sim::rig::look_at(
            Vector3::from(eye),
            Vector3::zeros(),
            Vector3::new(0.0, 0.0, 1.0),
            Matrix3::new(f, 0.0, c, 0.0, f, c, 0.0, 0.0, 1.0),
            size,
            size,
        )
    }

    /// A view-independent albedo on the sphere: smooth stripes in three directions.
    fn albedo(x: Vector3<f64>) -> [f32; 3] {
        let s = |a: f64| (0.5 + 0.4 * (a * 4.0).sin()) as f32;
        [s(x.x + 0.3 * x.z), s(x.y - 0.2 * x.x), s(x.z + 0.5 * x.y)]
    }

    /// Renders a textured sphere of radius `rs` at the origin (exact ray-sphere intersection),
    /// white outside, with its mask; `noise_seed` adds per-view independent noise of amplitude
    /// `noise` (view-dependent appearance).
    fn render(cam: &Camera, rs: f64, noise: f32, noise_seed: u64) -> (RgbImage, GrayImage) {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(noise_seed);
        let n = cam.width as usize;
        let mut img = RgbImage::new(n, n);
        let mut mask = GrayImage::new(n, n);
        for y in 0..n {
            for x in 0..n {
                let (o, d) = cam.ray(x as f64 + 0.5, y as f64 + 0.5);
                let b = o.dot(&d);
                let disc = b * b - (o.norm_squared() - rs * rs);
                let e: f32 = rng.random_range(-1.0..1.0) * noise;
                if disc > 0.0 {
                    let t = -b - disc.sqrt();
                    let rgb = albedo(o + d * t).map(|c| (c + e).clamp(0.0, 1.0));
                    img.set(x, y, rgb);
                    mask.data[y * n + x] = 1.0;
                } else {
                    img.set(x, y, [1.0; 3]);
                }
            }
        }
        (img, mask)
    }

    fn centre(idx: usize, res: usize, r: f64) -> Vector3<f64> {
        let h = 2.0 * r / res as f64;
        let c = |i: usize| -r + (i as f64 + 0.5) * h;
        Vector3::new(c(idx % res), c((idx / res) % res), c(idx / (res * res)))
    }

    fn ring(n: usize) -> Vec<Camera> {
        (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                let el = if i % 2 == 0 { 0.5 } else { -0.3 };
                camera_at([3.0 * a.cos(), 3.0 * a.sin(), 3.0 * el], 96)
            })
            .collect()
    }

    /// The DDA's first hit is the occupied voxel whose cube the ray enters first, found by brute
    /// force (a slab test against every occupied voxel), on a random grid.
    #[test]
    fn dda_first_hit_matches_dense_sampling() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
        let (res, r) = (12usize, 1.0f32);
        let inside: Vec<bool> = (0..res * res * res)
            .map(|_| rng.random_bool(0.08))
            .collect();
        let h = 2.0 * r / res as f32;
        let mut checked = 0;
        for _ in 0..2000 {
            let o = [0; 3].map(|_| rng.random_range(-3.0f32..3.0));
            let d = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0f32),
            )
            .normalize();
            let d = [d.x, d.y, d.z];
            let Some((t0, t1)) = box_span(o, d, r) else {
                continue;
            };
            let o = std::array::from_fn(|a| o[a] + d[a] * t0);
            let ray = Ray {
                o,
                d,
                t_end: t1 - t0,
                view: 0,
                rgb: [0.0; 3],
            };
            // Brute force: the occupied voxel whose cube the ray enters first (slab test).
            let mut best: Option<(u32, f32)> = None;
            for (idx, _) in inside.iter().enumerate().filter(|(_, &b)| b) {
                let lo =
                    [idx % res, (idx / res) % res, idx / (res * res)].map(|c| -r + c as f32 * h);
                let (mut t0, mut t1) = (0.0f32, ray.t_end);
                for a in 0..3 {
                    if d[a] == 0.0 {
                        if o[a] < lo[a] || o[a] > lo[a] + h {
                            t1 = -1.0;
                        }
                        continue;
                    }
                    let (ta, tb) = ((lo[a] - o[a]) / d[a], (lo[a] + h - o[a]) / d[a]);
                    t0 = t0.max(ta.min(tb));
                    t1 = t1.min(ta.max(tb));
                }
                if t0 < t1 && best.is_none_or(|(_, t)| t0 < t) {
                    best = Some((idx as u32, t0));
                }
            }
            let dda = first_hit(&inside, res, r, &ray, 0.0);
            match (dda, best) {
                (Some((v, t)), Some((w, tw))) => {
                    // Equal, or a tie where the ray crosses an edge or corner.
                    assert!(v == w || (t - tw).abs() < 1e-5, "ray {o:?} {d:?}: {v} {w}");
                    checked += 1;
                }
                (None, None) => {}
                other => panic!("ray {o:?} {d:?}: DDA and brute force disagree: {other:?}"),
            }
        }
        assert!(checked > 100, "only {checked} rays hit the grid");
    }

    /// A textured sphere inside a loose hull (a ball 1.5 times its radius): the carve removes the
    /// seen space around the sphere and keeps the sphere (no voxel deeper than two voxels inside
    /// it is carved).
    #[test]
    fn carves_a_cube_down_to_a_textured_sphere() {
        let (res, r, rs) = (32usize, 1.0f32, 0.6f64);
        let cams = ring(24);
        let rendered: Vec<_> = cams.iter().map(|c| render(c, rs, 0.0, 0)).collect();
        // A loose hull: the ball of radius 0.9 around the sphere of radius 0.6.
        let mut inside: Vec<bool> = (0..res * res * res)
            .map(|i| centre(i, res, r as f64).norm() < 0.9)
            .collect();
        let views: Vec<_> = cams
            .iter()
            .zip(&rendered)
            .map(|(c, (img, m))| (c, img, Some(m)))
            .collect();
        let p = PhotoCarveParams {
            tau: 0.1,
            min_views: 3,
            max_iterations: 200,
        };
        let rep = photo_carve(&views, &mut inside, res, r, &p);
        assert!(rep.converged, "{rep:?}");
        let h = 2.0 * r as f64 / res as f64;
        let (mut deep_kept, mut deep) = (0, 0);
        let (mut near_out, mut far_out_kept) = (0, 0);
        for (idx, &b) in inside.iter().enumerate() {
            let d = centre(idx, res, r as f64).norm();
            if d < rs - 2.0 * h {
                deep += 1;
                deep_kept += usize::from(b);
            }
            // Between the sphere and the cube's faces, in the band the cameras look through.
            if d > rs + 3.0 * h && d < 0.9 && centre(idx, res, r as f64).z.abs() < 0.5 {
                near_out += 1;
                far_out_kept += usize::from(b);
            }
        }
        assert_eq!(deep_kept, deep, "the carve cut into the sphere: {rep:?}");
        assert!(
            (far_out_kept as f64) < 0.5 * near_out as f64,
            "{far_out_kept} of {near_out} voxels outside the sphere kept: {rep:?}"
        );
    }

    /// Consistency is what keeps a voxel: the same sphere with independent per-view noise much
    /// above `tau` is carved into; with `tau` above the noise nothing of the sphere is lost; and
    /// voxels fewer than `min_views` views see are kept.
    #[test]
    fn inconsistent_colours_are_carved_and_too_few_views_keep_everything() {
        let (res, r, rs) = (24usize, 1.0f32, 0.6f64);
        let cams = ring(8);
        let sphere: Vec<bool> = (0..res * res * res)
            .map(|i| centre(i, res, r as f64).norm() < rs)
            .collect();
        let noisy: Vec<_> = cams
            .iter()
            .enumerate()
            .map(|(i, c)| render(c, rs, 0.3, 100 + i as u64))
            .collect();
        let views: Vec<_> = cams
            .iter()
            .zip(&noisy)
            .map(|(c, (img, m))| (c, img, Some(m)))
            .collect();
        let carve = |tau: f32, min_views: usize| {
            let mut g = sphere.clone();
            let p = PhotoCarveParams {
                tau,
                min_views,
                max_iterations: 3,
            };
            let rep = photo_carve(&views, &mut g, res, r, &p);
            (rep, g)
        };
        let (low, _) = carve(0.02, 3);
        assert!(low.inside_after < low.inside_before, "{low:?}");
        let (high, g) = carve(0.5, 3);
        assert_eq!(high.inside_after, high.inside_before, "{high:?}");
        assert!(high.converged);
        assert_eq!(g, sphere);
        let (few, _) = carve(0.02, 9);
        assert_eq!(
            few.inside_after, few.inside_before,
            "8 views cannot reach 9: {few:?}"
        );
    }

    #[test]
    fn box_span_clips_to_the_box_and_misses() {
        let (t0, t1) = box_span([-3.0, 0.0, 0.0], [1.0, 0.0, 0.0], 1.0).unwrap();
        assert!((t0 - 2.0).abs() < 1e-6 && (t1 - 4.0).abs() < 1e-6);
        assert!(box_span([-3.0, 2.0, 0.0], [1.0, 0.0, 0.0], 1.0).is_none());
        let (t0, _) = box_span([0.0; 3], [0.0, 0.0, 1.0], 1.0).unwrap();
        assert_eq!(t0, 0.0);
    }
}
