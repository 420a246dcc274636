//! PLY input and output for triangle meshes and point clouds, on the `ply-rs-bw` crate.
//!
//! Reading accepts ASCII and binary (both endians) files, `float` or `double` coordinates, any
//! integer list type for faces (`vertex_indices` or `vertex_index`, as MeshLab, Open3D and DTU's
//! `stl*_total.ply` write them), polygons (fan-triangulated) and extra properties (ignored).
//! Writing produces binary little-endian files (`float x, y, z`, optional `uchar red, green, blue`,
//! `list uchar uint vertex_indices`) that MeshLab, Open3D, trimesh and pymeshlab open. Files are
//! written to a temporary sibling and renamed, so a crash never leaves a half-written PLY behind.

use crate::mesh::{MeshError, TriMesh};
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    Addable, ElementDef, Encoding, Header, Property, PropertyAccess, PropertyAccessResult,
    PropertyDef, PropertyType, ScalarType,
};
use ply_rs_bw::writer::Writer;
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

/// Errors of PLY input/output. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum PlyError {
    /// The file could not be opened, read or written.
    #[error("cannot access {path}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The header or the payload does not parse.
    #[error("{path} is not a valid PLY file: {message}")]
    Parse { path: PathBuf, message: String },
    /// A required element or property is absent.
    #[error("{path} has no {what}")]
    Missing { path: PathBuf, what: String },
    /// A face has fewer than three vertices or negative indices.
    #[error("{path}: face {face} is not a polygon with valid indices")]
    BadFace { path: PathBuf, face: usize },
    /// The mesh read is inconsistent (NaN vertex, index past the vertices).
    #[error("{path} holds an invalid mesh")]
    Invalid {
        path: PathBuf,
        #[source]
        source: MeshError,
    },
}

#[derive(Default)]
struct VertexIn {
    xyz: [f32; 3],
    seen: u8,
}

impl PropertyAccess for VertexIn {
    fn new() -> Self {
        Self::default()
    }
    fn set_property(&mut self, key: &str, property: Property) -> PropertyAccessResult {
        let axis = match key {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return PropertyAccessResult::Ignored,
        };
        match property.to_f32_lossy() {
            Some(v) => {
                self.xyz[axis] = v;
                self.seen |= 1 << axis;
                PropertyAccessResult::Set
            }
            None => PropertyAccessResult::UnsupportedType,
        }
    }
}

/// A face as read: its index list, or `None` when the list held a negative index.
#[derive(Default)]
struct FaceIn {
    indices: Option<Vec<u32>>,
}

impl PropertyAccess for FaceIn {
    fn new() -> Self {
        Self::default()
    }
    fn set_property(&mut self, key: &str, property: Property) -> PropertyAccessResult {
        if key != "vertex_indices" && key != "vertex_index" {
            return PropertyAccessResult::Ignored;
        }
        self.indices = Some(property.to_u32_list().unwrap_or_default());
        PropertyAccessResult::Set
    }
}

/// An element we do not use (edges, materials, ...): parsed and dropped.
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

struct Parsed {
    vertices: Vec<[f32; 3]>,
    faces: Option<Vec<FaceIn>>,
}

fn parse(path: &Path) -> Result<Parsed, PlyError> {
    let file = File::open(path).map_err(|source| PlyError::Io {
        path: path.into(),
        source,
    })?;
    let parse_err = |e: ply_rs_bw::parser::ParseError| PlyError::Parse {
        path: path.into(),
        message: e.to_string(),
    };
    let mut buffered = BufReader::with_capacity(1 << 20, file);
    let head = std::io::BufRead::fill_buf(&mut buffered).map_err(|source| PlyError::Io {
        path: path.into(),
        source,
    })?;
    // Every PLY file opens with the line "ply" (Turk's format description); without it the
    // parser's complaint is about whatever bytes it met first.
    if !(head.starts_with(b"ply\n") || head.starts_with(b"ply\r\n")) {
        let shown: String = head
            .iter()
            .take(16)
            .map(|&b| std::ascii::escape_default(b).to_string())
            .collect();
        return Err(PlyError::Parse {
            path: path.into(),
            message: format!(
                "it does not start with the line 'ply' that opens every PLY file (its first \
                 bytes: \"{shown}\")"
            ),
        });
    }
    let mut reader = Reader::new(buffered);
    let vertex_parser = Parser::<VertexIn>::new();
    let header: Header = vertex_parser.read_header(&mut reader).map_err(parse_err)?;
    let mut vertices = None;
    let mut faces = None;
    for (_, element) in &header.elements {
        match element.name.as_str() {
            "vertex" => {
                for axis in ["x", "y", "z"] {
                    if !element.properties.contains_key(axis) {
                        return Err(PlyError::Missing {
                            path: path.into(),
                            what: format!("vertex property '{axis}'"),
                        });
                    }
                }
                let list = vertex_parser
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(parse_err)?;
                vertices = Some(list.into_iter().map(|v| v.xyz).collect());
            }
            "face" => {
                faces = Some(
                    Parser::<FaceIn>::new()
                        .read_payload_for_element(&mut reader, element, &header)
                        .map_err(parse_err)?,
                );
            }
            _ => {
                Parser::<Skip>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(parse_err)?;
            }
        }
    }
    let vertices = vertices.ok_or_else(|| PlyError::Missing {
        path: path.into(),
        what: "'vertex' element".into(),
    })?;
    Ok(Parsed { vertices, faces })
}

/// Reads a triangle mesh. Polygons are split into triangle fans; a file without a `face`
/// element gives a mesh with no faces. Non-finite vertices and out-of-range indices are errors.
pub fn read_mesh(path: &Path) -> Result<TriMesh, PlyError> {
    let parsed = parse(path)?;
    let mut faces = Vec::new();
    for (i, face) in parsed.faces.unwrap_or_default().iter().enumerate() {
        match face.indices.as_deref() {
            Some(idx) if idx.len() >= 3 => {
                for k in 1..idx.len() - 1 {
                    faces.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {
                return Err(PlyError::BadFace {
                    path: path.into(),
                    face: i,
                })
            }
        }
    }
    let mesh = TriMesh {
        vertices: parsed.vertices,
        faces,
    };
    mesh.validate().map_err(|source| PlyError::Invalid {
        path: path.into(),
        source,
    })?;
    Ok(mesh)
}

/// Reads the vertices of any PLY file as a point cloud (faces, if present, are ignored).
/// Non-finite points are an error.
pub fn read_points(path: &Path) -> Result<Vec<[f32; 3]>, PlyError> {
    let vertices = parse(path)?.vertices;
    let cloud = TriMesh {
        vertices,
        faces: Vec::new(),
    };
    cloud.validate().map_err(|source| PlyError::Invalid {
        path: path.into(),
        source,
    })?;
    Ok(cloud.vertices)
}

struct VertexOut<'a> {
    xyz: &'a [f32; 3],
    rgb: Option<&'a [u8; 3]>,
}

impl PropertyAccess for VertexOut<'_> {
    fn new() -> Self {
        unreachable!("output-only element")
    }
    fn get_float(&self, key: &str) -> Option<f32> {
        match key {
            "x" => Some(self.xyz[0]),
            "y" => Some(self.xyz[1]),
            "z" => Some(self.xyz[2]),
            _ => None,
        }
    }
    fn get_uchar(&self, key: &str) -> Option<u8> {
        let c = self.rgb?;
        match key {
            "red" => Some(c[0]),
            "green" => Some(c[1]),
            "blue" => Some(c[2]),
            _ => None,
        }
    }
}

struct FaceOut<'a>(&'a [u32; 3]);

impl PropertyAccess for FaceOut<'_> {
    fn new() -> Self {
        unreachable!("output-only element")
    }
    fn get_list_uint(&self, key: &str) -> Option<&[u32]> {
        (key == "vertex_indices").then_some(&self.0[..])
    }
}

fn scalar(name: &str, t: ScalarType) -> PropertyDef {
    PropertyDef::new(name.to_string(), PropertyType::Scalar(t))
}

/// Writes `vertices` (with optional per-vertex colours) and `faces` as a binary little-endian PLY,
/// atomically ([`crate::atomic::write_atomic_with`]). `comment` lines go into the header.
pub fn write(
    path: &Path,
    vertices: &[[f32; 3]],
    colors: Option<&[[u8; 3]]>,
    faces: &[[u32; 3]],
    comments: &[&str],
) -> Result<(), PlyError> {
    if let Some(c) = colors {
        assert_eq!(c.len(), vertices.len(), "one colour per vertex");
    }
    let io_err = |source| PlyError::Io {
        path: path.into(),
        source,
    };
    let mut header = Header::new();
    header.encoding = Encoding::BinaryLittleEndian;
    header.comments = comments.iter().map(|c| c.to_string()).collect();
    let mut vdef = ElementDef::new("vertex".to_string());
    for axis in ["x", "y", "z"] {
        vdef.properties.add(scalar(axis, ScalarType::Float));
    }
    if colors.is_some() {
        for ch in ["red", "green", "blue"] {
            vdef.properties.add(scalar(ch, ScalarType::UChar));
        }
    }
    vdef.count = vertices.len();
    header.elements.add(vdef.clone());
    let mut fdef = ElementDef::new("face".to_string());
    fdef.properties.add(PropertyDef::new(
        "vertex_indices".to_string(),
        PropertyType::List(ScalarType::UChar, ScalarType::UInt),
    ));
    fdef.count = faces.len();
    if !faces.is_empty() {
        header.elements.add(fdef.clone());
    }

    crate::atomic::write_atomic_with(path, |mut out| {
        let out = &mut out;
        Writer::<VertexOut>::new().write_header(out, &header)?;
        let vw = Writer::<VertexOut>::new();
        for (i, xyz) in vertices.iter().enumerate() {
            let rgb = colors.map(|c| &c[i]);
            vw.write_little_endian_element(out, &VertexOut { xyz, rgb }, &vdef)?;
        }
        let fw = Writer::<FaceOut>::new();
        for f in faces {
            fw.write_little_endian_element(out, &FaceOut(f), &fdef)?;
        }
        Ok(())
    })
    .map_err(io_err)
}

/// Writes a triangle mesh as binary little-endian PLY (see [`write`]).
pub fn write_mesh(path: &Path, mesh: &TriMesh) -> Result<(), PlyError> {
    write(path, &mesh.vertices, None, &mesh.faces, &[])
}

/// Writes a point cloud (optionally coloured) as binary little-endian PLY (see [`write`]).
pub fn write_points(
    path: &Path,
    points: &[[f32; 3]],
    colors: Option<&[[u8; 3]]>,
) -> Result<(), PlyError> {
    write(path, points, colors, &[], &[])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> TriMesh {
        TriMesh {
            vertices: vec![
                [1.0, 1.0, 1.0],
                [1.0, -1.0, -1.0],
                [-1.0, 1.0, -1.0],
                [-1.0, -1.0, 1.0],
            ],
            faces: vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]],
        }
    }

    #[test]
    fn binary_round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.ply");
        let mut mesh = tetra();
        mesh.vertices[2] = [0.1, -1e-7, 1234.5678];
        write_mesh(&path, &mesh).unwrap();
        assert_eq!(read_mesh(&path).unwrap(), mesh);
        assert_eq!(read_points(&path).unwrap(), mesh.vertices);
        // No temporary file is left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn coloured_points_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.ply");
        let pts = vec![[0.5, 1.5, -2.5], [3.0, 4.0, 5.0]];
        write_points(&path, &pts, Some(&[[255, 0, 0], [0, 10, 200]])).unwrap();
        assert_eq!(read_points(&path).unwrap(), pts);
        assert!(read_mesh(&path).unwrap().faces.is_empty());
    }

    #[test]
    fn ascii_quads_doubles_and_extra_properties() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.ply");
        std::fs::write(
            &path,
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\n\
             property double z\nproperty float nx\nelement face 1\n\
             property list uchar int vertex_index\nelement edge 1\nproperty int vertex1\n\
             property int vertex2\nend_header\n0 0 0 1\n1 0 0 1\n1 1 0 1\n0 1 0 1\n4 0 1 2 3\n0 1\n",
        )
        .unwrap();
        let mesh = read_mesh(&path).unwrap();
        assert_eq!(mesh.vertices.len(), 4);
        assert_eq!(mesh.faces, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn bad_files_give_errors_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let cases: [(&str, &str); 5] = [
            ("missing.ply", ""),
            ("garbage.ply", "this is not a ply\n"),
            (
                "nan.ply",
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                 property float z\nend_header\nnan 0 0\n",
            ),
            (
                "range.ply",
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                 end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n",
            ),
            (
                "noz.ply",
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                 end_header\n0 0\n",
            ),
        ];
        for (name, text) in cases {
            let path = dir.path().join(name);
            if !text.is_empty() {
                std::fs::write(&path, text).unwrap();
            }
            let err = read_mesh(&path).unwrap_err().to_string();
            assert!(err.contains(name), "{name}: {err}");
            if name == "garbage.ply" {
                assert!(err.contains("does not start with the line 'ply'"), "{err}");
            }
        }
    }
}
