//! Steps 4 and 5 of the module doc of [`super`]: the hole fill, its free-space check and the
//! march through the other views' surfels.

use super::{MvsConfig, View};
use nalgebra::{Matrix3, Vector3};

/// A depth the hole fill found: `(camera z, dx, dy, grey there)`, offsets in pixels.
type Found = (f64, f64, f64, f64);

/// Steps 4 and 5 of the module doc for one view of `w × h` pixels: its camera-`z` map `z` with
/// the holes inside `mask` filled, and which pixels the fill gave. `grey`: `[y * w + x]`, as
/// the view's. `free(k, z)`: whether pixel `k`'s point at camera depth `z` passes the
/// free-space check (the candidates are tried in order of preference); `cast(k, z0)`: the
/// march's depth for pixel `k` from the preferred candidate's `z0`, asked only when every
/// candidate fails. Without the check: `|_, _| true` and `|_, _| None`.
#[allow(clippy::too_many_arguments)]
pub(super) fn fill_holes(
    cfg: &MvsConfig,
    w: usize,
    h: usize,
    mask: &[bool],
    grey: &[f32],
    z: &[f32],
    free: impl Fn(usize, f64) -> bool,
    cast: impl Fn(usize, f64) -> Option<f64>,
) -> (Vec<f32>, Vec<bool>) {
    const DIRS: [(isize, isize); 8] = [
        (1, 0),
        (-1, 0),
        (0, 1),
        (0, -1),
        (1, 1),
        (-1, -1),
        (1, -1),
        (-1, 1),
    ];
    let (wi, hi) = (w as isize, h as isize);
    let (jump, tol) = (cfg.hole_jump as f64, cfg.hole_tol as f64);
    let gtol = cfg.hole_grey_tol as f64;
    let mut out = z.to_vec();
    let mut filled = vec![false; z.len()];
    // Per direction the nearest depth: (z, dx, dy, grey there), farthest first once sorted.
    let mut found: Vec<Found> = Vec::with_capacity(8);
    // The candidate groups of `found`: (start, end, grey distance), preferred first.
    let mut groups: Vec<(usize, usize, f64)> = Vec::with_capacity(8);
    for k in 0..z.len() {
        if !mask[k] || z[k].is_finite() {
            continue;
        }
        let (x, y) = ((k % w) as isize, (k / w) as isize);
        found.clear();
        for (dx, dy) in DIRS {
            for s in 1..=cfg.hole_radius as isize {
                let (xx, yy) = (x + dx * s, y + dy * s);
                if xx < 0 || yy < 0 || xx >= wi || yy >= hi {
                    break;
                }
                let q = (yy * wi + xx) as usize;
                if !mask[q] {
                    break;
                }
                if z[q].is_finite() {
                    let (ox, oy) = ((dx * s) as f64, (dy * s) as f64);
                    found.push((z[q] as f64, ox, oy, grey[q] as f64));
                    break;
                }
            }
        }
        if found.len() < 2 {
            continue;
        }
        found.sort_by(|a, b| b.0.total_cmp(&a.0));
        let far = found[0].0;
        let near = found[found.len() - 1].0;
        groups.clear();
        if far - near <= jump * far {
            groups.push((0, found.len(), 0.0));
        } else {
            // Farthest first; with the grey test only those whose mean grey lies within it of
            // the pixel's, the nearest in grey first (on a tie, the farther).
            let mut a = 0;
            while a + 1 < found.len() {
                let n = found[a..]
                    .iter()
                    .take_while(|f| found[a].0 - f.0 <= tol * found[a].0)
                    .count();
                if n < 2 {
                    a += 1;
                    continue;
                }
                let g = &found[a..a + n];
                let gm = g.iter().map(|f| f.3).sum::<f64>() / n as f64;
                let d = (gm - grey[k] as f64).abs();
                if gtol <= 0.0 {
                    groups.push((a, a + n, 0.0));
                } else if d < gtol {
                    groups.push((a, a + n, d));
                }
                a += n;
            }
            groups.sort_by(|a, b| a.2.total_cmp(&b.2));
        }
        let mut preferred = None;
        let mut pick = None;
        for &(g0, g1, _) in &groups {
            let group = &found[g0..g1];
            let fit = fit_inverse_plane(group);
            let mut zk = plane_through(group, fit);
            if cfg.hole_refine > 0 {
                let seed = fit.unwrap_or(Vector3::new(0.0, 0.0, 1.0 / zk));
                if let Some(zr) = refit_plane(cfg, w, h, mask, z, (x, y), seed) {
                    // A background depth lies beyond the occluder's, and no fill lies far
                    // behind everything it was found from.
                    if zr > near && zr < 1.05 * far {
                        zk = zr;
                    }
                }
            }
            preferred.get_or_insert(zk);
            if free(k, zk) {
                pick = Some(zk);
                break;
            }
        }
        let Some(zk) = pick.or_else(|| cast(k, preferred?)) else {
            continue;
        };
        out[k] = zk as f32;
        filled[k] = true;
    }
    (out, filled)
}

/// Step 5 of the module doc: whether fewer than `cfg.free_views` views other than `i` see
/// past the world point `x` (normalised frame): their depth in `evidence[j]` (camera `z`, NaN:
/// none) at the pixel `x` falls in lies beyond `x`'s camera depth by more than `cfg.free_tol`
/// of it. The free-space constraint of visibility-based depth-map fusion (Merrell et al.,
/// ICCV 2007, §4: a point that another view's depth ray passes through is not on a surface).
pub(super) fn free_of_others(
    cfg: &MvsConfig,
    views: &[View],
    evidence: &[Vec<f32>],
    i: usize,
    x: &Vector3<f64>,
) -> bool {
    let mut past = 0;
    for (j, vj) in views.iter().enumerate() {
        if j == i {
            continue;
        }
        let (u, v, zj) = vj.project(x);
        if !(u >= 0.0 && v >= 0.0 && zj > 0.0) {
            continue;
        }
        let (xj, yj) = (u as usize, v as usize);
        if xj >= vj.w || yj >= vj.h {
            continue;
        }
        if evidence[j][yj * vj.w + xj] as f64 > zj * (1.0 + cfg.free_tol as f64) {
            past += 1;
            if past >= cfg.free_views {
                return false;
            }
        }
    }
    true
}

/// Surfels a plane fit of [`SurfelCloud::plane_depth`] needs.
const CAST_MIN_SURFELS: usize = 10;

/// The world points of every view's consistent depths (normalised frame), thinned to one
/// per voxel of `radius / 8` (the mean of the voxel's points), each with the mean unit
/// direction towards the cameras that saw it, in a hash grid of cells of `radius`: what the
/// march of the hole fill (step 5) intersects its rays with.
pub(super) struct SurfelCloud {
    /// `[surfel]` position.
    pub(super) p: Vec<Vector3<f64>>,
    /// `[surfel]` unit direction towards the cameras that saw it.
    pub(super) seen_from: Vec<Vector3<f64>>,
    pub(super) radius: f64,
    /// Cell `floor(x / radius)` → the surfels in it.
    pub(super) grid: std::collections::HashMap<[i64; 3], Vec<u32>>,
}

impl SurfelCloud {
    fn cell(x: &Vector3<f64>, size: f64) -> [i64; 3] {
        [
            (x.x / size).floor() as i64,
            (x.y / size).floor() as i64,
            (x.z / size).floor() as i64,
        ]
    }

    /// `z[j]`: view `j`'s camera-`z` map (NaN: none).
    pub(super) fn new(views: &[View], z: &[Vec<f32>], radius: f64) -> Self {
        let voxel = radius / 8.0;
        let mut acc: std::collections::HashMap<[i64; 3], (Vector3<f64>, Vector3<f64>, u32)> =
            Default::default();
        for (v, m) in views.iter().zip(z) {
            for (k, &zz) in m.iter().enumerate() {
                if !zz.is_finite() {
                    continue;
                }
                let p = v.point(k, zz as f64);
                let e = acc.entry(Self::cell(&p, voxel)).or_insert((
                    Vector3::zeros(),
                    Vector3::zeros(),
                    0,
                ));
                e.0 += p;
                e.1 += (v.c - p).normalize();
                e.2 += 1;
            }
        }
        // Sorted voxels: the same surfels in the same order whatever the map's hashing.
        let mut voxels: Vec<_> = acc.into_iter().filter(|(_, a)| a.2 >= 2).collect();
        voxels.sort_unstable_by_key(|(key, _)| *key);
        let mut cloud = SurfelCloud {
            p: Vec::with_capacity(voxels.len()),
            seen_from: Vec::with_capacity(voxels.len()),
            radius,
            grid: Default::default(),
        };
        for (_, (sp, sd, n)) in voxels {
            let p = sp / n as f64;
            cloud
                .grid
                .entry(Self::cell(&p, radius))
                .or_default()
                .push(cloud.p.len() as u32);
            cloud.p.push(p);
            cloud.seen_from.push(sd.normalize());
        }
        cloud
    }

    /// The camera `z` where the ray of pixel `k` of `v` (direction `d`, camera `z` = 1)
    /// crosses the plane fitted to the surfels within `radius` of its point at camera depth
    /// `z` that were seen from the ray's side (their direction towards the cameras against
    /// the ray's: cosine below −0.2). `None` with fewer than [`CAST_MIN_SURFELS`] of them,
    /// when they do not lie on a plane (the smallest eigenvalue of their scatter above 5 % of
    /// the middle one), or when the ray runs along the plane.
    fn plane_depth(&self, v: &View, d: &Vector3<f64>, z: f64) -> Option<f64> {
        let du = d.normalize();
        let x0 = v.c + d * z;
        let [cx, cy, cz] = Self::cell(&x0, self.radius);
        // Sums of the offsets from `x0` (within the radius: no cancellation to speak of).
        let (mut n, mut s1, mut s2) = (0usize, Vector3::zeros(), Matrix3::zeros());
        for a in -1..=1 {
            for b in -1..=1 {
                for c in -1..=1 {
                    for &i in self
                        .grid
                        .get(&[cx + a, cy + b, cz + c])
                        .into_iter()
                        .flatten()
                    {
                        let (q, s) = (self.p[i as usize] - x0, self.seen_from[i as usize]);
                        if q.norm_squared() <= self.radius * self.radius && s.dot(&du) < -0.2 {
                            n += 1;
                            s1 += q;
                            s2 += q * q.transpose();
                        }
                    }
                }
            }
        }
        if n < CAST_MIN_SURFELS {
            return None;
        }
        let m = s1 / n as f64;
        let c = x0 + m;
        let eig = (s2 - m * s1.transpose()).symmetric_eigen();
        let mut order = [0, 1, 2];
        order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        if eig.eigenvalues[order[0]] > 0.05 * eig.eigenvalues[order[1]] {
            return None;
        }
        let n: Vector3<f64> = eig.eigenvectors.column(order[0]).into();
        let den = n.dot(d);
        if den.abs() < 1e-9 {
            return None;
        }
        let zn = n.dot(&(c - v.c)) / den;
        zn.is_finite().then_some(zn)
    }

    /// Marches the ray of pixel `k` of `v` outwards from 2 % beyond camera depth `z0`, in steps
    /// of half the radius (at most 64), and returns the first [`Self::plane_depth`] that lies
    /// beyond that start, within the radius of the march point, and that `ok` accepts.
    pub(super) fn cast(
        &self,
        v: &View,
        k: usize,
        z0: f64,
        ok: &dyn Fn(f64) -> bool,
    ) -> Option<f64> {
        let d = v.dir((k % v.w) as f64 + 0.5, (k / v.w) as f64 + 0.5);
        let (len, start) = (d.norm(), 1.02 * z0);
        let step = 0.5 * self.radius / len;
        (0..64).find_map(|s| {
            let z = start + s as f64 * step;
            let zn = self.plane_depth(v, &d, z)?;
            (zn > start && (zn - z).abs() * len <= self.radius && ok(zn)).then_some(zn)
        })
    }
}

/// Depths a refit needs inside its window.
const REFIT_MIN_DEPTHS: usize = 8;

/// The least-squares plane `1/z = a·dx + b·dy + c` (as `(a, b, c)`) through `samples` `(z, dx,
/// dy, _)`, when there are three or more and they span a plane.
fn fit_inverse_plane(samples: &[Found]) -> Option<Vector3<f64>> {
    if samples.len() < 3 {
        return None;
    }
    let mut ata = Matrix3::<f64>::zeros();
    let mut atb = Vector3::<f64>::zeros();
    for &(zz, dx, dy, _) in samples {
        let r = Vector3::new(dx, dy, 1.0);
        ata += r * r.transpose();
        atb += r / zz;
    }
    if ata.determinant().abs() <= 1e-6 {
        return None;
    }
    ata.try_inverse().map(|m| m * atb)
}

/// The camera `z` at pixel `(x, y)` of the plane `seed` (`1/z = a·dx + b·dy + c`, offsets from
/// `(x, y)` in pixels) refitted `cfg.hole_refine` rounds to the depths of `z` (camera `z`, NaN:
/// none) inside `mask` within `cfg.hole_radius` pixels (a square window) that lie within
/// `cfg.hole_tol` of the current plane: a consensus refit, as RANSAC's final step (Fischler &
/// Bolles, CACM 1981). `None` when a round finds fewer than [`REFIT_MIN_DEPTHS`] or they do
/// not span a plane.
fn refit_plane(
    cfg: &MvsConfig,
    w: usize,
    h: usize,
    mask: &[bool],
    z: &[f32],
    (x, y): (isize, isize),
    seed: Vector3<f64>,
) -> Option<f64> {
    let (wi, hi) = (w as isize, h as isize);
    let (r, tol) = (cfg.hole_radius as isize, cfg.hole_tol as f64);
    let mut p = seed;
    for _ in 0..cfg.hole_refine {
        let mut ata = Matrix3::<f64>::zeros();
        let mut atb = Vector3::<f64>::zeros();
        let mut n = 0;
        for yy in (y - r).max(0)..=(y + r).min(hi - 1) {
            for xx in (x - r).max(0)..=(x + r).min(wi - 1) {
                let q = (yy * wi + xx) as usize;
                let zq = z[q] as f64;
                if !zq.is_finite() || !mask[q] {
                    continue;
                }
                let row = Vector3::new((xx - x) as f64, (yy - y) as f64, 1.0);
                let zp = 1.0 / p.dot(&row);
                if zp > 0.0 && (zp - zq).abs() <= tol * zq {
                    ata += row * row.transpose();
                    atb += row / zq;
                    n += 1;
                }
            }
        }
        if n < REFIT_MIN_DEPTHS || ata.determinant().abs() <= 1e-6 {
            return None;
        }
        p = ata.try_inverse()? * atb;
    }
    let zz = 1.0 / p.z;
    zz.is_finite().then_some(zz)
}

/// The camera `z` at offset `(0, 0)` of `fit`, the plane [`fit_inverse_plane`] gives for
/// `samples` `(z, dx, dy, _)`, when there is one and the result lies within 1 % of their depth
/// range; the samples' mean depth otherwise.
fn plane_through(samples: &[Found], fit: Option<Vector3<f64>>) -> f64 {
    let mean = samples.iter().map(|s| s.0).sum::<f64>() / samples.len() as f64;
    let Some(p) = fit else {
        return mean;
    };
    let zz = 1.0 / p.z;
    let lo = samples.iter().map(|s| s.0).fold(f64::INFINITY, f64::min);
    let hi = samples.iter().map(|s| s.0).fold(0.0, f64::max);
    if zz.is_finite() && zz >= 0.99 * lo && zz <= 1.01 * hi {
        zz
    } else {
        mean
    }
}
