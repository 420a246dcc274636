//! Deterministic surface sampling of a triangle mesh, as DTU's MATLAB `MeshSupSamp` and
//! jzhangbs/DTUeval-python `eval.py` (`sample_single_tri` and the lines before it) do it.
//!
//! The rule, for each triangle `q0, q1, q2` (all arithmetic in `f64` on the `f32` vertices, in the
//! same operation order as the numpy reference so that the samples are bit-identical to it):
//! - `v1 = q1 - q0`, `v2 = q2 - q0`, `l1 = |v1|`, `l2 = |v2|`, `A2 = |v1 × v2|` (twice the area);
//!   triangles with `A2 = 0` (or not `> 0`) are skipped;
//! - `thr = density · sqrt(l1·l2 / A2)`, `n1 = floor(l1 / thr)`, `n2 = floor(l2 / thr)`;
//! - for `c1` in `0..=n1` and `c2` in `0..=n2` (the reference's `np.mgrid[:n1+1, :n2+1]`, `c1`
//!   outer), `k1 = (c1 + 0.5) / n1`, `k2 = (c2 + 0.5) / n2`; a point `(v1·k1 + v2·k2) + q0` is
//!   emitted when `k1 + k2 < 1` (strict). When `n1` or `n2` is 0 the reference divides by `1e-7`,
//!   which makes `k` huge: such triangles emit nothing.
//!
//! The sample set is **all mesh vertices first** (unreferenced ones included), then the samples in
//! face order (the reference's `np.concatenate([vertices, new_pts])`). Samples are rounded to
//! `f32` (the reference keeps `float64`; the rounding is below 4e-5 mm at DTU's 1 m scale, 200×
//! finer than the 0.2 mm density).

use crate::mesh::TriMesh;
use rayon::prelude::*;

/// Faces per rayon task.
const FACES_PER_TASK: usize = 4096;

/// The per-triangle grid sizes `(n1, n2)` of the rule above, or `None` for a degenerate triangle
/// (`A2` not `> 0`).
#[inline]
fn grid_size(q0: [f64; 3], q1: [f64; 3], q2: [f64; 3], density: f64) -> Option<(f64, f64)> {
    let v1 = sub(q1, q0);
    let v2 = sub(q2, q0);
    let l1 = norm(v1);
    let l2 = norm(v2);
    let a2 = norm(cross(v1, v2));
    // Skips A2 = 0 (and NaN, which the mesh validation excludes anyway): the reference's
    // `area2 > 0` filter.
    if a2.is_nan() || a2 <= 0.0 {
        return None;
    }
    let thr = density * (l1 * l2 / a2).sqrt();
    Some(((l1 / thr).floor(), (l2 / thr).floor()))
}

/// Appends the samples of one triangle (not its vertices) to `out`.
fn sample_triangle(q: [[f32; 3]; 3], density: f64, out: &mut Vec<[f32; 3]>) {
    let [q0, q1, q2] = q.map(|v| v.map(f64::from));
    let Some((n1, n2)) = grid_size(q0, q1, q2, density) else {
        return;
    };
    if n1 < 1.0 || n2 < 1.0 {
        return;
    }
    let v1 = sub(q1, q0);
    let v2 = sub(q2, q0);
    let (m1, m2) = (n1 as u64, n2 as u64);
    for c1 in 0..=m1 {
        let k1 = (c1 as f64 + 0.5) / n1;
        if k1 >= 1.0 {
            break; // k2 > 0, so no c2 can pass; k1 grows with c1.
        }
        for c2 in 0..=m2 {
            let k2 = (c2 as f64 + 0.5) / n2;
            if k1 + k2 >= 1.0 {
                // k1 + k2 grows with c2 (non-decreasing in floating point as well).
                break;
            }
            out.push(std::array::from_fn(|i| {
                ((v1[i] * k1 + v2[i] * k2) + q0[i]) as f32
            }));
        }
    }
}

/// An upper bound on the number of points [`sample_mesh`] returns, computed cheaply (the
/// vertices plus `(n1+1)(n2+1)/2 + n1 + n2 + 1` per triangle), to refuse meshes whose sampling
/// would not fit in memory (typically a mesh in the wrong unit).
pub fn sample_count_bound(mesh: &TriMesh, density: f64) -> u64 {
    let faces: u64 = mesh
        .faces
        .par_iter()
        .map(|f| {
            let [q0, q1, q2] = f.map(|i| mesh.vertices[i as usize].map(f64::from));
            match grid_size(q0, q1, q2, density) {
                Some((n1, n2)) if n1 >= 1.0 && n2 >= 1.0 => {
                    let b = (n1 + 1.0) * (n2 + 1.0) / 2.0 + n1 + n2 + 1.0;
                    if b < 1e18 {
                        b as u64
                    } else {
                        u64::MAX / 4
                    }
                }
                _ => 0,
            }
        })
        .reduce(|| 0, |a, b| a.saturating_add(b));
    faces.saturating_add(mesh.vertices.len() as u64)
}

/// Samples `mesh` (world mm for DTU) at `density` (mm; DTU uses 0.2) with the rule in the module
/// doc: `[n_vertices + n_samples][3]`, vertices first, then the samples in face order.
/// Deterministic (no randomness; parallel over faces with an ordered merge).
/// The mesh must be valid ([`TriMesh::validate`]); `density` must be finite and `> 0`.
pub fn sample_mesh(mesh: &TriMesh, density: f64) -> Vec<[f32; 3]> {
    assert!(density.is_finite() && density > 0.0, "density {density}");
    let chunks: Vec<Vec<[f32; 3]>> = mesh
        .faces
        .par_chunks(FACES_PER_TASK)
        .map(|faces| {
            let mut out = Vec::new();
            for f in faces {
                let q = f.map(|i| mesh.vertices[i as usize]);
                sample_triangle(q, density, &mut out);
            }
            out
        })
        .collect();
    let total = mesh.vertices.len() + chunks.iter().map(Vec::len).sum::<usize>();
    let mut points = Vec::with_capacity(total);
    points.extend_from_slice(&mesh.vertices);
    for c in chunks {
        points.extend_from_slice(&c);
    }
    points
}

#[inline]
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `np.cross` order: `[a1·b2 − a2·b1, a2·b0 − a0·b2, a0·b1 − a1·b0]`.
#[inline]
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `np.linalg.norm` order: `sqrt((x² + y²) + z²)`.
#[inline]
fn norm(a: [f64; 3]) -> f64 {
    ((a[0] * a[0] + a[1] * a[1]) + a[2] * a[2]).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(vertices: Vec<[f32; 3]>) -> TriMesh {
        TriMesh {
            vertices,
            faces: vec![[0, 1, 2]],
        }
    }

    /// A plain transcription of the rule (every `c1, c2` in the full grid, no early exits).
    fn reference(mesh: &TriMesh, density: f64) -> Vec<[f32; 3]> {
        let mut out = mesh.vertices.clone();
        for f in &mesh.faces {
            let [q0, q1, q2] = f.map(|i| mesh.vertices[i as usize].map(f64::from));
            let v1 = sub(q1, q0);
            let v2 = sub(q2, q0);
            let (l1, l2, a2) = (norm(v1), norm(v2), norm(cross(v1, v2)));
            if a2.is_nan() || a2 <= 0.0 {
                continue;
            }
            let thr = density * (l1 * l2 / a2).sqrt();
            let (n1, n2) = ((l1 / thr).floor(), (l2 / thr).floor());
            let mut c1 = 0.0;
            while c1 <= n1 {
                let mut c2 = 0.0;
                while c2 <= n2 {
                    let k1 = (c1 + 0.5) / n1.max(1e-7);
                    let k2 = (c2 + 0.5) / n2.max(1e-7);
                    if k1 + k2 < 1.0 {
                        out.push(std::array::from_fn(|i| {
                            ((v1[i] * k1 + v2[i] * k2) + q0[i]) as f32
                        }));
                    }
                    c2 += 1.0;
                }
                c1 += 1.0;
            }
        }
        out
    }

    #[test]
    fn right_triangle_counts_by_hand() {
        // Legs of 1 mm at density 0.2: thr = 0.2, n1 = n2 = 5, k = 0.1, 0.3, ..., 1.1; pairs with
        // k1 + k2 < 1 are c1 + c2 <= 3: 1 + 2 + 3 + 4 = 10 samples, plus the 3 vertices.
        let m = tri(vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        let s = sample_mesh(&m, 0.2);
        assert_eq!(s.len(), 13);
        assert_eq!(&s[..3], &m.vertices[..]);
        assert_eq!(s[3], [0.1, 0.1, 0.0]);
        assert_eq!(s[4], [0.1, 0.3, 0.0]);
        // Every sample lies strictly inside the triangle.
        assert!(s[3..]
            .iter()
            .all(|p| p[0] > 0.0 && p[1] > 0.0 && p[0] + p[1] < 1.0));
    }

    #[test]
    fn small_and_degenerate_triangles_give_only_vertices() {
        // Legs shorter than the density: n1 = n2 = 0.
        let m = tri(vec![[0.0; 3], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0]]);
        assert_eq!(sample_mesh(&m, 0.2).len(), 3);
        // n1 = n2 = 1: k = 0.5, 1.5, and 0.5 + 0.5 = 1 is not < 1.
        let m = tri(vec![[0.0; 3], [0.3, 0.0, 0.0], [0.0, 0.3, 0.0]]);
        assert_eq!(sample_mesh(&m, 0.2).len(), 3);
        // Collinear and repeated vertices: A2 = 0.
        let m = tri(vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]);
        assert_eq!(sample_mesh(&m, 0.2).len(), 3);
        let m = tri(vec![[5.0; 3], [5.0; 3], [5.0; 3]]);
        assert_eq!(sample_mesh(&m, 0.2).len(), 3);
    }

    #[test]
    fn matches_plain_transcription_on_random_meshes() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(11);
        let n = 200;
        let vertices: Vec<[f32; 3]> = (0..n)
            .map(|_| std::array::from_fn(|_| 300.0 + 4.0 * rng.random::<f32>()))
            .collect();
        let faces: Vec<[u32; 3]> = (0..5000)
            .map(|_| std::array::from_fn(|_| rng.random_range(0..n as u32)))
            .collect();
        let m = TriMesh { vertices, faces };
        let fast = sample_mesh(&m, 0.2);
        assert_eq!(fast, reference(&m, 0.2));
        assert!(fast.len() > 10 * n, "{} samples", fast.len());
        assert!(sample_count_bound(&m, 0.2) >= fast.len() as u64);
    }
}
