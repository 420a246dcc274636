//! Visual-hull initialisation of the SDF (`[train.init] kind = "visual_hull"`).
//!
//! The default start is the SDF network's geometric init, a sphere of radius
//! `field.sdf.sphere_init_radius` (SAL, Atzmon & Lipman 2020; NeuS `models/fields.py`
//! `geometric_init`). When the object is far from that sphere, as a frame of thin rods is,
//! the first steps see no surface near the silhouettes: the mask loss drives the weight sum down
//! everywhere, `inv_s` falls and the field becomes fog that never turns into a surface (an empty
//! mesh whatever the variance init).
//!
//! This module starts the field from the object's silhouettes instead, in three steps:
//! 1. [`carve`]: voxel centres of a `res³` grid over the box `[-r, r]³` (normalised space) are
//!    kept when every training view that sees them inside its image has them inside its mask,
//!    dilated by the voxel's projected size (so thin parts are not lost between voxel centres).
//!    A voxel no view sees is outside. This is the visual hull (Laurentini 1994) on a grid, the
//!    space carving with masks that NeuS's mask loss and MonoSDF / NeuralWarp culling also rely
//!    on.
//! 2. [`HullSdf::from_occupancy`]: the signed Euclidean distance to the hull surface at the voxel
//!    centres, from two exact squared distance transforms (Felzenszwalb & Huttenlocher 2012,
//!    "Distance Transforms of Sampled Functions", separable 1-D lower envelopes of parabolas),
//!    negative inside, in normalised units.
//! 3. [`fit`]: a few hundred AdamW steps of L1 regression of the SDF channel onto that distance
//!    (`NeusModel::sdf_fit_loss_grad`) at random points, half uniform in the box and half near
//!    the hull surface, with the hash levels active at training step 0, so the coarse-to-fine
//!    schedule then adds finer levels to a field that already has the hull's shape.
//!
//! `kind = "sphere_or_hull"` (every preset but `paper`) chooses between the two starts per
//! scene, before training, from [`sphere_cover`]: the share of the init sphere's volume that lies
//! inside the hull. The hull start wins where the masks carve most of the sphere away (a frame of
//! thin rods, a ring whose hole takes the sphere's middle, thin sheets) and loses where the object
//! fills it (measured: docs/recipe.md). The threshold, one half, says "the masks carve away most
//! of the sphere"; the shares met in practice lie far from it on both sides.
//!
//! The hull contains the object but not its concavities (a vessel's inside, a relief's hollows):
//! rendering carves those during training, as it carves the sphere. Holes the masks show (a
//! torus's hole, the gaps of a frame) are open from the start.

use super::adam::{AdamW, AdamWConfig, OptimError};
use crate::render::NeusModel;
use crate::scene::camera::pixel_of;
use crate::scene::image::dilate_mask;
use crate::scene::{Camera, GrayImage};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// How the SDF starts (`[train.init] kind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InitKind {
    /// The SDF network's sphere init alone (what every run used before).
    #[default]
    Sphere,
    /// The sphere init, then a fit to the visual hull of the training masks (module docs). An
    /// error without masks.
    VisualHull,
    /// `VisualHull` when the run trains with masks and every training view has one, else
    /// `Sphere` (for scripts that run the same configuration on scenes with and without masks).
    Auto,
    /// `Sphere`, unless every training view has a mask and the masks' visual hull covers less than
    /// [`InitConfig::sphere_cover_min`] of the init sphere's volume: then `VisualHull`
    /// ([`sphere_cover`]). The sphere start works when the object fills a good part of the sphere,
    /// and the hull start costs accuracy there; when the masks carve most of the sphere away (a
    /// frame of thin rods), the first steps' mask loss drives the weight sum down everywhere and
    /// the field turns to fog (an empty mesh), which the hull start avoids.
    SphereOrHull,
}

/// The SDF initialisation (`[train.init]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InitConfig {
    pub kind: InitKind,
    /// Voxels per axis of the hull grid over `[-r, r]³` (96: 2.1 % of the box per voxel).
    pub resolution: usize,
    /// Fit steps (400).
    pub steps: u64,
    /// Points per fit step (8192, half uniform in the box, half near the hull surface).
    pub points: usize,
    /// AdamW learning rate of the fit (1e-2, the training's base rate; no weight decay).
    pub lr: f32,
    /// `kind = "sphere_or_hull"`: the hull start is taken when the visual hull covers less than
    /// this share of the init sphere's volume ([`sphere_cover`]; 0.5: the masks carve away
    /// most of the sphere).
    pub sphere_cover_min: f64,
}

impl Default for InitConfig {
    fn default() -> Self {
        Self {
            kind: InitKind::Sphere,
            resolution: 96,
            steps: 400,
            points: 8192,
            lr: 1e-2,
            sphere_cover_min: 0.5,
        }
    }
}

impl InitConfig {
    /// The first invalid field, as `(key, value, why)`.
    pub fn invalid(&self) -> Option<(&'static str, String, &'static str)> {
        if !(8..=512).contains(&self.resolution) {
            return Some((
                "train.init.resolution",
                self.resolution.to_string(),
                "must be in 8..=512",
            ));
        }
        if self.steps == 0 {
            return Some(("train.init.steps", "0".into(), "must be at least 1"));
        }
        if self.points == 0 {
            return Some(("train.init.points", "0".into(), "must be at least 1"));
        }
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return Some(("train.init.lr", self.lr.to_string(), "must be positive"));
        }
        if !(0.0..=1.0).contains(&self.sphere_cover_min) {
            return Some((
                "train.init.sphere_cover_min",
                self.sphere_cover_min.to_string(),
                "must be in [0, 1]",
            ));
        }
        None
    }
}

/// Why the hull cannot start a run.
#[derive(Debug, thiserror::Error)]
pub enum HullError {
    #[error("train.init.kind = \"visual_hull\" needs object masks, and {0}")]
    NoMasks(&'static str),
    #[error(
        "the masks carve away every voxel of the {res}³ hull grid: no point of the box projects \
         inside the mask of every view that sees it. The cameras and masks disagree (a wrong \
         pose, an inverted mask, or an object outside the unit sphere of the normalised space)"
    )]
    Empty { res: usize },
    #[error(
        "the visual hull fills the whole box of the {res}³ grid: the masks carve nothing (all \
         masks full?). Use the sphere init (train.init.kind = \"sphere\")"
    )]
    Full { res: usize },
    #[error("visual-hull fit: {0}")]
    Optim(#[from] OptimError),
}

/// Centre of voxel `i` along one axis: `-r + (i + ½)·h`, `h = 2r/res`.
fn voxel_centre(i: usize, r: f64, h: f64) -> f64 {
    -r + (i as f64 + 0.5) * h
}

/// Centre `(x, y, z)` of the voxel at flat index `idx = (k·res + j)·res + i` ([`carve`]'s order).
fn voxel_centre_at(idx: usize, res: usize, r: f64, h: f64) -> [f64; 3] {
    [idx % res, (idx / res) % res, idx / (res * res)].map(|i| voxel_centre(i, r, h))
}

/// Visual hull on a `res³` grid of voxel centres over `[-radius, radius]³` (module docs, step 1).
/// `views` pairs each camera (normalised space) with its mask (object `> 0.5`). Returns
/// `inside [res³]`, index `(k·res + j)·res + i` for the voxel at `(x_i, y_j, z_k)`.
pub fn carve(views: &[(&Camera, &GrayImage)], radius: f32, res: usize) -> Vec<bool> {
    let r = radius as f64;
    let h = 2.0 * r / res as f64;
    // A voxel projects to about `f·(√3/2·h)/depth` pixels around its centre; dilate each mask by
    // that at the box's nearest depth, so a voxel that touches the silhouette is kept.
    let dilated: Vec<Vec<bool>> = views
        .iter()
        .map(|(cam, m)| {
            let f = cam.k[(0, 0)].max(cam.k[(1, 1)]);
            let depth = (cam.center.norm() - 3f64.sqrt() * r).max(0.1 * cam.center.norm());
            let px = (f * 0.5 * 3f64.sqrt() * h / depth.max(1e-9)).ceil();
            dilate_mask(m, px.clamp(1.0, 32.0) as usize)
        })
        .collect();
    let mut inside = vec![false; res * res * res];
    inside
        .par_chunks_mut(res * res)
        .enumerate()
        .for_each(|(k, slab)| {
            let z = voxel_centre(k, r, h);
            for j in 0..res {
                let y = voxel_centre(j, r, h);
                for i in 0..res {
                    let x = Vector3::new(voxel_centre(i, r, h), y, z);
                    let mut seen = false;
                    let mut carved = false;
                    for ((cam, _), d) in views.iter().zip(&dilated) {
                        if let Some((u, v)) = pixel_of(cam, &x) {
                            seen = true;
                            if !d[v * cam.width as usize + u] {
                                carved = true;
                                break;
                            }
                        }
                    }
                    slab[j * res + i] = seen && !carved;
                }
            }
        });
    inside
}

/// Share of the voxel centres of a `res³` [`carve`] grid over `[-radius, radius]³` that lie in
/// the ball `|x| ≤ sphere_radius` (the SDF network's init sphere, normalised space) and inside
/// the hull, among those in the ball; 0 when no centre is in the ball. `inside` is indexed as
/// [`carve`] returns it.
pub fn sphere_cover(inside: &[bool], res: usize, radius: f32, sphere_radius: f32) -> f64 {
    let (r, h) = (radius as f64, 2.0 * radius as f64 / res as f64);
    let rs2 = (sphere_radius as f64).powi(2);
    let (mut ball, mut covered) = (0u64, 0u64);
    for (idx, &b) in inside.iter().enumerate() {
        let c = voxel_centre_at(idx, res, r, h);
        if c[0] * c[0] + c[1] * c[1] + c[2] * c[2] <= rs2 {
            ball += 1;
            covered += u64::from(b);
        }
    }
    if ball == 0 {
        0.0
    } else {
        covered as f64 / ball as f64
    }
}

/// Squared Euclidean distance transform of a sampled function along one line (Felzenszwalb &
/// Huttenlocher 2012, §2.1): `d[q] = min_p (q − p)² + f[p]`. `f` uses a large finite value
/// (not ∞) for "no feature"; `v` and `z` are scratch of at least `n` and `n + 1` entries.
fn edt_1d(f: &[f64], d: &mut [f64], v: &mut [usize], z: &mut [f64]) {
    let n = f.len();
    if n == 0 {
        return;
    }
    let mut k = 0usize;
    v[0] = 0;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in 1..n {
        let fq = f[q] + (q * q) as f64;
        let s = loop {
            // z[0] = −∞ ends the loop at k = 0 at the latest (every f is finite).
            let p = v[k];
            let s = (fq - (f[p] + (p * p) as f64)) / (2.0 * (q as f64 - p as f64));
            if s > z[k] {
                break s;
            }
            k -= 1;
        };
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    let mut k = 0usize;
    for (q, dq) in d.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let p = v[k];
        let dx = q as f64 - p as f64;
        *dq = dx * dx + f[p];
    }
}

/// "No feature" in the distance transforms: far beyond any squared distance in a grid.
const FAR: f64 = 1e20;

/// Runs `f(line, out)` on every line of a `res³` grid (index `(k·res + j)·res + i`) along x,
/// then y, then z, writing `out` back in place of the line: the passes of a separable filter.
fn along_every_axis<T: Copy + Default>(g: &mut [T], res: usize, mut f: impl FnMut(&[T], &mut [T])) {
    let mut line = vec![T::default(); res];
    let mut out = vec![T::default(); res];
    for stride in [1, res, res * res] {
        for base in 0..res * res {
            // The line's first voxel: `base` enumerates the other two coordinates.
            let start = match stride {
                1 => base * res,
                s if s == res => (base / res) * res * res + base % res,
                _ => base,
            };
            for (t, l) in line.iter_mut().enumerate() {
                *l = g[start + t * stride];
            }
            f(&line, &mut out);
            for (t, o) in out.iter().enumerate() {
                g[start + t * stride] = *o;
            }
        }
    }
}

/// Squared distance (in voxels²) from each voxel centre of a `res³` grid to the nearest voxel
/// with `feature` set; [`FAR`] where there is none. Separable: lines along x, then y, then z.
pub fn squared_distance_to(feature: &[bool], res: usize) -> Vec<f64> {
    assert_eq!(feature.len(), res * res * res);
    let mut g: Vec<f64> = feature.iter().map(|&b| if b { 0.0 } else { FAR }).collect();
    let mut v = vec![0usize; res];
    let mut z = vec![0f64; res + 1];
    along_every_axis(&mut g, res, |line, out| {
        edt_1d(line, out, &mut v, &mut z);
        for o in out.iter_mut() {
            *o = o.min(FAR);
        }
    });
    g
}

/// A signed distance sampled at the voxel centres of a `res³` grid over `[-radius, radius]³`
/// (normalised units, negative inside), interpolated trilinearly.
#[derive(Clone, Debug)]
pub struct HullSdf {
    pub res: usize,
    pub radius: f32,
    /// `[res³]`, index `(k·res + j)·res + i`.
    pub values: Vec<f32>,
}

impl HullSdf {
    /// The signed distance of an occupancy grid (module docs, step 2): outside, the distance to
    /// the nearest inside voxel centre minus half a voxel; inside, minus (the distance to the
    /// nearest outside voxel centre minus half a voxel). The zero level lies half-way between
    /// the centres of an inside and an outside neighbour.
    pub fn from_occupancy(inside: &[bool], res: usize, radius: f32) -> Result<Self, HullError> {
        let n_in = inside.iter().filter(|&&b| b).count();
        if n_in == 0 {
            return Err(HullError::Empty { res });
        }
        if n_in == inside.len() {
            return Err(HullError::Full { res });
        }
        let outside: Vec<bool> = inside.iter().map(|&b| !b).collect();
        let to_in = squared_distance_to(inside, res);
        let to_out = squared_distance_to(&outside, res);
        let h = 2.0 * radius as f64 / res as f64;
        let values = inside
            .iter()
            .zip(to_in.iter().zip(&to_out))
            .map(|(&b, (&di, &d_o))| {
                let s = if b {
                    -(d_o.sqrt() - 0.5)
                } else {
                    di.sqrt() - 0.5
                };
                (s * h) as f32
            })
            .collect();
        Ok(Self {
            res,
            radius,
            values,
        })
    }

    /// Voxel edge length (normalised units).
    pub fn voxel(&self) -> f32 {
        2.0 * self.radius / self.res as f32
    }

    /// Trilinear interpolation of the voxel-centre values at `x` (clamped to the centres' hull).
    pub fn at(&self, x: [f32; 3]) -> f32 {
        let n = self.res;
        let h = self.voxel();
        let mut i0 = [0usize; 3];
        let mut t = [0f32; 3];
        for a in 0..3 {
            let u = ((x[a] + self.radius) / h - 0.5).clamp(0.0, (n - 1) as f32);
            let f = u.floor().min((n.max(2) - 2) as f32);
            i0[a] = f as usize;
            t[a] = u - f;
        }
        let idx = |i: usize, j: usize, k: usize| (k * n + j) * n + i;
        let mut acc = 0f32;
        for c in 0..8 {
            let (di, dj, dk) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
            let w = (if di == 1 { t[0] } else { 1.0 - t[0] })
                * (if dj == 1 { t[1] } else { 1.0 - t[1] })
                * (if dk == 1 { t[2] } else { 1.0 - t[2] });
            let (i, j, k) = (
                (i0[0] + di).min(n - 1),
                (i0[1] + dj).min(n - 1),
                (i0[2] + dk).min(n - 1),
            );
            acc += w * self.values[idx(i, j, k)];
        }
        acc
    }

    /// Share of the voxels inside the hull.
    pub fn inside_share(&self) -> f64 {
        self.values.iter().filter(|&&v| v < 0.0).count() as f64 / self.values.len() as f64
    }
}

/// What the fit did.
#[derive(Clone, Debug, PartialEq)]
pub struct FitReport {
    /// Mean |f − t| of the first and last steps' points (normalised units).
    pub l1_first: f64,
    pub l1_last: f64,
    /// Share of the grid inside the hull.
    pub inside_share: f64,
}

/// Fits the SDF channel of `params` to `hull` (module docs, step 3) with `active` hash levels.
/// Seeded: the same `(params, hull, cfg, seed)` gives the same parameters.
pub fn fit(
    model: &NeusModel,
    params: &mut [f32],
    hull: &HullSdf,
    cfg: &InitConfig,
    active: usize,
    seed: u64,
) -> Result<FitReport, HullError> {
    let h = hull.voxel();
    let r = hull.radius;
    // Centres of the voxels within 2 voxels of the hull surface.
    let n = hull.res;
    let near: Vec<[f32; 3]> = hull
        .values
        .iter()
        .enumerate()
        .filter(|(_, v)| v.abs() < 2.0 * h)
        .map(|(idx, _)| {
            let (i, j, k) = (idx % n, (idx / n) % n, idx / (n * n));
            [i, j, k].map(|c| -r + (c as f32 + 0.5) * h)
        })
        .collect();
    let mut adam = AdamW::new(
        AdamWConfig {
            lr: cfg.lr,
            weight_decay: 0.0,
            ..AdamWConfig::default()
        },
        model.n_params(),
    );
    let mut grads = vec![0f32; model.n_params()];
    let mut rng = Pcg64Mcg::seed_from_u64(seed ^ 0x6875_6c6c);
    let mut pts = Vec::with_capacity(cfg.points);
    let mut targets = Vec::with_capacity(cfg.points);
    let (mut first, mut last) = (f64::NAN, f64::NAN);
    for step in 0..cfg.steps {
        pts.clear();
        targets.clear();
        for q in 0..cfg.points {
            let x = if q % 2 == 0 || near.is_empty() {
                [0; 3].map(|_| rng.random_range(-r..r))
            } else {
                let c = near[rng.random_range(0..near.len())];
                c.map(|v| (v + rng.random_range(-h..h)).clamp(-r, r))
            };
            pts.push(x);
            targets.push(hull.at(x));
        }
        let l = model.sdf_fit_loss_grad(params, &pts, &targets, active, &mut grads);
        if step == 0 {
            first = l;
        }
        last = l;
        adam.step_and_zero_grads(params, &mut grads, &model.layout, 1.0)?;
    }
    Ok(FitReport {
        l1_first: first,
        l1_last: last,
        inside_share: hull.inside_share(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cover of the init sphere by a ball-shaped hull of radius `a` is `(a/b)³` for `a < b`
    /// (up to the grid), 1 for `a ≥ b`, and 0 for an empty hull.
    #[test]
    fn sphere_cover_of_concentric_balls() {
        let (res, r, b) = (64usize, 1.0f32, 0.5f32);
        let h = 2.0 * r as f64 / res as f64;
        let ball = |a: f64| -> Vec<bool> {
            (0..res * res * res)
                .map(|idx| {
                    let c = voxel_centre_at(idx, res, r as f64, h);
                    (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt() <= a
                })
                .collect()
        };
        for a in [0.2, 0.3, 0.4] {
            let c = sphere_cover(&ball(a), res, r, b);
            let want = (a / b as f64).powi(3);
            assert!((c - want).abs() < 0.05, "a = {a}: {c} against {want}");
        }
        assert_eq!(sphere_cover(&ball(0.7), res, r, b), 1.0);
        assert_eq!(sphere_cover(&vec![false; res * res * res], res, r, b), 0.0);
        // A ball smaller than a voxel's half-diagonal holds no centre.
        assert_eq!(sphere_cover(&ball(0.7), res, r, 0.001), 0.0);
    }

    fn brute(feature: &[bool], res: usize) -> Vec<f64> {
        let pos = |idx: usize| [idx % res, (idx / res) % res, idx / (res * res)];
        (0..feature.len())
            .map(|a| {
                let pa = pos(a);
                feature
                    .iter()
                    .enumerate()
                    .filter(|(_, &f)| f)
                    .map(|(b, _)| {
                        let pb = pos(b);
                        (0..3)
                            .map(|t| (pa[t] as f64 - pb[t] as f64).powi(2))
                            .sum::<f64>()
                    })
                    .fold(FAR, f64::min)
            })
            .collect()
    }

    #[test]
    fn init_section_is_written_and_round_trips() {
        use crate::train::TrainConfig;
        let text = toml::to_string(&TrainConfig::default()).unwrap();
        assert!(text.contains("[init]\nkind = \"sphere\""), "{text}");
        let t: TrainConfig =
            toml::from_str("[init]\nkind = \"visual_hull\"\nsteps = 10\n").unwrap();
        assert_eq!(t.init.kind, InitKind::VisualHull);
        assert_eq!((t.init.steps, t.init.resolution), (10, 96));
        let again: TrainConfig = toml::from_str(&toml::to_string(&t).unwrap()).unwrap();
        assert_eq!(again, t);
        let err = toml::from_str::<TrainConfig>("[init]\nkind = \"hull\"\n").unwrap_err();
        assert!(err.to_string().contains("visual_hull"), "{err}");
        assert!(InitConfig {
            points: 0,
            ..InitConfig::default()
        }
        .invalid()
        .is_some_and(|(k, _, _)| k == "train.init.points"));
    }

    #[test]
    fn distance_transform_matches_brute_force() {
        let mut rng = Pcg64Mcg::seed_from_u64(3);
        for (res, density) in [(7usize, 0.05), (9, 0.3), (6, 0.9), (5, 0.0), (8, 0.01)] {
            let f: Vec<bool> = (0..res * res * res)
                .map(|_| rng.random_bool(density))
                .collect();
            let fast = squared_distance_to(&f, res);
            let slow = brute(&f, res);
            for (a, b) in fast.iter().zip(&slow) {
                assert!(
                    (a - b).abs() < 1e-9,
                    "res {res} density {density}: {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn hull_sdf_of_a_ball_is_its_distance_within_a_voxel() {
        let (res, r) = (40usize, 1.0f32);
        let h = 2.0 * r / res as f32;
        let c = |i: usize| -r + (i as f32 + 0.5) * h;
        let inside: Vec<bool> = (0..res * res * res)
            .map(|idx| {
                let (i, j, k) = (idx % res, (idx / res) % res, idx / (res * res));
                (c(i).powi(2) + c(j).powi(2) + c(k).powi(2)).sqrt() < 0.5
            })
            .collect();
        let s = HullSdf::from_occupancy(&inside, res, r).unwrap();
        let mut rng = Pcg64Mcg::seed_from_u64(1);
        for _ in 0..500 {
            let x = [0; 3].map(|_| rng.random_range(-0.9f32..0.9));
            let truth = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt() - 0.5;
            assert!(
                (s.at(x) - truth).abs() < 1.2 * h,
                "{x:?}: {} vs {truth}",
                s.at(x)
            );
        }
        assert!(matches!(
            HullSdf::from_occupancy(&[false; 8], 2, 1.0),
            Err(HullError::Empty { .. })
        ));
        assert!(matches!(
            HullSdf::from_occupancy(&[true; 8], 2, 1.0),
            Err(HullError::Full { .. })
        ));
    }
}
