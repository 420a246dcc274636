//! Synthetic DTU-style fixtures, so tests never need real DTU data.
//!
//! The "scan": ground-truth points quasi-uniformly spread (Fibonacci lattice) on a sphere of
//! radius `R` around a DTU-like centre (world mm), an observation mask that marks the upper part
//! of the sphere's box as observed except for one unobserved slab, and a tilted ground plane
//! that cuts off the bottom of the sphere. Meshes are UV spheres around the same centre.
#![allow(dead_code)]

use dtu_eval::gt::{GtPaths, ObsMask, Plane};
use dtu_eval::TriMesh;
use std::path::Path;

/// Sphere centre (world mm), as far from the origin as DTU's objects are.
pub const CENTRE: [f64; 3] = [-30.0, 40.0, 620.0];
/// Ground-truth sphere radius (mm).
pub const RADIUS: f64 = 12.0;
/// Observation-mask voxel (mm).
pub const RES: f64 = 1.0;

/// `n` points of a Fibonacci lattice on the sphere `(centre, radius)`.
pub fn fibonacci_sphere(n: usize, centre: [f64; 3], radius: f64) -> Vec<[f32; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            let d = [r * phi.cos(), r * phi.sin(), z];
            std::array::from_fn(|k| (centre[k] + radius * d[k]) as f32)
        })
        .collect()
}

/// A UV sphere with `n_lat` latitude bands and `n_lon` longitudes, outward-facing.
pub fn uv_sphere(centre: [f64; 3], radius: f64, n_lat: usize, n_lon: usize) -> TriMesh {
    let mut vertices = vec![[
        centre[0] as f32,
        centre[1] as f32,
        (centre[2] + radius) as f32,
    ]];
    for i in 1..n_lat {
        let theta = std::f64::consts::PI * i as f64 / n_lat as f64;
        for j in 0..n_lon {
            let phi = 2.0 * std::f64::consts::PI * j as f64 / n_lon as f64;
            let d = [
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ];
            vertices.push(std::array::from_fn(|k| (centre[k] + radius * d[k]) as f32));
        }
    }
    vertices.push([
        centre[0] as f32,
        centre[1] as f32,
        (centre[2] - radius) as f32,
    ]);
    let south = (vertices.len() - 1) as u32;
    let ring = |i: usize, j: usize| (1 + (i - 1) * n_lon + j % n_lon) as u32;
    let mut faces = Vec::new();
    for j in 0..n_lon {
        faces.push([0, ring(1, j), ring(1, j + 1)]);
        faces.push([south, ring(n_lat - 1, j + 1), ring(n_lat - 1, j)]);
    }
    for i in 1..n_lat - 1 {
        for j in 0..n_lon {
            let (a, b, c, d) = (
                ring(i, j),
                ring(i, j + 1),
                ring(i + 1, j),
                ring(i + 1, j + 1),
            );
            faces.push([a, c, b]);
            faces.push([b, c, d]);
        }
    }
    TriMesh { vertices, faces }
}

/// The fixture's observation mask: box = sphere box grown by 4 mm; voxels observed when their
/// centre is above `centre.z − R/2` and not in the slab `x > centre.x + R/2`.
pub fn obs_mask() -> ObsMask {
    let margin = RADIUS + 4.0;
    let bb0 = CENTRE.map(|c| c - margin);
    let bb1 = CENTRE.map(|c| c + margin);
    let dims: [usize; 3] = std::array::from_fn(|k| ((bb1[k] - bb0[k]) / RES).round() as usize + 1);
    let mut data = vec![false; dims.iter().product()];
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let x = bb0[0] + i as f64 * RES;
                let z = bb0[2] + k as f64 * RES;
                data[i + dims[0] * (j + dims[1] * k)] =
                    z > CENTRE[2] - RADIUS / 2.0 && x <= CENTRE[0] + RADIUS / 2.0;
            }
        }
    }
    ObsMask {
        dims,
        data,
        bb: [bb0, bb1],
        res: RES,
    }
}

/// The fixture's plane: tilted, through `centre − 0.6·R·ẑ`; points above it have positive value.
pub fn plane() -> Plane {
    let n = [0.1f64, -0.05, 1.0];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let n = n.map(|v| v / len);
    let p0 = [CENTRE[0], CENTRE[1], CENTRE[2] - 0.6 * RADIUS];
    Plane([
        n[0],
        n[1],
        n[2],
        -(n[0] * p0[0] + n[1] * p0[1] + n[2] * p0[2]),
    ])
}

/// Writes the fixture's ground truth (`n_gt` points) for `scan` under `root`.
pub fn write_gt(root: &Path, scan: u32, n_gt: usize) -> GtPaths {
    let paths = GtPaths::new(root, scan);
    std::fs::create_dir_all(paths.points.parent().unwrap()).unwrap();
    let pts = fibonacci_sphere(n_gt, CENTRE, RADIUS);
    dtu_eval::ply::write_points(&paths.points, &pts, None).unwrap();
    obs_mask().write(&paths.obs_mask).unwrap();
    plane().write(&paths.plane).unwrap();
    paths
}

/// Isolated vertices (no faces: still part of the sample set) placed where the filter's exact
/// semantics decide: voxel coordinates exactly half-way between an observed and an unobserved
/// voxel (`np.around` rounds half to even), and the box's bounds (`>=` below, `<` above).
pub fn probe_vertices() -> Vec<[f32; 3]> {
    let m = RADIUS + 4.0; // the mask box's margin: BB0 = CENTRE - m, BB1 = CENTRE + m
    let (cx, cy, cz) = (CENTRE[0], CENTRE[1], CENTRE[2]);
    let x_obs_edge = (cx + RADIUS / 2.0) - (cx - m); // last observed x voxel (22 here)
    let z_obs_edge = (cz - RADIUS / 2.0) - (cz - m); // last unobserved z voxel (10 here)
    [
        [cx - m + x_obs_edge + 0.5, cy, cz], // 22.5 -> 22, observed (23 would not be)
        [cx - m + x_obs_edge - 1.5, cy, cz], // 20.5 -> 20, observed either way
        [cx, cy, cz - m + z_obs_edge + 0.5], // 10.5 -> 10, unobserved (11 would be)
        [cx, cy, cz - m + z_obs_edge + 1.5], // 11.5 -> 12, observed
        [cx - m - 60.0, cy, cz],             // lower box bound: inside (>=)
        [cx + m + 120.0, cy, cz],            // upper box bound: outside (<)
        [cx + m + 119.5, cy, cz],            // just inside the upper bound
    ]
    .into_iter()
    .map(|p: [f64; 3]| p.map(|v| v as f32))
    .collect()
}

/// A mesh to score: a UV sphere of radius `R + offset`, plus two floaters (one inside the
/// box-with-patch but outside the mask grid, one far outside the box) and the
/// [`probe_vertices`].
pub fn test_mesh(offset: f64, n_lat: usize, n_lon: usize) -> TriMesh {
    let mut m = uv_sphere(CENTRE, RADIUS + offset, n_lat, n_lon);
    for shift in [[0.0, 0.0, RADIUS + 25.0], [400.0, 0.0, 0.0]] {
        let c: [f64; 3] = std::array::from_fn(|k| CENTRE[k] + shift[k]);
        let base = m.vertices.len() as u32;
        let f = uv_sphere(c, 2.0, 6, 12);
        m.vertices.extend(f.vertices);
        m.faces.extend(f.faces.iter().map(|t| t.map(|i| i + base)));
    }
    m.vertices.extend(probe_vertices());
    m
}
