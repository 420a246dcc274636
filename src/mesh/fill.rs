//! Fills the free space that no camera sees, in grid values before marching cubes.
//!
//! A trained SDF can hold pockets of "outside" (values above the iso level) that no image could
//! have shown: closed voids inside the material, and tunnels through a wall that no view looks
//! through. Where such a pocket reaches the surface it is a handle. Space carving's argument is
//! that free space has to be seen to be free: the photo hull, the largest shape consistent with
//! the images, keeps every point that no camera sees in front of a surface (Kutulakos & Seitz,
//! *A Theory of Shape by Space Carving*, IJCV 2000, §2 and §4). The rule here applies it to the
//! pockets of the level set, not to the open space around the object:
//!
//! 1. the raw level set of the values (marching cubes) is ray cast from every camera into a
//!    depth map: the depth along the optical axis of the first surface, `∞` where a ray hits
//!    nothing, one ray per cell of `s × s` pixels with `s` the smallest step that keeps the map
//!    at most [`MAX_MAP_WIDTH`] cells wide;
//! 2. a grid point outside the level set is **seen** when some camera has it in front of the
//!    camera plane and inside its image, at a depth below the farthest surface depth of the
//!    3 × 3 map cells around its projection plus one cell diagonal of the grid. The test is
//!    lenient on purpose: a point next to a seen face, or past a rod's silhouette, counts as
//!    seen, so a seen surface never moves;
//! 3. the points outside and unseen are split into 6-connected regions. A region that reaches a
//!    face of the grid is open to the space around the object (under it, where the cameras do
//!    not look) and is kept. Every other region is enclosed by material and seen space; it is
//!    filled, its values set to half the smallest cell size below the iso level, so that the
//!    surface closes it between its last point and the first seen one.
//!
//! With no camera, or a level set without faces, nothing is filled. The result does not depend
//! on the thread count (every point's test is independent; the regions are visited in index
//! order).

use super::trace::Tracer;
use super::{inside, marching_cubes_values, GridSpec, McError};
use crate::scene::Camera;
use glam::Vec3A;
use nalgebra::{Matrix3x4, Vector3, Vector4};
use obvhs::triangle::Triangle;
use rayon::prelude::*;

/// Widest depth map, in cells: a camera wider than this is sampled every `s` pixels.
pub const MAX_MAP_WIDTH: u32 = 512;

/// What [`fill_unseen`] found and filled.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct FillReport {
    /// Grid points outside the level set.
    pub outside: usize,
    /// Of those, the points no camera sees.
    pub unseen: usize,
    /// Unseen regions enclosed by material and seen space (every one is filled).
    pub regions: usize,
    /// Grid points filled.
    pub filled: usize,
}

/// One camera's depth map of a mesh (module docs, step 1).
struct DepthMap {
    /// `K·[R | −R·C]`.
    p: Matrix3x4<f64>,
    width: f64,
    height: f64,
    /// Pixels per map cell along each axis.
    step: f64,
    w: usize,
    h: usize,
    /// `[h][w]` depth along the optical axis of the first hit, `∞` for none.
    z: Vec<f32>,
}

impl DepthMap {
    fn new(cam: &Camera, tracer: &Tracer) -> Self {
        let step = cam.width.div_ceil(MAX_MAP_WIDTH).max(1);
        let (w, h) = (
            cam.width.div_ceil(step) as usize,
            cam.height.div_ceil(step) as usize,
        );
        let kinv = cam
            .k
            .try_inverse()
            .expect("K is upper triangular with a positive diagonal");
        let rt = cam.r.transpose();
        let o = Vec3A::new(
            cam.center.x as f32,
            cam.center.y as f32,
            cam.center.z as f32,
        );
        let z = (0..w * h)
            .into_par_iter()
            .map(|q| {
                let u = ((q % w) as f64 + 0.5) * step as f64;
                let v = ((q / w) as f64 + 0.5) * step as f64;
                // Camera-frame direction with z = 1: the hit's depth is t / |d|.
                let d = kinv * Vector3::new(u, v, 1.0);
                let n = d.norm();
                let dw = rt * d / n;
                match tracer.closest(o, Vec3A::new(dw.x as f32, dw.y as f32, dw.z as f32)) {
                    Some((_, t)) => (t as f64 / n) as f32,
                    None => f32::INFINITY,
                }
            })
            .collect();
        Self {
            p: cam.projection(),
            width: cam.width as f64,
            height: cam.height as f64,
            step: step as f64,
            w,
            h,
            z,
        }
    }

    /// Whether the camera sees `x` as free space (module docs, step 2), `tol` in the frame's
    /// units.
    fn sees(&self, x: &Vector3<f64>, tol: f32) -> bool {
        let q = self.p * Vector4::new(x.x, x.y, x.z, 1.0);
        if q.z <= 0.0 {
            return false;
        }
        let (u, v) = (q.x / q.z, q.y / q.z);
        if !(u >= 0.0 && v >= 0.0 && u < self.width && v < self.height) {
            return false;
        }
        let (mx, my) = (
            ((u / self.step) as usize).min(self.w - 1),
            ((v / self.step) as usize).min(self.h - 1),
        );
        let mut far = f32::NEG_INFINITY;
        for y in my.saturating_sub(1)..=(my + 1).min(self.h - 1) {
            for x in mx.saturating_sub(1)..=(mx + 1).min(self.w - 1) {
                far = far.max(self.z[y * self.w + x]);
            }
        }
        (q.z as f32) < far + tol
    }
}

/// Point states during the fill.
const INSIDE: u8 = 0;
const SEEN: u8 = 1;
const UNSEEN: u8 = 2;
const VISITED: u8 = 3;

/// Fills, in place, the regions of `values` (`[k][j][i]`, x fastest, on `grid`) that lie outside
/// the level set `iso`, that no camera of `cameras` sees, and that do not reach a face of the
/// grid (module docs). `cameras` are in the grid's frame (normalised space in `reconstruct`).
///
/// Errors: those of marching cubes on the values (a grid that does not match, a NaN value).
pub fn fill_unseen(
    values: &mut [f32],
    grid: &GridSpec,
    iso: f32,
    cameras: &[&Camera],
) -> Result<FillReport, McError> {
    let mesh = marching_cubes_values(values, grid, iso)?;
    let outside = values.iter().filter(|&&v| !inside(v, iso)).count();
    let mut rep = FillReport {
        outside,
        ..FillReport::default()
    };
    if cameras.is_empty() || mesh.faces.is_empty() {
        return Ok(rep);
    }
    let vx = |i: u32| Vec3A::from(mesh.vertices[i as usize]);
    let tris: Vec<Triangle> = mesh
        .faces
        .iter()
        .map(|f| Triangle {
            v0: vx(f[0]),
            v1: vx(f[1]),
            v2: vx(f[2]),
        })
        .collect();
    let tracer = Tracer::new(&tris);
    let maps: Vec<DepthMap> = cameras.iter().map(|c| DepthMap::new(c, &tracer)).collect();
    let cell = grid.cell_size();
    let tol = cell.iter().map(|c| c * c).sum::<f32>().sqrt();
    let coords = [grid.coords(0), grid.coords(1), grid.coords(2)];
    let [nx, ny, nz] = grid.res;
    let mut state: Vec<u8> = values
        .par_iter()
        .enumerate()
        .map(|(q, &v)| {
            if inside(v, iso) {
                return INSIDE;
            }
            let x = Vector3::new(
                coords[0][q % nx],
                coords[1][(q / nx) % ny],
                coords[2][q / (nx * ny)],
            );
            if maps.iter().any(|m| m.sees(&x, tol)) {
                SEEN
            } else {
                UNSEEN
            }
        })
        .collect();
    rep.unseen = state.iter().filter(|&&s| s == UNSEEN).count();
    let fill_value = iso - 0.5 * cell.iter().copied().fold(f32::INFINITY, f32::min);
    let mut region = Vec::new();
    for start in 0..state.len() {
        if state[start] != UNSEEN {
            continue;
        }
        state[start] = VISITED;
        region.clear();
        region.push(start);
        let mut open = false;
        let mut next = 0;
        while next < region.len() {
            let q = region[next];
            next += 1;
            let (i, j, k) = (q % nx, (q / nx) % ny, q / (nx * ny));
            open |= i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1;
            let neighbours = [
                (i > 0).then(|| q - 1),
                (i + 1 < nx).then(|| q + 1),
                (j > 0).then(|| q - nx),
                (j + 1 < ny).then(|| q + nx),
                (k > 0).then(|| q - nx * ny),
                (k + 1 < nz).then(|| q + nx * ny),
            ];
            for n in neighbours.into_iter().flatten() {
                if state[n] == UNSEEN {
                    state[n] = VISITED;
                    region.push(n);
                }
            }
        }
        if !open {
            rep.regions += 1;
            rep.filled += region.len();
            for &q in &region {
                values[q] = fill_value;
            }
        }
    }
    Ok(rep)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{sample_grid, McOptions, TopologyReport};
    use crate::scene::camera::{centred_intrinsics, look_at};

    /// A camera 3 units from the origin along `dir`, looking at it, 96 × 96 pixels, `f` = 120.
    fn cam(dir: [f64; 3]) -> Camera {
        let d = Vector3::from(dir).normalize();
        let up = if d.z.abs() > 0.9 {
            Vector3::y()
        } else {
            Vector3::z()
        };
        look_at(
            d * 3.0,
            Vector3::zeros(),
            up,
            centred_intrinsics(120.0, 96, 96),
            96,
            96,
        )
    }

    /// The slab `|x|, |y| ≤ 0.5, |z| ≤ 0.25` with, when `void`, a ball of radius 0.12 about
    /// `(0, 0.3, 0)` carved out of it, and, when `tunnel`, a bore of radius 0.1 along x through it.
    fn slab(p: &[[f32; 3]], void: bool, tunnel: bool) -> Vec<f32> {
        p.iter()
            .map(|&[x, y, z]| {
                let q = [x.abs() - 0.5, y.abs() - 0.5, z.abs() - 0.25];
                let out = q.iter().map(|c| c.max(0.0).powi(2)).sum::<f32>().sqrt();
                let mut d = out + q[0].max(q[1]).max(q[2]).min(0.0);
                if void {
                    let y = y - 0.3;
                    d = d.max(0.12 - (x * x + y * y + z * z).sqrt());
                }
                if tunnel {
                    d = d.max(0.1 - (y * y + z * z).sqrt());
                }
                d
            })
            .collect()
    }

    fn values(grid: &GridSpec, void: bool, tunnel: bool) -> Vec<f32> {
        let f = |p: &[[f32; 3]]| slab(p, void, tunnel);
        sample_grid(&f, grid, &McOptions::default()).unwrap()
    }

    /// With nothing to fill (no camera), the in-memory path of `extract_two_pass_filled` gives
    /// the streamed extraction's mesh bit for bit, the closing included.
    #[test]
    fn the_filled_path_without_cameras_is_the_streamed_extraction() {
        use crate::mesh::extract::{extract_two_pass, extract_two_pass_filled, TwoPassOptions};
        let f = |p: &[[f32; 3]]| slab(p, true, true);
        for close_radius in [0, 1] {
            let opts = TwoPassOptions {
                coarse_res: 24,
                fine_res: 40,
                mc: McOptions {
                    close_radius,
                    ..McOptions::default()
                },
                ..TwoPassOptions::default()
            };
            let streamed = extract_two_pass(&f, &opts).unwrap();
            let (filled, rep) = extract_two_pass_filled(&f, &opts, &[]).unwrap();
            assert_eq!(filled, streamed, "close_radius {close_radius}");
            assert_eq!(rep.unwrap().filled, 0);
        }
    }

    fn genus_and_parts(v: &[f32], grid: &GridSpec) -> (i64, usize) {
        let t = TopologyReport::of(&marching_cubes_values(v, grid, 0.0).unwrap());
        assert!(t.is_closed_manifold());
        (t.genus, t.components)
    }

    /// A closed void and a tunnel that no camera looks along are filled (the genus drops to 0,
    /// one part); a camera that looks through the tunnel keeps it open, and the space under and
    /// around the slab, which reaches the grid's faces, is never filled, so the outer surface
    /// does not move.
    #[test]
    fn unseen_voids_and_tunnels_are_filled_and_a_seen_tunnel_stays() {
        let grid = GridSpec::cube([-0.8; 3], [0.8; 3], 49);
        // Cameras above the slab only (none looks along x through the bore, none from below).
        let above: Vec<Camera> = [
            [0.0, 0.0, 1.0],
            [0.6, 0.0, 1.0],
            [0.0, 0.6, 1.0],
            [-0.5, -0.5, 1.0],
        ]
        .into_iter()
        .map(cam)
        .collect();
        let above_refs: Vec<&Camera> = above.iter().collect();

        let raw = values(&grid, true, true);
        assert_eq!(
            genus_and_parts(&raw, &grid),
            (1, 2),
            "a bore and an inner void"
        );
        let mut v = raw.clone();
        let rep = fill_unseen(&mut v, &grid, 0.0, &above_refs).unwrap();
        assert!(rep.regions >= 2 && rep.filled > 0, "{rep:?}");
        assert_eq!(genus_and_parts(&v, &grid), (0, 1), "{rep:?}");
        // The slab's own outside never changes: every changed point was inside the slab.
        for (q, (&a, &b)) in raw.iter().zip(&v).enumerate() {
            if a != b {
                let [nx, ny] = [grid.res[0], grid.res[1]];
                let c = grid.coords(0);
                let (x, y, z) = (c[q % nx], c[(q / nx) % ny], c[q / (nx * ny)]);
                assert!(
                    x.abs() <= 0.5 && y.abs() <= 0.5 && z.abs() <= 0.25,
                    "{x} {y} {z}"
                );
            }
        }

        // A camera looking down the bore: the bore is seen, only the void is filled.
        let mut through = above.clone();
        through.push(cam([1.0, 0.0, 0.0]));
        let refs: Vec<&Camera> = through.iter().collect();
        let mut v = raw.clone();
        let rep = fill_unseen(&mut v, &grid, 0.0, &refs).unwrap();
        assert_eq!(genus_and_parts(&v, &grid), (1, 1), "{rep:?}");

        // A plain slab seen from above: nothing to fill, though its underside is unseen.
        let plain = values(&grid, false, false);
        let mut v = plain.clone();
        let rep = fill_unseen(&mut v, &grid, 0.0, &above_refs).unwrap();
        assert!(rep.unseen > 0 && rep.filled == 0, "{rep:?}");
        assert_eq!(v, plain);
    }

    /// Without cameras, or without a surface, nothing changes; a NaN value is an error.
    #[test]
    fn no_cameras_no_surface_and_nan() {
        let grid = GridSpec::cube([-0.8; 3], [0.8; 3], 17);
        let raw = values(&grid, true, false);
        let mut v = raw.clone();
        let rep = fill_unseen(&mut v, &grid, 0.0, &[]).unwrap();
        assert_eq!((rep.filled, v == raw), (0, true));
        let c = cam([0.0, 0.0, 1.0]);
        let mut empty = vec![1.0f32; grid.n_points()];
        let rep = fill_unseen(&mut empty, &grid, 0.0, &[&c]).unwrap();
        assert_eq!((rep.filled, rep.outside), (0, grid.n_points()));
        let mut nan = raw.clone();
        nan[100] = f32::NAN;
        assert!(matches!(
            fill_unseen(&mut nan, &grid, 0.0, &[&c]),
            Err(McError::NanSdf { .. })
        ));
    }
}
