//! Midpoint subdivision of a triangle mesh, for tests that judge a mesh face by face (the
//! visibility of rule 4 in [`super::clean`] looks at face centroids, so a coarse mesh is judged
//! coarsely).
//!
//! One level splits every triangle `(a, b, c)` into four, `(a, ab, ca)`, `(ab, b, bc)`,
//! `(ca, bc, c)`, `(ab, bc, ca)`, with `ab` the midpoint of edge `a–b`. A midpoint is made once
//! per edge and shared by both faces of the edge, so a closed mesh stays closed, the Euler
//! characteristic and the orientation are kept, and the surface does not move (the new vertices
//! lie on the old faces). Positions are computed in f64 and stored as f32, in the mesh's own
//! frame and units.

use super::TriMesh;
use std::collections::HashMap;

/// Longest edge of the mesh (its units); 0 for a mesh without faces.
pub fn longest_edge(mesh: &TriMesh) -> f64 {
    let p = |i: u32| mesh.vertices[i as usize].map(f64::from);
    let len = |a: [f64; 3], b: [f64; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    mesh.faces
        .iter()
        .flat_map(|f| {
            let (a, b, c) = (p(f[0]), p(f[1]), p(f[2]));
            [len(a, b), len(b, c), len(c, a)]
        })
        .fold(0.0, f64::max)
}

/// One level of midpoint subdivision (module docs): 4 × the faces, `V + E` vertices. The old
/// vertices keep their indices; the midpoints follow in the order their edges are first met.
pub fn subdivide_once(mesh: &TriMesh) -> TriMesh {
    let mut vertices = mesh.vertices.clone();
    let mut mid: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.faces.len() * 3 / 2);
    let mut midpoint = |a: u32, b: u32, vertices: &mut Vec<[f32; 3]>| -> u32 {
        let key = (a.min(b), a.max(b));
        *mid.entry(key).or_insert_with(|| {
            let (pa, pb) = (vertices[a as usize], vertices[b as usize]);
            vertices.push(std::array::from_fn(|k| {
                ((pa[k] as f64 + pb[k] as f64) * 0.5) as f32
            }));
            (vertices.len() - 1) as u32
        })
    };
    let mut faces = Vec::with_capacity(mesh.faces.len() * 4);
    for &[a, b, c] in &mesh.faces {
        let ab = midpoint(a, b, &mut vertices);
        let bc = midpoint(b, c, &mut vertices);
        let ca = midpoint(c, a, &mut vertices);
        faces.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    TriMesh { vertices, faces }
}

/// Subdivides until no edge is longer than `max_edge` or one more level would pass `max_faces`
/// faces (so the result holds at most `max(max_faces, faces)` faces). Returns the mesh and the
/// number of levels applied.
pub fn subdivide_to(mesh: &TriMesh, max_edge: f64, max_faces: usize) -> (TriMesh, u32) {
    let mut m = mesh.clone();
    let mut levels = 0;
    while !m.faces.is_empty()
        && longest_edge(&m) > max_edge
        && m.faces.len().saturating_mul(4) <= max_faces
    {
        m = subdivide_once(&m);
        levels += 1;
    }
    (m, levels)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::clean::surface_area as area;
    use crate::mesh::{marching_cubes, sdf::Shape, GridSpec, McOptions, TopologyReport};

    #[test]
    fn a_closed_torus_stays_closed_in_place_and_oriented() {
        let torus = Shape::named("torus").unwrap();
        let grid = GridSpec::cube([-1.0; 3], [1.0; 3], 20);
        let m = marching_cubes(
            &|p: &[[f32; 3]]| torus.eval_batch(p),
            &grid,
            &McOptions::default(),
        )
        .unwrap();
        let before = TopologyReport::of(&m);
        assert!(before.is_closed_manifold());
        let s = subdivide_once(&m);
        let after = TopologyReport::of(&s);
        assert_eq!(s.faces.len(), 4 * m.faces.len());
        // V + E vertices; for a closed mesh E = 3F/2.
        assert_eq!(s.vertices.len(), m.vertices.len() + 3 * m.faces.len() / 2);
        assert!(after.is_closed_manifold(), "{after:?}");
        assert_eq!(after.euler_characteristic, before.euler_characteristic);
        assert_eq!(after.misoriented_edges, 0);
        assert!((area(&s) - area(&m)).abs() < 1e-5 * area(&m));
        // Every child's normal points the parent's way.
        let n = |m: &TriMesh, f: &[u32; 3]| {
            let p = |i: u32| nalgebra::Vector3::from(m.vertices[i as usize].map(f64::from));
            (p(f[1]) - p(f[0])).cross(&(p(f[2]) - p(f[0])))
        };
        for (i, f) in m.faces.iter().enumerate() {
            for g in &s.faces[4 * i..4 * i + 4] {
                assert!(n(&m, f).dot(&n(&s, g)) > 0.0);
            }
        }
        assert!((longest_edge(&s) - 0.5 * longest_edge(&m)).abs() < 1e-6);
    }

    /// After `L` levels the pieces of face `i` are faces `i·4^L .. (i+1)·4^L`, and they tile it:
    /// each lies in the parent's plane, inside it, and their areas add up to the parent's (what
    /// `reconstruct::seen_floor` relies on to score uncut faces whole).
    #[test]
    fn the_pieces_of_a_face_follow_it_in_one_block() {
        let m = TriMesh {
            vertices: vec![
                [0.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [0.0, 2.0, 0.0],
                [0.0, 0.0, 3.0],
            ],
            faces: vec![[0, 1, 2], [0, 3, 1], [1, 3, 2], [0, 2, 3]],
        };
        let (s, levels) = subdivide_to(&m, 0.6, 1 << 20);
        let block = 4usize.pow(levels);
        assert!(levels >= 2 && s.faces.len() == m.faces.len() * block);
        let v =
            |m: &TriMesh, i: u32| nalgebra::Vector3::from(m.vertices[i as usize].map(f64::from));
        for (i, f) in m.faces.iter().enumerate() {
            let (a, b, c) = (v(&m, f[0]), v(&m, f[1]), v(&m, f[2]));
            let n = (b - a).cross(&(c - a));
            let parent = TriMesh {
                vertices: m.vertices.clone(),
                faces: vec![*f],
            };
            let pieces = TriMesh {
                vertices: s.vertices.clone(),
                faces: s.faces[i * block..(i + 1) * block].to_vec(),
            };
            assert!((area(&pieces) - area(&parent)).abs() < 1e-5 * area(&parent));
            for g in &pieces.faces {
                let p = (v(&s, g[0]) + v(&s, g[1]) + v(&s, g[2])) / 3.0;
                assert!(
                    (p - a).dot(&n).abs() < 1e-5 * n.norm(),
                    "face {i}: off its plane"
                );
                // Inside: on the inner side of each of the parent's edges.
                for (x, y) in [(a, b), (b, c), (c, a)] {
                    assert!(
                        (y - x).cross(&(p - x)).dot(&n) > 0.0,
                        "face {i}: outside it"
                    );
                }
            }
        }
    }

    #[test]
    fn subdivision_stops_at_the_edge_length_or_the_face_cap() {
        let tri = TriMesh {
            vertices: vec![[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 3.0, 0.0]],
            faces: vec![[0, 1, 2]],
        };
        let (m, levels) = subdivide_to(&tri, 1.0, 1 << 20);
        // The hypotenuse (5) halves three times to 0.625.
        assert_eq!((levels, m.faces.len()), (3, 64));
        assert!(longest_edge(&m) <= 1.0);
        let (m, levels) = subdivide_to(&tri, 1.0, 20);
        assert_eq!(
            (levels, m.faces.len()),
            (2, 16),
            "a third level would make 64 > 20"
        );
        let (m, levels) = subdivide_to(&tri, 10.0, 1 << 20);
        assert_eq!((levels, m.faces.len()), (0, 1));
        let empty = TriMesh {
            vertices: vec![],
            faces: vec![],
        };
        assert_eq!(subdivide_to(&empty, 0.1, 100).1, 0);
        assert_eq!(longest_edge(&empty), 0.0);
    }
}
