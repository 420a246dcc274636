//! Step 1b of the module doc of [`super`]: slanted windows by PatchMatch stereo.
//!
//! The plane sweep of step 1 matches every pixel's window under a plane parallel to the image.
//! Where the camera grazes a surface the window's pixels lie at depths that differ by several
//! millimetres, the fronto-parallel warp puts the source's window in the wrong place everywhere
//! but at its centre, and the cost's minimum moves off the surface: the share of the sweep's
//! consistent depths near the truth falls from nearly all to little more than half as the depth
//! change per pixel grows from under half a millimetre to several (measured: docs/recipe.md).
//!
//! This step gives each pixel a plane of any orientation, as PatchMatch stereo does (Bleyer,
//! Rhemann & Rother, BMVC 2011, §2–3; COLMAP's `patch_match.cu` keeps a depth and a normal per
//! pixel the same way, Schönberger et al., ECCV 2016, §4). Each pixel starts from the sweep's
//! depth with a fronto-parallel plane (pixels without one start empty). Then `slant_iters`
//! passes go over the view in raster order, forward and backward in turn; at each pixel
//! - *propagation* tries the planes of the two neighbours the pass has already visited (left and
//!   above going forward, right and below going back): a plane found at one pixel of a surface
//!   holds for its neighbours;
//! - *refinement* tries `SLANT_TRIES` random perturbations of the pixel's plane, the depth by up
//!   to `SLANT_DEPTH_STEPS` sweep steps and the normal by up to 60°, halving both at each try.
//!
//! A plane is kept when its cost is lower; the cost is the sweep's (`1 − NCC` over the
//! `(2·window_half + 1)²` window, the mean of the `top_k` best sources), each window pixel
//! warped through the plane into the source (the homography of the plane). Normals stay within
//! `SLANT_MAX_DEG` of the pixel's ray. The pixel's depth is the plane's at its centre, kept when
//! its cost is below `max_cost`. The random numbers come from a generator seeded by the view's
//! index, so a scene gives the same depth maps at every run.

use super::sweep::top_k_mean;
use super::{MvsConfig, View};
use nalgebra::{Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// Perturbations tried at each pixel per pass.
const SLANT_TRIES: usize = 4;
/// The first perturbation moves the depth by up to this many sweep steps.
const SLANT_DEPTH_STEPS: f64 = 4.0;
/// The first perturbation tilts the normal by up to this angle (degrees).
const SLANT_TILT_DEG: f64 = 60.0;
/// A plane's normal stays within this angle of the pixel's ray (degrees): at 80° one pixel of
/// the window spans almost six times its width in depth.
const SLANT_MAX_DEG: f64 = 80.0;

/// A pixel's plane in the reference camera's frame: the points `X` with `n·X = d`, `n` a unit
/// vector with `n·r > 0` along the pixel's ray `r` (so `n` points away from the camera), `d > 0`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Plane {
    n: Vector3<f64>,
    d: f64,
}

/// What the cost of one view needs: its pixels' rays and the sources' warps.
pub(super) struct Matcher<'a> {
    cfg: &'a MvsConfig,
    vi: &'a View,
    views: &'a [View],
    srcs: &'a [usize],
    /// Per source: [`View::warp_to`] from view `i`.
    warps: Vec<(Matrix3<f64>, Vector3<f64>)>,
    /// `K_i⁻¹`: the camera-frame ray (`z = 1`) of pixel coordinates `(u, v, 1)`.
    kinv: Matrix3<f64>,
    /// Window pixels.
    nwin: usize,
    min_var: f64,
}

impl<'a> Matcher<'a> {
    /// The matcher of view `i` against its sources `srcs`.
    pub(super) fn new(cfg: &'a MvsConfig, views: &'a [View], i: usize, srcs: &'a [usize]) -> Self {
        let vi = &views[i];
        let hf = cfg.window_half;
        let nwin = (2 * hf + 1) * (2 * hf + 1);
        Matcher {
            cfg,
            vi,
            views,
            srcs,
            warps: srcs.iter().map(|&j| vi.warp_to(&views[j])).collect(),
            kinv: vi.kinv,
            nwin,
            min_var: (cfg.min_std as f64).powi(2) * nwin as f64,
        }
    }

    /// The camera-frame ray (`z = 1`) through pixel coordinates `(u, v)`.
    fn ray(&self, u: f64, v: f64) -> Vector3<f64> {
        self.kinv * Vector3::new(u, v, 1.0)
    }

    /// The plane through the point at camera depth `z` of pixel `(x, y)` with normal `n`.
    pub(super) fn plane_at(&self, x: usize, y: usize, z: f64, n: Vector3<f64>) -> Plane {
        let r = self.ray(x as f64 + 0.5, y as f64 + 0.5);
        Plane {
            n,
            d: z * n.dot(&r),
        }
    }

    /// The camera depth of `pl` at pixel `(x, y)`, when it lies in front of the camera and
    /// the normal is within [`SLANT_MAX_DEG`] of the ray.
    pub(super) fn depth(&self, pl: &Plane, x: usize, y: usize) -> Option<f64> {
        let r = self.ray(x as f64 + 0.5, y as f64 + 0.5);
        let nr = pl.n.dot(&r);
        let cos_max = SLANT_MAX_DEG.to_radians().cos();
        (nr > cos_max * r.norm() && pl.d > 0.0).then(|| pl.d / nr)
    }

    /// The reference window of pixel `(x, y)` (the window inside the image): `(mean, Σ(a −
    /// mean)²)` of its grey values, `None` when it holds a non-finite value or too little
    /// texture (`min_std`). It does not depend on the plane, so [`refine`] takes it once.
    pub(super) fn reference(&self, x: usize, y: usize) -> Option<(f64, f64)> {
        let (w, hf) = (self.vi.w, self.cfg.window_half as isize);
        let n = self.nwin as f64;
        let (mut sa, mut saa) = (0.0f64, 0.0f64);
        for dy in -hf..=hf {
            for dx in -hf..=hf {
                let g = self.vi.grey[(y as isize + dy) as usize * w + (x as isize + dx) as usize];
                if !g.is_finite() {
                    return None;
                }
                sa += g as f64;
                saa += (g as f64) * (g as f64);
            }
        }
        let va = saa - sa * sa / n;
        (va >= self.min_var && va > 0.0).then_some((sa / n, va))
    }

    /// The cost of `pl` at pixel `(x, y)`, whose window is `reference` ([`Self::reference`]):
    /// `1 − NCC` averaged over the `top_k` best sources, NaN when fewer than `top_k` give one.
    pub(super) fn cost(
        &self,
        pl: &Plane,
        x: usize,
        y: usize,
        (mean_a, va): (f64, f64),
        costs: &mut Vec<f32>,
    ) -> f32 {
        let a = &self.vi.grey;
        let (w, hf) = (self.vi.w, self.cfg.window_half as isize);
        let n = self.nwin as f64;
        costs.clear();
        let (u0, v0) = (x as f64 + 0.5, y as f64 + 0.5);
        let r0 = self.ray(u0, v0);
        let (rx, ry) = (self.kinv.column(0), self.kinv.column(1));
        let (nr0, nrx, nry) = (pl.n.dot(&r0), pl.n.dot(&rx), pl.n.dot(&ry));
        for (s, (am, b)) in self.warps.iter().enumerate() {
            let vj = &self.views[self.srcs[s]];
            let p0 = am * Vector3::new(u0, v0, 1.0);
            let (px, py) = (am.column(0), am.column(1));
            let (mut sb, mut sbb, mut sab) = (0.0f64, 0.0f64, 0.0f64);
            let mut ok = true;
            'win: for dy in -hf..=hf {
                for dx in -hf..=hf {
                    let (fx, fy) = (dx as f64, dy as f64);
                    let nr = nr0 + fx * nrx + fy * nry;
                    let hh = (p0 + px * fx + py * fy) * (pl.d / nr) + b;
                    if !(nr > 0.0 && hh.z > 1e-9) {
                        ok = false;
                        break 'win;
                    }
                    let g = vj.bilinear(hh.x / hh.z, hh.y / hh.z);
                    if !g.is_finite() {
                        ok = false;
                        break 'win;
                    }
                    let (g, ga) = (
                        g as f64,
                        a[(y as isize + dy) as usize * w + (x as isize + dx) as usize] as f64,
                    );
                    sb += g;
                    sbb += g * g;
                    sab += g * (ga - mean_a);
                }
            }
            if !ok {
                continue;
            }
            let vb = sbb - sb * sb / n;
            if vb < self.min_var || vb <= 0.0 {
                continue;
            }
            costs.push((1.0 - sab / (va * vb).sqrt()) as f32);
        }
        top_k_mean(costs, self.cfg.top_k)
    }
}

/// `n` tilted by a random offset of up to about `angle` radians (`n + sin(angle)·u`, `u`
/// uniform in the cube `[−1, 1]³`, normalised). A draw that cancels `n` gives a non-finite
/// vector, which [`Matcher::depth`] refuses.
fn tilt(rng: &mut Pcg64Mcg, n: &Vector3<f64>, angle: f64) -> Vector3<f64> {
    let s = angle.sin();
    let u = Vector3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    (n + u * s).normalize()
}

/// Step 1b for view `i`: its camera-`z` map `z0` from the sweep (NaN: none) refined with
/// slanted planes, `dz` the sweep's plane step (camera depth). Pixels outside the mask, or
/// whose window leaves the image, keep what they had.
pub(super) fn refine(
    cfg: &MvsConfig,
    views: &[View],
    i: usize,
    srcs: &[usize],
    z0: &[f32],
    dz: f64,
) -> Vec<f32> {
    let vi = &views[i];
    let (w, h, hf) = (vi.w, vi.h, cfg.window_half);
    if cfg.slant_iters == 0 || srcs.len() < cfg.top_k || w <= 2 * hf || h <= 2 * hf {
        return z0.to_vec();
    }
    let m = Matcher::new(cfg, views, i, srcs);
    // The pixels refined: in the mask, with the window inside the image.
    let inside =
        |x: usize, y: usize| x >= hf && y >= hf && x + hf < w && y + hf < h && vi.mask[y * w + x];
    let refw: Vec<Option<(f64, f64)>> = (0..w * h)
        .map(|k| {
            let (x, y) = (k % w, k / w);
            inside(x, y).then(|| m.reference(x, y)).flatten()
        })
        .collect();
    let mut plane: Vec<Option<Plane>> = vec![None; w * h];
    let mut cost = vec![f32::INFINITY; w * h];
    let mut scratch = Vec::with_capacity(srcs.len());
    let front = Vector3::new(0.0, 0.0, 1.0);
    for y in 0..h {
        for x in 0..w {
            let k = y * w + x;
            let z = z0[k] as f64;
            if !(inside(x, y) && z.is_finite() && z > 0.0) {
                continue;
            }
            let pl = m.plane_at(x, y, z, front);
            let c = refw[k].map_or(f32::NAN, |r| m.cost(&pl, x, y, r, &mut scratch));
            plane[k] = Some(pl);
            cost[k] = if c.is_finite() { c } else { f32::INFINITY };
        }
    }
    let mut rng = Pcg64Mcg::seed_from_u64(0x5EED_0000 + i as u64);
    let tilt0 = SLANT_TILT_DEG.to_radians();
    for it in 0..cfg.slant_iters {
        let forward = it % 2 == 0;
        for step in 0..w * h {
            let k = if forward { step } else { w * h - 1 - step };
            let (x, y) = (k % w, k / w);
            if !inside(x, y) {
                continue;
            }
            let mut try_plane = |pl: Plane, plane: &mut [Option<Plane>], cost: &mut [f32]| {
                let Some(r) = refw[k] else {
                    return;
                };
                if m.depth(&pl, x, y).is_none() {
                    return;
                }
                let c = m.cost(&pl, x, y, r, &mut scratch);
                if c < cost[k] {
                    cost[k] = c;
                    plane[k] = Some(pl);
                }
            };
            // Propagation from the neighbours visited already.
            let nbrs = if forward {
                [(x > 0).then(|| k - 1), (y > 0).then(|| k - w)]
            } else {
                [(x + 1 < w).then(|| k + 1), (y + 1 < h).then(|| k + w)]
            };
            for q in nbrs.into_iter().flatten() {
                if let Some(pl) = plane[q] {
                    try_plane(pl, &mut plane, &mut cost);
                }
            }
            // Refinement: perturbations halving in size.
            let Some(cur) = plane[k] else {
                continue;
            };
            let Some(zc) = m.depth(&cur, x, y) else {
                continue;
            };
            let (mut zs, mut ts) = (SLANT_DEPTH_STEPS * dz, tilt0);
            for _ in 0..SLANT_TRIES {
                let base = plane[k].unwrap_or(cur);
                let zb = m.depth(&base, x, y).unwrap_or(zc);
                let z = zb + rng.random_range(-1.0..1.0) * zs;
                let n = tilt(&mut rng, &base.n, ts);
                if z > 0.0 {
                    let pl = m.plane_at(x, y, z, n);
                    try_plane(pl, &mut plane, &mut cost);
                }
                zs *= 0.5;
                ts *= 0.5;
            }
        }
    }
    let mut out = z0.to_vec();
    for (k, o) in out.iter_mut().enumerate() {
        let (x, y) = (k % w, k / w);
        if !inside(x, y) {
            continue;
        }
        *o = match plane[k] {
            Some(pl) if cost[k] <= cfg.max_cost => {
                m.depth(&pl, x, y).map_or(f32::NAN, |z| z as f32)
            }
            _ => f32::NAN,
        };
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::tests::grazing_rig;
    use super::super::{nearest_sources, stereo_views};
    use super::*;

    /// The cost of `pl` at `(x, y)` the long way: each window pixel's ray cut with the plane in
    /// the world frame, the point projected into each source by [`View::project`], and the
    /// textbook NCC of the two windows.
    fn cost_by_rays(m: &Matcher, pl: &Plane, x: usize, y: usize) -> f32 {
        let (vi, hf) = (m.vi, m.cfg.window_half as isize);
        let mut per = Vec::new();
        for &j in m.srcs {
            let vj = &m.views[j];
            let (mut a, mut b) = (Vec::new(), Vec::new());
            for dy in -hf..=hf {
                for dx in -hf..=hf {
                    let (px, py) = ((x as isize + dx) as usize, (y as isize + dy) as usize);
                    let (u, v) = (px as f64 + 0.5, py as f64 + 0.5);
                    let rc = vi.kinv * Vector3::new(u, v, 1.0);
                    let z = pl.d / pl.n.dot(&rc);
                    let xw = vi.c + vi.dir(u, v) * z;
                    let (uj, vj_, _) = vj.project(&xw);
                    a.push(vi.grey[py * vi.w + px] as f64);
                    b.push(vj.bilinear(uj, vj_) as f64);
                }
            }
            if b.iter().any(|g| !g.is_finite()) {
                continue;
            }
            let n = a.len() as f64;
            let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
            let cov: f64 = a.iter().zip(&b).map(|(p, q)| (p - ma) * (q - mb)).sum();
            let va: f64 = a.iter().map(|p| (p - ma).powi(2)).sum();
            let vb: f64 = b.iter().map(|q| (q - mb).powi(2)).sum();
            if va < m.min_var || vb < m.min_var {
                continue;
            }
            per.push((1.0 - cov / (va * vb).sqrt()) as f32);
        }
        top_k_mean(&mut per, m.cfg.top_k)
    }

    #[test]
    fn the_slanted_cost_matches_the_cost_through_rays_and_projections() {
        let (cams, imgs, masks) = grazing_rig();
        let views = stereo_views(&cams, &imgs, Some(&masks));
        let srcs = &nearest_sources(&views, 4)[0];
        let cfg = MvsConfig::default();
        let vi = &views[0];
        let m = Matcher {
            cfg: &cfg,
            vi,
            views: &views,
            srcs,
            warps: srcs.iter().map(|&j| vi.warp_to(&views[j])).collect(),
            kinv: vi.kinv,
            nwin: 25,
            min_var: (cfg.min_std as f64).powi(2) * 25.0,
        };
        let mut rng = Pcg64Mcg::seed_from_u64(7);
        let (mut compared, mut scratch) = (0, Vec::new());
        for _ in 0..400 {
            let (x, y) = (rng.random_range(2..94), rng.random_range(2..78));
            let r = m.ray(x as f64 + 0.5, y as f64 + 0.5).normalize();
            let n = tilt(&mut rng, &r, 1.0);
            let z = rng.random_range(1.2..2.6);
            let pl = m.plane_at(x, y, z, n);
            if m.depth(&pl, x, y).is_none() {
                continue;
            }
            let fast = m
                .reference(x, y)
                .map_or(f32::NAN, |r| m.cost(&pl, x, y, r, &mut scratch));
            let slow = cost_by_rays(&m, &pl, x, y);
            assert_eq!(
                fast.is_finite(),
                slow.is_finite(),
                "({x}, {y}): {fast} {slow}"
            );
            if fast.is_finite() {
                assert!(
                    (fast - slow).abs() < 1e-4,
                    "({x}, {y}): {fast} against {slow}"
                );
                compared += 1;
            }
        }
        assert!(compared > 100, "only {compared} finite costs compared");
    }

    #[test]
    fn the_same_view_gives_the_same_depths_and_no_passes_change_nothing() {
        let (cams, imgs, masks) = grazing_rig();
        let views = stereo_views(&cams, &imgs, Some(&masks));
        let srcs = &nearest_sources(&views, 4)[2];
        let cfg = MvsConfig {
            slant_iters: 2,
            ..Default::default()
        };
        let z0 = super::super::sweep_view(&cfg, &views, 2, srcs);
        let a = refine(&cfg, &views, 2, srcs, &z0, 2.0 / 128.0);
        let b = refine(&cfg, &views, 2, srcs, &z0, 2.0 / 128.0);
        assert!(a.iter().zip(&b).all(|(p, q)| p.to_bits() == q.to_bits()));
        assert!(a.iter().any(|z| z.is_finite()));
        let off = MvsConfig {
            slant_iters: 0,
            ..cfg
        };
        let c = refine(&off, &views, 2, srcs, &z0, 2.0 / 128.0);
        assert!(c.iter().zip(&z0).all(|(p, q)| p.to_bits() == q.to_bits()));
    }
}
