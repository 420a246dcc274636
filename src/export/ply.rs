//! The coloured mesh as binary little-endian PLY, the layout MeshLab, Open3D and trimesh read
//! vertex normals and colours, as MeshLab, Open3D and trimesh read them:
//!
//! ```text
//! element vertex N: float x, y, z (world mm); float nx, ny, nz (unit); uchar red, green, blue
//! element face M:   list uchar uint vertex_indices
//! ```
//!
//! The positions are the `f32` values [`dtu_eval::ply::write_mesh`] writes and the faces the same
//! lists, so `dtu_eval::ply::read_mesh` (which skips the extra properties) reads back exactly the
//! geometry-only file's mesh. Records are packed by hand (27 bytes a vertex, 13 a face): the same
//! bytes a generic PLY writer would produce, at disk speed.

use super::{io_err, ColoredMesh, ExportError};
use std::path::Path;

/// The header of a coloured mesh with `n_vertices` and `n_faces` (the face element is left out
/// when there are no faces, as `dtu_eval`'s writer does).
fn header(n_vertices: usize, n_faces: usize) -> String {
    let mut h = String::from("ply\nformat binary_little_endian 1.0\n");
    h += "comment neus-aug: world mm; normals from the SDF gradient; colours from the colour \
          network at the surface\n";
    h += &format!("element vertex {n_vertices}\n");
    for p in ["x", "y", "z", "nx", "ny", "nz"] {
        h += &format!("property float {p}\n");
    }
    for p in ["red", "green", "blue"] {
        h += &format!("property uchar {p}\n");
    }
    if n_faces > 0 {
        h += &format!("element face {n_faces}\nproperty list uchar uint vertex_indices\n");
    }
    h + "end_header\n"
}

/// Writes `m` to `path` atomically ([`dtu_eval::atomic::write_atomic_with`]).
pub fn write_colored_ply(path: &Path, m: &ColoredMesh) -> Result<(), ExportError> {
    let n = m.mesh.vertices.len();
    assert!(
        m.normals.len() == n && m.colors.len() == n,
        "one normal and one colour per vertex"
    );
    dtu_eval::atomic::write_atomic_with(path, |w| {
        w.write_all(header(n, m.mesh.faces.len()).as_bytes())?;
        let mut rec = [0u8; 27];
        for ((v, nr), c) in m.mesh.vertices.iter().zip(&m.normals).zip(&m.colors) {
            for (k, x) in v.iter().chain(nr).enumerate() {
                rec[4 * k..4 * k + 4].copy_from_slice(&x.to_le_bytes());
            }
            rec[24..27].copy_from_slice(c);
            w.write_all(&rec)?;
        }
        let mut frec = [0u8; 13];
        frec[0] = 3;
        for f in &m.mesh.faces {
            for (k, i) in f.iter().enumerate() {
                frec[1 + 4 * k..5 + 4 * k].copy_from_slice(&i.to_le_bytes());
            }
            w.write_all(&frec)?;
        }
        Ok(())
    })
    .map_err(io_err(path))
}

#[cfg(test)]
mod tests {
    use super::*;
    use dtu_eval::mesh::TriMesh;

    fn tetra() -> ColoredMesh {
        let mesh = TriMesh {
            vertices: vec![
                [1.0, 1.0, 1.0],
                [1.0, -1.0, -1.0],
                [-1.0, 1.5e-7, -1.0],
                [-1.0, -1.0, 123.456],
            ],
            faces: vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]],
        };
        ColoredMesh {
            normals: super::super::colors::area_weighted_normals(&mesh),
            colors: vec![[255, 0, 0], [0, 255, 0], [0, 0, 255], [10, 20, 30]],
            mesh,
            fallbacks: 0,
        }
    }

    /// `dtu_eval` reads back the very geometry of the geometry-only writer, and the payload has
    /// the size the header announces.
    #[test]
    fn geometry_reads_back_exactly_and_sizes_match() {
        let dir = tempfile::tempdir().unwrap();
        let m = tetra();
        let (a, b) = (dir.path().join("c.ply"), dir.path().join("g.ply"));
        write_colored_ply(&a, &m).unwrap();
        dtu_eval::ply::write_mesh(&b, &m.mesh).unwrap();
        let (ra, rb) = (
            dtu_eval::ply::read_mesh(&a).unwrap(),
            dtu_eval::ply::read_mesh(&b).unwrap(),
        );
        assert_eq!(ra, m.mesh);
        assert_eq!(ra, rb);
        let bytes = std::fs::read(&a).unwrap();
        let h = header(4, 4);
        assert!(bytes.starts_with(h.as_bytes()));
        assert_eq!(bytes.len(), h.len() + 4 * 27 + 4 * 13);
        // The last vertex's colour sits just before the faces.
        let end = h.len() + 4 * 27;
        assert_eq!(&bytes[end - 3..end], &[10, 20, 30]);
    }
}
