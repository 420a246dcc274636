//! Ground truth in DTU's own files and units: the visible surface sampled as points, the
//! observation mask and the ground plane (world frame, mm).
//!
//! - **Sampling.** Every triangle is covered by a square grid of pitch `spacing` laid in its own
//!   plane, anchored at its longest edge; grid points inside the triangle are kept, and every mesh
//!   vertex is added. So each point lies on the mesh (up to the f32 rounding of world coordinates
//!   below 512 mm: ≤ 2.7e-5 mm) and the density is one point per `spacing²` of area. (DTU's own
//!   `MeshSupSamp` rule, as jzhangbs/DTUeval-python `eval.py` ports it, leaves gaps of several
//!   spacings on thin triangles, so it is kept for scoring reconstructions, not for making ground
//!   truth.)
//! - **Visibility.** A point is kept when some camera sees it: it projects inside the image,
//!   in front of the camera, and no surface crosses the line of sight more than
//!   `gt.occlusion_eps_mm` (0.02 mm, a tenth of DTU's 0.2 mm sampling) in front of it. The epsilon
//!   absorbs the f32 error of the obvhs intersection distance (about 1e-4 mm at 600 mm, more at
//!   grazing angles) without letting a real occluder through: any occluder nearer than 0.02 mm to
//!   the point is below DTU's resolution. For closed, outward-oriented meshes (every built-in), a
//!   point whose triangle faces away from the camera is skipped without a ray: its line of sight
//!   enters the solid and must leave it again, so it is occluded.
//! - **Observation mask.** DTU's `ObsMask` marks the *observed volume* (Jensen et al., "Large
//!   scale multi-view stereopsis evaluation", CVPR 2014: the part of the scene the scanner could
//!   observe), and accuracy only counts reconstruction points in it. Here, with voxel edge
//!   `Res = gt.obs_res_mm` (2 mm) and DTU's indexing `round_half_even((p − BB₀)/Res)`
//!   (jzhangbs/DTUeval-python `eval.py`), a voxel is observed when it lies within
//!   `gt.obs_dilate_mm` (20 mm) of a visible ground-truth point and either contains one (a surface
//!   voxel) or its centre is seen by some camera: above the ground plane, outside the solid (for
//!   closed meshes, one ray from the centre whose first hit is a front face), in an image, and not
//!   occluded. Since DTU's accuracy ignores distances of 20 mm or more, a 20 mm band is
//!   equivalent to the whole observed volume; and voxels no camera could see (under the object,
//!   behind it, inside it) are left out, so a perfect reconstruction is not charged for surface
//!   nobody observed. `BB` is the visible points' bounding box padded by the band plus one voxel.
//! - **Plane.** `Plane.mat` holds `P = [n, −n·x₀]` with `n` the world up direction and `x₀` a point
//!   of the ground plane 1 mm below the object's lowest point, so `[x, y, z, 1]·P > 0` above it.

use super::setup::SimScene;
use dtu_eval::gt::{ObsMask, Plane};
use glam::Vec3A;
use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

/// The face index recorded for points that are mesh vertices (no single triangle).
pub const VERTEX_POINT: u32 = u32::MAX;

/// A surface sample: world position (mm, f32) and the triangle it lies on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// World coordinates (mm).
    pub p: [f32; 3],
    /// Its face, or [`VERTEX_POINT`].
    pub face: u32,
}

/// Ground truth and how it was made.
#[derive(Clone, Debug)]
pub struct GroundTruth {
    /// Visible surface points, world mm (what `stl{scan}_total.ply` holds).
    pub points: Vec<[f32; 3]>,
    /// The observation mask.
    pub obs_mask: ObsMask,
    /// The ground plane.
    pub plane: Plane,
    /// Counts.
    pub stats: GtStats,
}

/// Counts of the ground-truth generation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct GtStats {
    /// Surface samples before the visibility test.
    pub sampled: u64,
    /// Samples seen by at least one camera.
    pub visible: u64,
    /// Occlusion rays cast.
    pub occlusion_rays: u64,
    /// (point, camera) pairs skipped because the triangle faces away.
    pub backfacing_skips: u64,
    /// Observed voxels.
    pub obs_voxels: u64,
    /// Band voxels whose centre was tested for visibility.
    pub obs_tested: u64,
    /// Rays cast for the observation mask (inside tests and lines of sight).
    pub obs_rays: u64,
}

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Grid points of pitch `spacing` inside triangle `(a, b, c)` (see the module doc), in f64.
pub fn sample_triangle(a: V3, b: V3, c: V3, spacing: f64, out: &mut Vec<V3>) {
    // Relabel so that (p0, p1) is the longest edge; then the foot of p2 lies on it.
    let l2 = |u: V3, v: V3| dot(sub(u, v), sub(u, v));
    let (p0, p1, p2) = {
        let (ab, bc, ca) = (l2(a, b), l2(b, c), l2(c, a));
        if ab >= bc && ab >= ca {
            (a, b, c)
        } else if bc >= ca {
            (b, c, a)
        } else {
            (c, a, b)
        }
    };
    let e = sub(p1, p0);
    let len = dot(e, e).sqrt();
    if len == 0.0 {
        return;
    }
    let ex = e.map(|v| v / len);
    let q = sub(p2, p0);
    let hx = dot(q, ex);
    let hv = sub(q, ex.map(|v| v * hx));
    let height = dot(hv, hv).sqrt();
    if height <= 0.0 {
        return;
    }
    let ey = hv.map(|v| v / height);
    let mut j = 0usize;
    loop {
        let y = (j as f64 + 0.5) * spacing;
        if y >= height {
            break;
        }
        let t = y / height;
        let (x_lo, x_hi) = (hx * t, len + (hx - len) * t);
        let i0 = (x_lo / spacing - 0.5).ceil().max(0.0) as usize;
        let mut i = i0;
        loop {
            let x = (i as f64 + 0.5) * spacing;
            if x > x_hi {
                break;
            }
            if x >= x_lo {
                out.push(std::array::from_fn(|k| p0[k] + ex[k] * x + ey[k] * y));
            }
            i += 1;
        }
        j += 1;
    }
}

/// Samples the whole world mesh: grid points of every face (in face order), then every vertex.
pub fn sample_surface(scene: &SimScene, spacing: f64) -> Vec<SurfacePoint> {
    let mesh = &scene.mesh_world;
    let v = |i: u32| mesh.vertices[i as usize].map(|c| c as f64);
    let chunks: Vec<Vec<SurfacePoint>> = mesh
        .faces
        .par_chunks(2048)
        .enumerate()
        .map(|(ci, faces)| {
            let mut out = Vec::new();
            let mut buf = Vec::new();
            for (k, f) in faces.iter().enumerate() {
                buf.clear();
                sample_triangle(v(f[0]), v(f[1]), v(f[2]), spacing, &mut buf);
                let face = (ci * 2048 + k) as u32;
                out.extend(buf.iter().map(|p| SurfacePoint {
                    p: p.map(|c| c as f32),
                    face,
                }));
            }
            out
        })
        .collect();
    let mut all: Vec<SurfacePoint> = chunks.into_iter().flatten().collect();
    all.extend(mesh.vertices.iter().map(|&p| SurfacePoint {
        p,
        face: VERTEX_POINT,
    }));
    all
}

/// Per-camera data for visibility queries.
struct CamInfo {
    center_world: V3,
    center_rig: Vec3A,
}

impl SimScene {
    /// Outward unit normal of face `f` in world coordinates (f64).
    fn face_normal_world(&self, f: u32) -> V3 {
        let m = &self.mesh_world;
        let [a, b, c] = m.faces[f as usize].map(|i| m.vertices[i as usize].map(|x| x as f64));
        let n = cross(sub(b, a), sub(c, a));
        let l = dot(n, n).sqrt();
        n.map(|x| x / l)
    }

    /// Whether camera `view` sees world point `pt` (see the module doc), and the rays it cast
    /// and back-facing skips it made.
    pub fn sees(&self, view: usize, pt: &SurfacePoint) -> (bool, u64, u64) {
        let cam = &self.cameras[view];
        let info = CamInfo {
            center_world: cam.center.into(),
            center_rig: {
                let c = self.camera_center_rig(view);
                Vec3A::new(c.x as f32, c.y as f32, c.z as f32)
            },
        };
        self.sees_with(view, &info, pt)
    }

    fn sees_with(&self, view: usize, info: &CamInfo, pt: &SurfacePoint) -> (bool, u64, u64) {
        let cam = &self.cameras[view];
        let pw = pt.p.map(|c| c as f64);
        let Some((u, v, _)) = cam.project(&Vector3::from(pw)) else {
            return (false, 0, 0);
        };
        if !(u >= 0.0 && v >= 0.0 && u < cam.width as f64 && v < cam.height as f64) {
            return (false, 0, 0);
        }
        if self.closed_oriented && pt.face != VERTEX_POINT {
            let n = self.face_normal_world(pt.face);
            if dot(n, sub(info.center_world, pw)) <= 0.0 {
                return (false, 0, 1);
            }
        }
        let pr = self.frame.to_rig(&Vector3::from(pw));
        let pr = Vec3A::new(pr.x as f32, pr.y as f32, pr.z as f32);
        let to = pr - info.center_rig;
        let dist = to.length();
        let tmax = dist - self.desc.gt.occlusion_eps_mm as f32;
        if tmax <= 0.0 {
            return (true, 0, 0);
        }
        let blocked = self
            .object_tracer
            .occluded(info.center_rig, to / dist, 0.0, tmax);
        (!blocked, 1, 0)
    }

    /// Samples the surface at `gt.spacing_mm`, keeps the visible points, and builds the
    /// observation mask and plane.
    pub fn ground_truth(&self) -> GroundTruth {
        let samples = sample_surface(self, self.desc.gt.spacing_mm);
        let infos: Vec<CamInfo> = (0..self.cameras.len())
            .map(|i| {
                let c = self.camera_center_rig(i);
                CamInfo {
                    center_world: self.cameras[i].center.into(),
                    center_rig: Vec3A::new(c.x as f32, c.y as f32, c.z as f32),
                }
            })
            .collect();
        let n_cam = self.cameras.len();
        // Per chunk: the visible flags and counts. Each chunk starts its camera search at the
        // camera that saw its previous point (points of a chunk are neighbours on the surface);
        // this changes only the cost, never the answer.
        let chunks: Vec<(Vec<bool>, u64, u64)> = samples
            .par_chunks(1024)
            .map(|chunk| {
                let mut flags = Vec::with_capacity(chunk.len());
                let (mut rays, mut skips) = (0u64, 0u64);
                let mut start = 0usize;
                for pt in chunk {
                    let mut seen = false;
                    for k in 0..n_cam {
                        let view = (start + k) % n_cam;
                        let (vis, r, s) = self.sees_with(view, &infos[view], pt);
                        rays += r;
                        skips += s;
                        if vis {
                            seen = true;
                            start = view;
                            break;
                        }
                    }
                    flags.push(seen);
                }
                (flags, rays, skips)
            })
            .collect();
        let mut stats = GtStats {
            sampled: samples.len() as u64,
            ..GtStats::default()
        };
        let mut points = Vec::new();
        let mut flags = chunks.iter().flat_map(|c| c.0.iter());
        for s in &samples {
            if *flags.next().expect("one flag per sample") {
                points.push(s.p);
            }
        }
        for c in &chunks {
            stats.occlusion_rays += c.1;
            stats.backfacing_skips += c.2;
        }
        stats.visible = points.len() as u64;
        let plane = self.plane;
        let (obs_mask, tested, obs_rays) = observation_mask(
            &points,
            self.desc.gt.obs_res_mm,
            self.desc.gt.obs_dilate_mm,
            |c| {
                if plane.eval(c) <= 0.0 {
                    return (false, 0);
                }
                self.free_point_seen(c)
            },
        );
        stats.obs_voxels = obs_mask.data.iter().filter(|&&b| b).count() as u64;
        stats.obs_tested = tested;
        stats.obs_rays = obs_rays;
        GroundTruth {
            points,
            obs_mask,
            plane: self.plane,
            stats,
        }
    }
}

/// The DTU voxel index of `p`: `round_half_even((p − BB₀)/Res)` per axis (may be out of range).
pub fn voxel_index(p: [f32; 3], bb0: [f64; 3], res: f64) -> [i64; 3] {
    std::array::from_fn(|k| ((p[k] as f64 - bb0[k]) / res).round_ties_even() as i64)
}

/// The observation mask of visible surface `points` (see the module doc): surface voxels, plus
/// the voxels within `dilate` of them whose centre `seen(centre) -> (seen, rays cast)` accepts.
/// Returns the mask, the number of centres tested and the rays cast. An empty point set gives a
/// 1×1×1 unobserved grid at the origin.
pub fn observation_mask(
    points: &[[f32; 3]],
    res: f64,
    dilate: f64,
    seen: impl Fn([f64; 3]) -> (bool, u64) + Sync,
) -> (ObsMask, u64, u64) {
    if points.is_empty() {
        let empty = ObsMask {
            dims: [1, 1, 1],
            data: vec![false],
            bb: [[0.0; 3], [0.0; 3]],
            res,
        };
        return (empty, 0, 0);
    }
    let pad = dilate + res;
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k] as f64);
            hi[k] = hi[k].max(p[k] as f64);
        }
    }
    let bb0: [f64; 3] = std::array::from_fn(|k| lo[k] - pad);
    let dims: [usize; 3] =
        std::array::from_fn(|k| ((hi[k] + pad - bb0[k]) / res).ceil() as usize + 1);
    let bb1: [f64; 3] = std::array::from_fn(|k| bb0[k] + (dims[k] - 1) as f64 * res);
    let [nx, ny, nz] = dims;
    let at = |i: i64, j: i64, k: i64| (i as usize) + nx * ((j as usize) + ny * (k as usize));
    let mut surface = vec![false; nx * ny * nz];
    for p in points {
        let [i, j, k] = voxel_index(*p, bb0, res);
        surface[at(i, j, k)] = true;
    }
    // The band: every voxel within `dilate` of a surface voxel.
    let r = (dilate / res).floor() as i64;
    let ball: Vec<[i64; 3]> = (-r..=r)
        .flat_map(|i| (-r..=r).flat_map(move |j| (-r..=r).map(move |k| [i, j, k])))
        .filter(|[i, j, k]| ((i * i + j * j + k * k) as f64) * res * res <= dilate * dilate)
        .collect();
    let mut band = vec![false; nx * ny * nz];
    for k in 0..nz as i64 {
        for j in 0..ny as i64 {
            for i in 0..nx as i64 {
                if !surface[at(i, j, k)] {
                    continue;
                }
                for [di, dj, dk] in &ball {
                    let (a, b, c) = (i + di, j + dj, k + dk);
                    if a >= 0 && b >= 0 && c >= 0 && a < nx as i64 && b < ny as i64 && c < nz as i64
                    {
                        band[at(a, b, c)] = true;
                    }
                }
            }
        }
    }
    // Test the band's other voxels, one z-slice per task (the result does not depend on order).
    let slices: Vec<(Vec<bool>, u64, u64)> = (0..nz)
        .into_par_iter()
        .map(|k| {
            let mut out = vec![false; nx * ny];
            let (mut tested, mut rays) = (0u64, 0u64);
            for j in 0..ny {
                for i in 0..nx {
                    let idx = at(i as i64, j as i64, k as i64);
                    if surface[idx] {
                        out[i + nx * j] = true;
                    } else if band[idx] {
                        let c = [
                            bb0[0] + i as f64 * res,
                            bb0[1] + j as f64 * res,
                            bb0[2] + k as f64 * res,
                        ];
                        let (ok, n) = seen(c);
                        tested += 1;
                        rays += n;
                        out[i + nx * j] = ok;
                    }
                }
            }
            (out, tested, rays)
        })
        .collect();
    let tested = slices.iter().map(|s| s.1).sum();
    let rays = slices.iter().map(|s| s.2).sum();
    let data = slices.into_iter().flat_map(|s| s.0).collect();
    (
        ObsMask {
            dims,
            data,
            bb: [bb0, bb1],
            res,
        },
        tested,
        rays,
    )
}

impl SimScene {
    /// Whether a camera sees the free-space point `c` (world mm): outside the solid (closed
    /// meshes: the first surface hit by a ray from `c` towards the first camera is a front face;
    /// a point inside sees a back face first), inside some image, in front of that camera, and
    /// with no surface on the line of sight. Returns the answer and the rays cast.
    pub fn free_point_seen(&self, c: [f64; 3]) -> (bool, u64) {
        let pr = self.frame.to_rig(&Vector3::from(c));
        let p = Vec3A::new(pr.x as f32, pr.y as f32, pr.z as f32);
        let mut rays = 0;
        if self.closed_oriented {
            let target = self.camera_center_rig(0);
            let target = Vec3A::new(target.x as f32, target.y as f32, target.z as f32);
            let d = (target - p).normalize();
            rays += 1;
            if let Some((tri, _)) = self.object_tracer.closest(p, d) {
                if self.object_tris[tri as usize].compute_normal().dot(d) > 0.0 {
                    return (false, rays);
                }
            }
        }
        for (view, cam) in self.cameras.iter().enumerate() {
            let Some((u, v, _)) = cam.project(&Vector3::from(c)) else {
                continue;
            };
            if !(u >= 0.0 && v >= 0.0 && u < cam.width as f64 && v < cam.height as f64) {
                continue;
            }
            let o = self.camera_center_rig(view);
            let o = Vec3A::new(o.x as f32, o.y as f32, o.z as f32);
            let to = p - o;
            let dist = to.length();
            rays += 1;
            let tmax = dist - self.desc.gt.occlusion_eps_mm as f32;
            if tmax <= 0.0 || !self.object_tracer.occluded(o, to / dist, 0.0, tmax) {
                return (true, rays);
            }
        }
        (false, rays)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_grid_has_the_right_density_and_stays_inside() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [3.0, 8.0, 0.0]);
        let mut out = Vec::new();
        sample_triangle(a, b, c, 0.1, &mut out);
        // Area 40 mm² at 0.01 mm² per point.
        let n = out.len() as f64;
        assert!((n - 4000.0).abs() < 4000.0 * 0.03, "{n} points");
        for p in &out {
            // Inside: all three edge functions non-negative (z = 0 plane, CCW).
            let e = |u: V3, v: V3| (v[0] - u[0]) * (p[1] - u[1]) - (v[1] - u[1]) * (p[0] - u[0]);
            assert!(
                e(a, b) >= -1e-12 && e(b, c) >= -1e-12 && e(c, a) >= -1e-12,
                "{p:?}"
            );
            assert_eq!(p[2], 0.0);
        }
        // A thin sliver still gets points along its length.
        let mut sliver = Vec::new();
        sample_triangle(
            [0.0; 3],
            [50.0, 0.0, 0.0],
            [25.0, 0.5, 0.0],
            0.2,
            &mut sliver,
        );
        let max_gap = {
            let mut xs: Vec<f64> = sliver.iter().map(|p| p[0]).collect();
            xs.sort_by(f64::total_cmp);
            xs.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max)
        };
        assert!(!sliver.is_empty() && max_gap <= 0.2 + 1e-9, "gap {max_gap}");
    }

    #[test]
    fn observation_mask_keeps_surface_voxels_and_seen_band_voxels_in_dtu_indexing() {
        let pts = [[10.0f32, 20.0, 30.0], [14.0, 20.0, 30.0]];
        // "Seen" = the half-space y < 20 (in front of the points); everything is tested once.
        let (m, tested, rays) = observation_mask(&pts, 1.0, 2.0, |c| (c[1] < 20.0, 1));
        assert_eq!(m.data.len(), m.dims.iter().product::<usize>());
        assert_eq!(tested, rays);
        // Each point's own voxel is observed even though its centre is not "seen".
        let idx = voxel_index(pts[0], m.bb[0], m.res);
        assert!(m.get(idx[0], idx[1], idx[2]));
        // Within 2 voxels: observed in front (y − 2), not behind (y + 2); 3 away: never.
        assert!(m.get(idx[0], idx[1] - 2, idx[2]));
        assert!(!m.get(idx[0], idx[1] + 2, idx[2]));
        assert!(!m.get(idx[0], idx[1] - 3, idx[2]));
        // (0, −2, 1) is √5 > 2 voxels away.
        assert!(!m.get(idx[0], idx[1] - 2, idx[2] + 1));
        // The band has 2·(ball of radius 2 = 33 voxels) minus the surface voxels, minus overlap.
        assert!(tested > 33 && tested < 66, "{tested}");
        // BB is padded by dilation + one voxel and spans whole voxels.
        assert_eq!(m.bb[0], [7.0, 17.0, 27.0]);
        for k in 0..3 {
            let span = m.bb[1][k] - m.bb[0][k];
            assert_eq!(span, (m.dims[k] - 1) as f64 * m.res);
        }
        assert!(m.bb[1][0] >= 14.0 + 3.0);
    }
}
