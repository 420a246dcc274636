//! The textured mesh as Wavefront OBJ + MTL (+ the PNG the caller writes first): `v` positions
//! (world mm) and `vn` normals one per geometry vertex, `vt` texture coordinates one per UV
//! vertex with `v` up (OBJ's convention: `vt = (u, 1 − v)` of the image-row `v` of
//! [`UvMesh`]), faces `f v/vt/vn` in the mesh's order, one material whose `map_Kd` names the
//! texture (Paul Bourke's MTL description; what MeshLab, Blender, trimesh and Open3D read).
//! Numbers are written in Rust's shortest round-trip form: the positions read back bit for bit.

use super::unwrap::UvMesh;
use super::{io_err, ExportError};
use std::path::Path;

/// Writes `dir/obj_name` and `dir/mtl_name` (atomically), the MTL naming `png_name`.
pub fn write_obj(
    dir: &Path,
    obj_name: &str,
    mtl_name: &str,
    png_name: &str,
    m: &UvMesh,
) -> Result<(), ExportError> {
    let mtl = format!(
        "# neus-aug: the colour network's colours seen head-on, baked\n\
         newmtl neus_aug\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nd 1\nillum 1\nmap_Kd {png_name}\n"
    );
    let mtl_path = dir.join(mtl_name);
    dtu_eval::atomic::write_atomic(&mtl_path, mtl.as_bytes()).map_err(io_err(&mtl_path))?;
    let path = dir.join(obj_name);
    dtu_eval::atomic::write_atomic_with(&path, |w| {
        writeln!(
            w,
            "# neus-aug textured mesh: {} vertices, {} texture coordinates, {} faces; world mm",
            m.positions.len(),
            m.uv.len(),
            m.faces.len()
        )?;
        writeln!(w, "mtllib {mtl_name}")?;
        for p in &m.positions {
            writeln!(w, "v {} {} {}", p[0], p[1], p[2])?;
        }
        for n in &m.normals {
            writeln!(w, "vn {} {} {}", n[0], n[1], n[2])?;
        }
        for t in &m.uv {
            writeln!(w, "vt {} {}", t[0], 1.0 - t[1])?;
        }
        writeln!(w, "usemtl neus_aug")?;
        for (f, t) in m.faces.iter().zip(&m.uv_faces) {
            writeln!(
                w,
                "f {}/{}/{} {}/{}/{} {}/{}/{}",
                f[0] + 1,
                t[0] + 1,
                f[0] + 1,
                f[1] + 1,
                t[1] + 1,
                f[1] + 1,
                f[2] + 1,
                t[2] + 1,
                f[2] + 1
            )?;
        }
        Ok(())
    })
    .map_err(io_err(&path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn obj_lines_follow_the_mesh() {
        let m = UvMesh {
            positions: vec![[0.0, 0.0, 0.0], [1.5, 0.0, 0.0], [0.0, 1.0, 1e-7]],
            normals: vec![[0.0, 0.0, 1.0]; 3],
            faces: vec![[0, 1, 2]],
            uv: vec![[0.25, 0.0], [0.75, 0.0], [0.25, 1.0]],
            xref: vec![0, 1, 2],
            uv_faces: vec![[0, 1, 2]],
            stats: Default::default(),
        };
        let dir = tempfile::tempdir().unwrap();
        write_obj(dir.path(), "m.obj", "m.mtl", "m.png", &m).unwrap();
        let obj = std::fs::read_to_string(dir.path().join("m.obj")).unwrap();
        let lines: Vec<&str> = obj.lines().collect();
        assert_eq!(lines[1], "mtllib m.mtl");
        assert_eq!(lines[4], "v 0 1 0.0000001");
        assert_eq!(lines[8], "vt 0.25 1", "v up");
        assert_eq!(lines[10], "vt 0.25 0");
        assert_eq!(lines[12], "f 1/1/1 2/2/2 3/3/3");
        let mtl = std::fs::read_to_string(dir.path().join("m.mtl")).unwrap();
        assert!(mtl.lines().any(|l| l == "map_Kd m.png"));
    }
}
