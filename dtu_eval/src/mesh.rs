//! Triangle meshes and point clouds in memory.
//!
//! Units and frame are the caller's: meshes scored by the DTU protocol must be in DTU world
//! coordinates (millimetres), not in the normalised unit-sphere space a network trains in.

/// An indexed triangle mesh: `vertices` is `[n_vertices][3]` (x, y, z), `faces` is
/// `[n_faces][3]` vertex indices, counter-clockwise seen from outside (outward normals).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions.
    pub vertices: Vec<[f32; 3]>,
    /// Triangles as indices into `vertices`.
    pub faces: Vec<[u32; 3]>,
}

/// Why a mesh cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {index} has a non-finite coordinate {value:?}")]
    NonFiniteVertex { index: usize, value: [f32; 3] },
    /// A face refers to a vertex that does not exist.
    #[error("face {face} refers to vertex {vertex}, but the mesh has only {n_vertices} vertices")]
    FaceOutOfRange {
        face: usize,
        vertex: u32,
        n_vertices: usize,
    },
}

impl TriMesh {
    /// Checks that every vertex is finite and every face index is in range.
    pub fn validate(&self) -> Result<(), MeshError> {
        if let Some((index, v)) = self
            .vertices
            .iter()
            .enumerate()
            .find(|(_, v)| v.iter().any(|c| !c.is_finite()))
        {
            return Err(MeshError::NonFiniteVertex { index, value: *v });
        }
        let n = self.vertices.len();
        for (face, f) in self.faces.iter().enumerate() {
            if let Some(&vertex) = f.iter().find(|&&i| i as usize >= n) {
                return Err(MeshError::FaceOutOfRange {
                    face,
                    vertex,
                    n_vertices: n,
                });
            }
        }
        Ok(())
    }

    /// Axis-aligned bounds `(min, max)`, or `None` for a mesh without vertices.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        bounds(&self.vertices)
    }

    /// Applies `v ↦ scale·v + offset` to every vertex (e.g. normalised space → world mm with the
    /// scene's `scale_mat`).
    pub fn scale_translate(&mut self, scale: f32, offset: [f32; 3]) {
        for v in &mut self.vertices {
            for k in 0..3 {
                v[k] = scale * v[k] + offset[k];
            }
        }
    }
}

/// Axis-aligned bounds `(min, max)` of a point set, or `None` when it is empty.
pub fn bounds(points: &[[f32; 3]]) -> Option<([f32; 3], [f32; 3])> {
    let first = *points.first()?;
    Some(points.iter().fold((first, first), |(mut lo, mut hi), p| {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
        (lo, hi)
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validate_names_the_bad_vertex_and_face() {
        let mut m = TriMesh {
            vertices: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            faces: vec![[0, 1, 2]],
        };
        assert_eq!(m.validate(), Ok(()));
        m.faces.push([0, 1, 3]);
        assert_eq!(
            m.validate(),
            Err(MeshError::FaceOutOfRange {
                face: 1,
                vertex: 3,
                n_vertices: 3
            })
        );
        m.faces.pop();
        m.vertices[1][2] = f32::NAN;
        assert!(matches!(
            m.validate(),
            Err(MeshError::NonFiniteVertex { index: 1, .. })
        ));
    }

    #[test]
    fn bounds_and_transform() {
        let mut m = TriMesh {
            vertices: vec![[-1.0, 0.0, 2.0], [1.0, -3.0, 0.5]],
            faces: vec![],
        };
        assert_eq!(m.bounds(), Some(([-1.0, -3.0, 0.5], [1.0, 0.0, 2.0])));
        m.scale_translate(2.0, [10.0, 0.0, -1.0]);
        assert_eq!(m.vertices[0], [8.0, 0.0, 3.0]);
        assert_eq!(TriMesh::default().bounds(), None);
    }
}
